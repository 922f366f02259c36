"""Key paths into problem data: ``arm.links[2].mass`` read, parsed and set.

The syntax is the one error messages use (:func:`cpopt.io.safe_yaml.key_path` writes it): names
separated by dots, list indices in brackets. The sweep (``cpopt sweep --vary KEY=SPEC``) and the
Python API (``cpopt.load(path, **{"motion.duration": 2.0})``) set values through it, on the
plain data of a problem file, before validation: whatever is set is checked like a value read
from the file.
"""

from __future__ import annotations

import copy
import re

from .safe_yaml import key_path

_PART = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)|\[(\d+)\]")


class KeyPathError(ValueError):
    """A key path that is malformed or does not lead into the data."""

    def __init__(self, path: str, message: str) -> None:
        self.path, self.message = path, message
        super().__init__(f"{path}: {message}" if path else message)


def parse_key_path(path: str) -> tuple[str | int, ...]:
    """``("motion", "via", 0, "t")`` from ``"motion.via[0].t"``.

    Raises
    ------
    KeyPathError
        For an empty path, a stray character, a leading index or an empty name.
    """
    parts: list[str | int] = []
    position = 0
    text = path.strip()
    while position < len(text):
        if parts and text[position] == ".":
            position += 1
        match = _PART.match(text, position)
        if match is None or (not parts and match.group(2) is not None):
            raise KeyPathError(
                path,
                f"expected a key path like arm.links[2].mass; "
                f"cannot read it at character {position + 1}",
            )
        name, index = match.groups()
        parts.append(name if name is not None else int(index))
        position = match.end()
    if not parts:
        raise KeyPathError(path, "expected a key path like motion.duration; got nothing")
    return tuple(parts)


def get_value(data, path: str):
    """The value at ``path`` in nested mappings and lists.

    Raises
    ------
    KeyPathError
        When the path does not lead to a value.
    """
    value = data
    for depth, part in enumerate(parse_key_path(path)):
        value = _step(value, part, path, depth)
    return value


def check_disjoint(paths: list[str]) -> None:
    """Refuse key paths that set one value twice: the same path (however spelt) or one path
    inside another (``motion`` and ``motion.duration``), whose values would contradict.

    Raises
    ------
    KeyPathError
        Naming both paths, or a malformed one.
    """
    parsed = [(path, parse_key_path(path)) for path in paths]
    for i, (first, a) in enumerate(parsed):
        for second, b in parsed[i + 1 :]:
            shorter, longer = sorted((a, b), key=len)
            if longer[: len(shorter)] == shorter:
                what = "the same key" if a == b else "one inside the other"
                raise KeyPathError(first, f"also given as {second} ({what}): give each value once")


def leaves(data, parts: tuple = ()):
    """``(parts, value)`` of every value in nested mappings and lists that is neither, its key
    parts as :func:`parse_key_path` gives them (``("arm", "links", 2, "mass")``)."""
    if isinstance(data, dict):
        for key, value in data.items():
            yield from leaves(value, (*parts, key))
    elif isinstance(data, list):
        for index, value in enumerate(data):
            yield from leaves(value, (*parts, index))
    else:
        yield parts, data


def with_values(data: dict, values: dict[str, object]) -> dict:
    """A deep copy of ``data`` with each key path of ``values`` set to its value.

    A missing last key of a mapping is added (validation then says whether the file format
    knows it); a missing mapping on the way is created; a list index must exist.

    Raises
    ------
    KeyPathError
        When a path cannot be set (an index past a list's end, a key into a number, ...), or
        two paths set one value (:func:`check_disjoint`).
    """
    check_disjoint(list(values))
    out = copy.deepcopy(data) if data is not None else {}
    for path, value in values.items():
        parts = parse_key_path(path)
        container = out
        for depth, part in enumerate(parts[:-1]):
            if isinstance(container, dict) and isinstance(part, str) and part not in container:
                container[part] = [] if isinstance(parts[depth + 1], int) else {}
            container = _step(container, part, path, depth)
        _check_container(container, parts[-1], path, len(parts) - 1)
        container[parts[-1]] = copy.deepcopy(value)
    return out


def _step(container, part: str | int, path: str, depth: int):
    _check_container(container, part, path, depth)
    if isinstance(part, int) or part in container:
        return container[part]
    raise KeyPathError(path, f"no key {part!r} at {_prefix(path, depth)}")


def _check_container(container, part: str | int, path: str, depth: int) -> None:
    where = _prefix(path, depth)
    if isinstance(part, int):
        if not isinstance(container, list):
            raise KeyPathError(path, f"{where} is not a list; cannot take item [{part}]")
        if part >= len(container):
            raise KeyPathError(path, f"{where} has {len(container)} item(s); no item [{part}]")
    elif not isinstance(container, dict):
        raise KeyPathError(path, f"{where} is not a mapping; cannot take key {part!r}")


def _prefix(path: str, depth: int) -> str:
    parts = parse_key_path(path)[:depth]
    return key_path(parts) if parts else "the top level"


__all__ = [
    "KeyPathError",
    "check_disjoint",
    "get_value",
    "leaves",
    "parse_key_path",
    "with_values",
]
