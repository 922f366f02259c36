"""The points of a sweep: ``--vary KEY=SPEC`` parsed, the grid, the names, the validation.

``SPEC`` is one of

* ``a:b:n``: ``n`` evenly spaced values from ``a`` to ``b`` (both included; whole numbers when
  ``a`` and ``b`` are written as integers and the step is whole);
* ``a,b,c``: a list, each item read as a YAML scalar (``1.5``, ``2``, ``1e-3``, ``torque``);
  one value without a comma is a list of one;
* ``random:a:b:n:seed``: ``n`` values drawn uniformly in ``[a, b)`` by NumPy's PCG64 generator
  seeded with ``seed`` (the same values on every machine and run).

Several ``--vary`` make the full grid, the first one outermost. Every point is the base file's
data with the values set (:func:`cpopt.io.keypath.with_values`) and is validated like a problem
file before any work starts.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..io.keypath import KeyPathError, check_disjoint, parse_key_path, with_values
from ..io.safe_yaml import YamlInputError, echo, parse_yaml, read_yaml
from ..problem import NAME, ProblemError, parse_problem, safe_name
from ..problem.keytypes import BOOLEAN, NUMBER, WORD, KeyType, key_type
from ..problem.urdf_arm import absolute_urdf

MAX_POINTS = 100_000
"""Most points of one sweep (a typo like ``0:1:1e9`` is refused before any work)."""
MAX_TIME = "optimizer.solver.max_time"
"""The key ``--time-limit`` sets in every point."""


class SweepError(ValueError):
    """A sweep that cannot run: a bad ``--vary``, key path or point (exit code 2)."""


@dataclass(frozen=True)
class Vary:
    """One ``--vary``: the key path and its values, in order."""

    key: str
    values: tuple


@dataclass(frozen=True)
class Point:
    """One point of the grid.

    Attributes
    ----------
    index : int
        Its place in the grid (0-based, first ``--vary`` outermost).
    name : str
        The problem's name and folder under ``--out``, made from the values.
    values : dict of str to object
        The value of each varied key path.
    data : dict
        The point's problem data (the base file's with the values and the name set).
    digest : str
        SHA-256 of the problem data (what ``--resume`` compares).
    """

    index: int
    name: str
    values: dict
    data: dict
    digest: str


def _number(text: str, what: str, spec: str) -> float | int:
    text = text.strip()
    try:
        value = int(text) if re.fullmatch(r"[+-]?\d+", text) else float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise SweepError(f"{spec}: {what} must be a finite number, got {echo(text)}")
    return value


def _count(text: str, spec: str) -> int:
    count = _number(text, "n", spec)
    if not isinstance(count, int) or count < 1:
        raise SweepError(f"{spec}: n must be a whole number >= 1, got {echo(text)}")
    if count > MAX_POINTS:  # before any list of values is made
        raise SweepError(f"{spec}: n must be at most {MAX_POINTS}, got {count}")
    return count


def _linear(parts: list[str], spec: str) -> tuple:
    a, b = (_number(p, w, spec) for p, w in zip(parts[:2], "ab", strict=True))
    n = _count(parts[2], spec)
    values = np.linspace(a, b, n)
    if isinstance(a, int) and isinstance(b, int) and (n == 1 or (b - a) % (n - 1) == 0):
        return tuple(round(float(v)) for v in values)
    return tuple(float(v) for v in values)


def _random(parts: list[str], spec: str) -> tuple:
    a, b = (float(_number(p, w, spec)) for p, w in zip(parts[:2], "ab", strict=True))
    n = _count(parts[2], spec)
    seed = _number(parts[3], "seed", spec)
    if not isinstance(seed, int) or seed < 0:
        raise SweepError(f"{spec}: seed must be a whole number >= 0, got {echo(parts[3])}")
    return tuple(float(v) for v in np.random.default_rng(seed).uniform(a, b, n))


def _typed(item: str, kind: KeyType, spec: str):
    """One value of a list SPEC read as the key takes it: a number, true/false or a word."""
    text = item.strip()
    if NUMBER in kind.kinds:
        try:
            float(text)
        except ValueError:
            pass
        else:
            return _number(text, "each value", spec)
    if BOOLEAN in kind.kinds and text.lower() in ("true", "false"):
        return text.lower() == "true"
    if WORD in kind.kinds and (text in kind.words or not kind.words):
        return text
    raise SweepError(f"{spec}: {echo(text)} is not {kind.describe()}")


def _yaml_item(item: str, spec: str):
    """One value of a list SPEC for a key the schema does not type: a YAML scalar."""
    try:
        value = parse_yaml(item)
    except YamlInputError:
        value = None
    if value is None or isinstance(value, dict | list):
        raise SweepError(f"{spec}: expected numbers or words separated by commas")
    if isinstance(value, float) and not math.isfinite(value):
        raise SweepError(f"{spec}: {echo(item)} is not a finite number")
    return value


def _listed(spec: str, kind: KeyType | None) -> tuple:
    values = []
    for item in spec.split(","):
        if not item.strip():
            raise SweepError(f"{spec}: expected numbers or words separated by commas")
        values.append(_yaml_item(item, spec) if kind is None else _typed(item, kind, spec))
    return tuple(values)


def _kind(value) -> str:
    if isinstance(value, bool):  # before int: True is an int too
        return BOOLEAN
    return NUMBER if isinstance(value, int | float) else WORD


def _one_kind(values: tuple, spec: str) -> None:
    """Refuse values of mixed kinds (``1,abc``, ``auto,2``): one column of the table, one axis
    of the plot."""
    kinds = sorted({_kind(v) for v in values})
    if len(kinds) > 1:
        raise SweepError(
            f"{spec}: values of mixed kinds ({' and '.join(k + 's' for k in kinds)}); "
            "give values of one kind"
        )


def parse_spec(spec: str, kind: KeyType | None = None) -> tuple:
    """The values of a ``SPEC`` (``a:b:n``, ``a,b,c`` or ``random:a:b:n:seed``).

    Parameters
    ----------
    spec : str
        The SPEC as written.
    kind : KeyType, optional
        What the varied key takes (:func:`cpopt.problem.keytypes.key_type`): the values of a
        list are read as that, and a range needs a key that takes numbers. Without it a list's
        values are YAML scalars.

    Raises
    ------
    SweepError
        Saying what was expected.
    """
    text = spec.strip()
    ranged = text.startswith("random:") or ":" in text
    if ranged and kind is not None and NUMBER not in kind.kinds:
        raise SweepError(f"{spec}: a range gives numbers; the key takes {kind.describe()}")
    if text.startswith("random:"):
        parts = text.split(":")[1:]
        if len(parts) != 4:
            raise SweepError(f"{spec}: expected random:a:b:n:seed")
        return _random(parts, spec)
    if ":" in text:
        parts = text.split(":")
        if len(parts) != 3:
            raise SweepError(f"{spec}: expected a:b:n (n evenly spaced values from a to b)")
        return _linear(parts, spec)
    values = _listed(text, kind)
    _one_kind(values, spec)
    return values


def parse_vary(text: str) -> Vary:
    """One ``--vary KEY=SPEC``, its values read as the key takes them
    (:func:`cpopt.problem.keytypes.key_type`).

    Raises
    ------
    SweepError
        For a missing ``=``, a malformed key path or SPEC, ``name`` (the sweep names the
        points), values the key does not take or of mixed kinds, or a value given twice.
    """
    key, sep, spec = text.partition("=")
    if not sep:
        raise SweepError(f"--vary {text}: expected KEY=SPEC, e.g. motion.duration=1.2:2.0:5")
    key = key.strip()
    try:
        parts = parse_key_path(key)
    except KeyPathError as err:
        raise SweepError(f"--vary {err}") from None
    if parts == ("name",):
        raise SweepError(
            f"--vary {text}: the sweep names each point after its values; vary a value of the "
            "problem instead"
        )
    try:
        values = parse_spec(spec, key_type(key))
    except SweepError as err:
        raise SweepError(f"--vary {key}={err}") from None
    if len(set(values)) != len(values):  # 1 and 1.0 are one value
        raise SweepError(f"--vary {key}={spec}: a value is given twice")
    return Vary(key, values)


def check_varies(varies: list[Vary], time_limit: float | None = None) -> None:
    """Refuse a key path varied twice or inside another varied one, one ``--time-limit``
    sets too, and a grid over :data:`MAX_POINTS` points."""
    keys = [v.key for v in varies]
    for key in keys:
        if keys.count(key) > 1:
            raise SweepError(f"--vary {key}: given twice; give all its values in one SPEC")
    try:
        check_disjoint(keys)
    except KeyPathError as err:
        raise SweepError(f"--vary {err}") from None
    if time_limit is not None:
        try:
            check_disjoint([*keys, MAX_TIME])
        except KeyPathError as err:
            raise SweepError(
                f"--vary {err.path} and --time-limit {time_limit:g} both set each point's "
                f"{MAX_TIME}; give one of them"
            ) from None
    size = math.prod(len(v.values) for v in varies)
    if size > MAX_POINTS:
        raise SweepError(f"the grid has {size} points; at most {MAX_POINTS}")


def _label(value, others: tuple) -> str:
    """A value in a folder name: as short as keeps the values of its key apart."""
    if isinstance(value, float):
        numbers = [v for v in others if isinstance(v, float)]
        for fmt in (".6g", ".10g"):
            if len({format(v, fmt) for v in numbers}) == len(numbers):
                return format(value, fmt)
        return repr(value)
    return str(value)


def point_names(base: str, varies: list[Vary], combos: list[tuple]) -> list[str]:
    """Folder names of the points: ``<base>__<key>_<value>__...`` (safe, unique), or
    ``<base>__point_<i>`` when those would be too long or clash."""
    names = []
    for combo in combos:
        parts = [
            f"{v.key}_{_label(value, v.values)}" for v, value in zip(varies, combo, strict=True)
        ]
        text = re.sub(r"\[(\d+)\]", r"_\1", "__".join([base, *parts]))
        names.append(re.sub(r"[^A-Za-z0-9_.-]", "_", text))
    if all(NAME.fullmatch(n) for n in names) and len({n.casefold() for n in names}) == len(names):
        return names
    width = len(str(len(combos)))
    return [f"{base[:60]}__point_{i + 1:0{width}d}" for i in range(len(combos))]


def digest(data: dict) -> str:
    """SHA-256 of problem data, independent of key order (what ``--resume`` compares)."""
    text = json.dumps(data, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def read_base(path: str) -> tuple[dict, str]:
    """The base file's data and the name its points are named after.

    Raises
    ------
    SweepError
        For a file that cannot be read (the message names it and the key path).
    """
    try:
        data = read_yaml(path)
    except YamlInputError as err:
        raise SweepError(str(ProblemError(path, err.path, err.message))) from None
    if not isinstance(data, dict):
        parse_problem(data, path)  # raises, with the usual message
    name = data.get("name")
    base = name if isinstance(name, str) and NAME.fullmatch(name) else None
    # the points are validated under other names than the file's: a URDF relative to it
    return absolute_urdf(data, path), base or safe_name(Path(path).stem)


def build_points(path: str, varies: list[Vary], time_limit: float | None = None) -> list[Point]:
    """Every point of the grid over the base file ``path``, each validated.

    ``time_limit`` [s], when given, replaces each point's ``optimizer.solver.max_time``.

    Raises
    ------
    SweepError
        For a key path that cannot be set or a point that does not validate: the message
        names the base file, the point (its values) and the key path.
    """
    check_varies(varies, time_limit)
    try:
        data, base = read_base(path)
    except ProblemError as err:
        raise SweepError(str(err)) from None
    combos = list(itertools.product(*(v.values for v in varies)))
    names = point_names(base, varies, combos)
    points = []
    for index, (combo, name) in enumerate(zip(combos, names, strict=True)):
        values = {v.key: value for v, value in zip(varies, combo, strict=True)}
        shown = ", ".join(f"{k}={v}" for k, v in values.items())
        where = f"{path} [point {index + 1}/{len(combos)}: {shown}]"
        try:
            point = with_values(data, values)
            point["name"] = name
            if time_limit is not None:
                point = with_values(point, {MAX_TIME: float(time_limit)})
            parse_problem(point, where)
        except KeyPathError as err:
            raise SweepError(f"{where}: --vary {err}") from None
        except ProblemError as err:
            raise SweepError(str(err)) from None
        points.append(Point(index, name, values, point, digest(point)))
    return points


__all__ = [
    "MAX_POINTS",
    "MAX_TIME",
    "Point",
    "SweepError",
    "Vary",
    "build_points",
    "check_varies",
    "digest",
    "parse_spec",
    "parse_vary",
    "point_names",
    "read_base",
]
