"""Building a :class:`Problem` from problem data or a file: the schema, then the checks."""

from __future__ import annotations

import copy
import math
import numbers
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path

from pydantic import ValidationError

from ..closedform.nodes import node_names, node_values, si_bounds
from ..closedform.plan import Node
from ..io.keypath import KeyPathError, with_values
from ..io.safe_yaml import YamlInputError, echo, read_yaml
from ..model.limits import Limit, arm_limits
from ..model.robot import Arm
from ..urdf import arm_urdf
from .gamma import GammaSide, gamma_sides
from .messages import check_removed_keys, describe_error
from .schema import ProblemError, ProblemSpec, safe_name
from .urdf_arm import expand_urdf
from .validate import check_physics


@dataclass(frozen=True)
class Problem:
    """A validated problem, ready for a planner.

    Attributes
    ----------
    name : str
        Problem name (the file's stem unless the file names it).
    source : str
        Where it came from (file path or ``<python>``).
    arm : Arm
        The arm.
    nodes : tuple of Node
        Start, via states and goal in SI units and radians (free values at their initial guess).
    spec : ProblemSpec
        The validated file content (planner and optimizer settings).
    free : dict of str to (float, float)
        The values the optimizer may choose, by name (:mod:`cpopt.closedform.nodes`), with
        their bounds in SI units (+-inf for none).
    limits : tuple of Limit
        The arm's limits in SI units (``optimizer.limits``).
    data : dict
        The problem data it was validated from (the file's content, with any overrides), which
        :meth:`replace` changes and validates again.
    """

    name: str
    source: str
    arm: Arm
    nodes: tuple[Node, ...]
    spec: ProblemSpec
    free: dict[str, tuple[float, float]]
    limits: tuple[Limit, ...]
    data: dict = field(default_factory=dict, repr=False, compare=False)

    @cached_property
    def values(self) -> dict[str, float]:
        """Every node value by name in SI units (free values at their initial guess)."""
        return node_values(self.nodes)

    @cached_property
    def gamma_sides(self) -> tuple[list[GammaSide], list[GammaSide]]:
        """gamma on arrival at each node and on departure from it (:func:`gamma_sides`)."""
        paths = [f"motion.{name}" for name in node_names(len(self.nodes))]
        return gamma_sides(self.arm, self.nodes, paths, self.free)

    @property
    def planner(self) -> str:
        """Planner to run: ``closed_form`` or ``optimize``."""
        return self.spec.planner

    @property
    def max_time(self) -> float:
        """Wall-clock limit of planning and verification together [s]."""
        return self.spec.optimizer.solver.max_time

    def replace(self, **overrides) -> Problem:
        """The problem with values changed by key path, validated again.

        Parameters
        ----------
        **overrides
            Values by key path, the syntax error messages use:
            ``problem.replace(**{"motion.duration": 2.0, "arm.links[2].mass": 0.5})``, or
            ``problem.replace(planner="optimize")``. Units are the file's (degrees in
            ``theta_deg``).

        Raises
        ------
        ProblemError
            For a key path that does not lead into the data, or a value the file format
            refuses, naming the key path.
        """
        return parse_problem(overridden(self.data, overrides, self.source), self.source, self.name)

    def to_urdf(self) -> str:
        """The arm as a URDF document (``cpopt export-urdf``), which ``arm: {urdf: FILE}``
        reads back to the same arm: joints ``joint1``..``joint3`` (revolute axes ``0 -1 0`` in
        the world's x-z plane, z up), the torque limits of ``optimizer.limits.torque`` as the
        actuated joints' effort limits, the passive third joint without a transmission.

        Returns
        -------
        str
            The URDF text (SI units).
        """
        return arm_urdf(self.arm, tuple(self.spec.optimizer.limits.torque), name=self.name)

    def with_print_level(self, level: int) -> Problem:
        """A copy whose Ipopt output level is ``level`` (0 silent .. 12).

        Raises
        ------
        ProblemError
            For a level that is not a whole number 0..12.
        """
        if not (isinstance(level, numbers.Integral) and not isinstance(level, bool)) or not (
            0 <= level <= 12
        ):
            raise ProblemError(
                self.source, "level", f"expected a whole number 0..12, got {echo(level)}"
            )
        return self._with_solver(print_level=int(level))

    def with_time_limit(self, seconds: float) -> Problem:
        """A copy whose wall-clock limit ``optimizer.solver.max_time`` is ``seconds``.

        Raises
        ------
        ProblemError
            For a value that is not a finite number of seconds > 0.
        """
        check_seconds(seconds, self.source, "seconds")
        return self._with_solver(max_time=float(seconds))

    def _with_solver(self, **update) -> Problem:
        opt = self.spec.optimizer
        solver = opt.solver.model_copy(update=update)
        spec = self.spec.model_copy(update={"optimizer": opt.model_copy(update={"solver": solver})})
        return replace(self, spec=spec)


def check_seconds(value, source: str, argument: str) -> None:
    """Refuse a duration that is not a finite number of seconds > 0 (True/False included).

    Raises
    ------
    ProblemError
        With ``argument`` as its key path (``time_limit``).
    """
    real = isinstance(value, numbers.Real) and not isinstance(value, bool)
    if not real or not (math.isfinite(value) and value > 0):
        raise ProblemError(
            source, argument, f"expected a finite number of seconds > 0, got {echo(value)}"
        )


def parse_problem(data, source: str = "<python>", name: str | None = None) -> Problem:
    """Validate problem data (the content of a YAML file) into a :class:`Problem`.

    Parameters
    ----------
    data : dict
        The parsed YAML document.
    source : str
        Shown in error messages.
    name : str, optional
        Default name when the data has none (made a safe folder name, see :func:`safe_name`).

    Raises
    ------
    ProblemError
        Naming the source, the key path and what was expected.
    """
    if not isinstance(data, dict):
        kind = "an empty document" if data is None else f"a {type(data).__name__}"
        raise ProblemError(source, "", f"expected a mapping with keys arm, motion, ...; got {kind}")
    check_removed_keys(data, source)
    plain = expand_urdf(data, source)
    try:
        spec = ProblemSpec.model_validate(plain)
    except ValidationError as err:
        # a typo shows as an unknown key and a missing one: report the typo
        errors = sorted(err.errors(), key=lambda e: e["type"] != "extra_forbidden")
        path, message = describe_error(errors[0])
        raise ProblemError(source, path, message) from None
    arm, nodes = check_physics(spec, source)
    return Problem(
        name=spec.name or safe_name(name or "problem"),
        source=source,
        arm=arm,
        nodes=nodes,
        spec=spec,
        free=si_bounds(spec.optimizer.free),
        limits=arm_limits(spec.optimizer.limits, arm),
        data=copy.deepcopy(data),
    )


def overridden(data: dict, overrides: dict, source: str) -> dict:
    """A copy of problem data with values set by key path (:func:`cpopt.io.keypath.with_values`).

    Raises
    ------
    ProblemError
        For a key path that is malformed or cannot be set, naming it.
    """
    try:
        return with_values(data, overrides)
    except KeyPathError as err:
        raise ProblemError(source, err.path, err.message) from None


def read_problem(source: str | Path | dict, overrides: dict | None = None) -> Problem:
    """A problem from a YAML file or from problem data, with values set by key path.

    Parameters
    ----------
    source : str, Path or dict
        A problem file, or its content as a dict (not changed).
    overrides : dict, optional
        Values by key path (``{"motion.duration": 2.0}``), set before validation.

    Raises
    ------
    ProblemError
        For an unreadable file, a key path that cannot be set or invalid content, naming the
        source and the key path.
    """
    if isinstance(source, dict):
        return parse_problem(overridden(source, overrides or {}, "<python>"))
    if not isinstance(source, str | Path):
        raise TypeError(f"a problem file or a dict of problem data, not {type(source).__name__}")
    name = str(source)
    try:
        data = read_yaml(source)
    except YamlInputError as err:
        raise ProblemError(name, err.path, err.message) from None
    if overrides and isinstance(data, dict):
        data = overridden(data, overrides, name)
    return parse_problem(data, name, name=safe_name(Path(source).stem))


def load_problem(path: str | Path) -> Problem:
    """Read and validate a YAML problem file (see :mod:`cpopt.io.safe_yaml` for the limits).

    Raises
    ------
    ProblemError
        For a missing, unreadable, empty, oversized or malformed file, or invalid content.
    """
    return read_problem(path)


def bundled_problems() -> list[Path]:
    """The problem files shipped with cpopt.

    They are package data, ``cpopt/problems/`` in an installed wheel; in a checkout that is a
    link to ``problems/`` at the top (and ``problems/`` is used where links are not checked
    out as links).
    """
    package = Path(__file__).resolve().parent.parent  # cpopt/, above cpopt/problem/
    for root in (package / "problems", package.parent / "problems"):
        files = sorted(root.glob("*.yaml"))
        if files:
            return files
    return []
