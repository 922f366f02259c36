"""Problem files: the YAML schema, its validation and the :class:`Problem` it yields.

This is the only module that knows the file format (documented in ``docs/problems.md``).
Units are SI; angles are degrees in files (``theta_deg``, ``thetadot_deg`` in deg/s) and
radians everywhere in code.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from . import flat
from .kinematics import ReachError, inverse_derivatives, inverse_position
from .limits import Limit, arm_limits
from .nodes import free_value_names, gamma_is_free, node_values, si_bounds
from .objectives import COLLOCATION_OBJECTIVES, LEAST_SQUARES, LINEAR, OBJECTIVES, weights
from .plan import GAMMA_ZERO, Node
from .robot import ARM_KINDS, BRANCHES, Arm, Link

Number = Annotated[float, Field(allow_inf_nan=False)]
Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]


def Pair(item):
    """A YAML list of exactly two items."""
    return Annotated[list[item], Field(min_length=2, max_length=2)]


def Triple(item):
    """A YAML list of exactly three items."""
    return Annotated[list[item], Field(min_length=3, max_length=3)]


class ProblemError(ValueError):
    """A problem file that cannot be used, with the file and the key path at fault."""

    def __init__(self, source: str, path: str, message: str) -> None:
        self.source, self.path, self.message = source, path, message
        where = f"{source}: {path}" if path else source
        super().__init__(f"{where}: {message}")


class _Spec(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True, frozen=True)


class LinkSpec(_Spec):
    """One link: ``length`` [m], ``mass`` [kg]; ``com`` [m] and ``inertia`` [kg m^2] optional."""

    length: Positive
    mass: Positive
    com: Number | None = None
    inertia: Annotated[float, Field(ge=0, allow_inf_nan=False)] | None = None


class ArmSpec(_Spec):
    """The arm: kind, base [m], gravity [m/s^2], IK branch and three links."""

    kind: Literal["RRR", "RPR", "PRR", "PPR"]
    base: Pair(Number) = [0.0, 0.0]
    gravity: Positive = 9.81
    branch: str | None = None
    links: Annotated[list[LinkSpec], Field(min_length=3, max_length=3)]


class StateSpec(_Spec):
    """A third-link state [m, deg, m/s, deg/s] with compensator values xi [m/s^2], eta [m/s^3]."""

    x: Number
    y: Number
    theta_deg: Number
    xdot: Number = 0.0
    ydot: Number = 0.0
    thetadot_deg: Number = 0.0
    xi: Number = 0.0
    eta: Number = 0.0


class ViaSpec(StateSpec):
    """A via state at time ``t`` [s]; ``eta_after`` [m/s^3] resets eta there."""

    t: Number
    eta_after: Number | None = None


class MotionSpec(_Spec):
    """The motion: duration [s], start, via states, goal."""

    duration: Positive
    start: StateSpec
    via: list[ViaSpec] = []
    goal: StateSpec


class ClosedFormSpec(_Spec):
    """Closed-form planner settings."""

    smooth_torque: bool = False


class LimitsSpec(_Spec):
    """Limits a real arm has (each entry null for none).

    ``torque`` [N m or N] for joints 1, 2; ``joint_position`` pairs [deg or m] and
    ``joint_velocity`` [deg/s or m/s] for joints 1..3.
    """

    torque: Pair(Positive | None) = [None, None]
    joint_position: Triple(Pair(Number) | None) | None = None
    joint_velocity: Triple(Positive | None) | None = None


class SolverSpec(_Spec):
    """Ipopt settings; ``hessian`` None means the objective's default
    (:func:`cpopt.objectives.default_hessian`)."""

    max_iter: Annotated[int, Field(gt=0)] = 1000
    tol: Positive = 1e-8
    print_level: Annotated[int, Field(ge=0, le=12)] = 0
    mu_strategy: Literal["adaptive", "monotone"] = "adaptive"
    hessian: Literal["exact", "gauss_newton"] | None = None


class OptimizerSpec(_Spec):
    """Optimizer settings (see docs/problems.md)."""

    curve: Literal["bspline", "polynomial"] = "bspline"
    degree: Annotated[int, Field(ge=7, le=15)] = 8
    coefficients: Annotated[int, Field(ge=8, le=60)] = 14
    objective: (
        Literal[OBJECTIVES] | dict[str, Annotated[float, Field(ge=0, allow_inf_nan=False)]]
    ) = "torque"
    gamma_min: Annotated[float, Field(ge=0, allow_inf_nan=False)] = 2.0
    gamma_sign: list[Literal["auto", "positive", "negative"]] | None = None
    smooth_torque: bool = True
    samples: Annotated[int, Field(ge=10, le=1000)] = 50
    limits: LimitsSpec = LimitsSpec()
    free: dict[str, Pair(Number | None)] = {}
    solver: SolverSpec = SolverSpec()

    @field_validator("objective")
    @classmethod
    def _known_objective(cls, value):
        if isinstance(value, dict):
            unknown = sorted(set(value) - set(OBJECTIVES))
            if unknown:
                raise ValueError(f"unknown objective term(s) {unknown}; expected {OBJECTIVES}")
            if not value or not any(value.values()):
                raise ValueError("give at least one objective term a positive weight")
        return value


class CollocationSpec(_Spec):
    """Direct-collocation peer settings (see docs/problems.md)."""

    intervals: Annotated[int, Field(ge=4, le=2000)] = 100
    method: Literal["collocation", "multiple_shooting"] = "collocation"
    degree: Annotated[int, Field(ge=1, le=9)] = 3
    steps: Annotated[int, Field(ge=1, le=20)] = 1
    gamma_constraint: bool = True
    solver: Literal["ipopt", "fatrop"] = "ipopt"
    warm_start: Literal["none", "flat"] = "none"
    replay_tolerance: Positive = 1e-3


class VerificationSpec(_Spec):
    """Verification settings: tracking poles [1/s] and trajectory samples per phase."""

    poles: Annotated[
        list[Annotated[float, Field(lt=0, allow_inf_nan=False)]], Field(min_length=4, max_length=4)
    ] = [-10.0, -10.0, -10.0, -10.0]
    samples: Annotated[int, Field(ge=11, le=20001)] = 401


class ProblemSpec(_Spec):
    """A whole problem file."""

    name: str | None = None
    description: str | None = None
    arm: ArmSpec
    motion: MotionSpec
    planner: Literal["closed_form", "optimize", "collocation"] = "closed_form"
    closed_form: ClosedFormSpec = ClosedFormSpec()
    optimizer: OptimizerSpec = OptimizerSpec()
    collocation: CollocationSpec = CollocationSpec()
    verification: VerificationSpec = VerificationSpec()


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
        The values the optimizer may choose, by name (:mod:`cpopt.nodes`), with their bounds in
        SI units (+-inf for none).
    limits : tuple of Limit
        The arm's limits in SI units (``optimizer.limits``).
    """

    name: str
    source: str
    arm: Arm
    nodes: tuple[Node, ...]
    spec: ProblemSpec
    free: dict[str, tuple[float, float]]
    limits: tuple[Limit, ...]

    @cached_property
    def values(self) -> dict[str, float]:
        """Every node value by name in SI units (free values at their initial guess)."""
        return node_values(self.nodes)

    @property
    def planner(self) -> str:
        """Planner to run: ``closed_form`` or ``optimize``."""
        return self.spec.planner

    def with_print_level(self, level: int) -> Problem:
        """A copy whose Ipopt output level is ``level`` (0 silent .. 12)."""
        opt = self.spec.optimizer
        solver = opt.solver.model_copy(update={"print_level": level})
        spec = self.spec.model_copy(update={"optimizer": opt.model_copy(update={"solver": solver})})
        return replace(self, spec=spec)


REMOVED_KEYS = {
    ("optimizer", "solver", "jit"): (
        "this key was removed: the optimizer's per-sample functions are now always compiled to "
        "C once per arm kind and cached in the user's cache folder (no setting needed; see "
        "'Compiled samples' in docs/problems.md); delete the key"
    ),
}
"""Keys that older files may have, with what replaced them."""


def _check_removed_keys(data: dict, source: str) -> None:
    for path, why in REMOVED_KEYS.items():
        node = data
        for key in path[:-1]:
            node = node.get(key) if isinstance(node, dict) else None
        if isinstance(node, dict) and path[-1] in node:
            raise ProblemError(source, ".".join(path), why)


def _key_path(loc) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out


def _allowed_keys(loc) -> list[str]:
    model: type[BaseModel] | None = ProblemSpec
    for part in loc[:-1]:
        if model is None or isinstance(part, int):
            continue
        field = model.model_fields.get(part)
        if field is None:
            return []
        ann = field.annotation
        inner = getattr(ann, "__args__", (ann,))
        model = next((a for a in inner if isinstance(a, type) and issubclass(a, BaseModel)), None)
        if model is None:
            for a in inner:  # list[ViaSpec] and the like
                for b in getattr(a, "__args__", ()):
                    if isinstance(b, type) and issubclass(b, BaseModel):
                        model = b
    return list(model.model_fields) if model else []


def _describe(error: dict) -> tuple[str, str]:
    loc = tuple(p for p in error["loc"] if not (isinstance(p, str) and "[" in p))
    path = _key_path(loc)
    kind = error["type"]
    given = error.get("input")
    if kind == "extra_forbidden":
        allowed = _allowed_keys(loc)
        close = difflib.get_close_matches(str(loc[-1]), allowed, n=1)
        hint = f"; did you mean '{close[0]}'?" if close else ""
        return path, f"unknown key{hint} (allowed here: {', '.join(allowed)})"
    if kind == "missing":
        return path, "required key is missing"
    msg = error["msg"]
    msg = msg[0].lower() + msg[1:]
    return path, f"{msg}, got {given!r}"


def _node(state: StateSpec, t: float) -> Node:
    return Node(
        t=t,
        x=state.x,
        y=state.y,
        theta=math.radians(state.theta_deg),
        xdot=state.xdot,
        ydot=state.ydot,
        thetadot=math.radians(state.thetadot_deg),
        xi=state.xi,
        eta=state.eta,
        eta_after=getattr(state, "eta_after", None),
    )


def _check_physics(spec: ProblemSpec, source: str) -> tuple[Arm, tuple[Node, ...]]:
    a = spec.arm
    allowed = BRANCHES[a.kind]
    if a.branch not in allowed and a.branch is not None:
        choices = ", ".join(str(b) for b in allowed)
        raise ProblemError(
            source, "arm.branch", f"a {a.kind} arm has branches {choices}, got {a.branch!r}"
        )
    for i, link in enumerate(a.links):
        if i == 2 and link.com is not None and link.com <= 0:
            raise ProblemError(
                source,
                "arm.links[2].com",
                f"the third link's centre of mass must lie beyond its joint "
                f"(> 0 m), got {link.com!r}",
            )
    arm = Arm(
        kind=a.kind,
        links=tuple(Link(l.length, l.mass, l.com, l.inertia) for l in a.links),  # noqa: E741
        base=a.base,
        gravity=a.gravity,
        branch=a.branch,
    )
    m = spec.motion
    T = m.duration
    prev = 0.0
    for i, via in enumerate(m.via):
        if not prev < via.t < T:
            raise ProblemError(
                source,
                f"motion.via[{i}].t",
                f"via times must increase strictly inside (0, {T:g}) s, got "
                f"{via.t:g} s after {prev:g} s",
            )
        prev = via.t
    nodes = (_node(m.start, 0.0), *(_node(v, v.t) for v in m.via), _node(m.goal, T))
    paths = ["motion.start", *(f"motion.via[{i}]" for i in range(len(m.via))), "motion.goal"]
    for node, path in zip(nodes, paths, strict=True):
        try:
            q = inverse_position(arm, node.x, node.y, node.theta)
            inverse_derivatives(
                arm, q, np.array([[node.xdot, node.ydot, node.thetadot]]), np.zeros((1, 3))
            )
        except ReachError as err:
            raise ProblemError(source, path, f"state not reachable: {err}") from None
    free = spec.optimizer.free if spec.planner != "closed_form" else {}
    names = free_value_names(len(spec.motion.via))
    for name, (lo, hi) in free.items():
        if name not in names:
            close = difflib.get_close_matches(name, names, n=1)
            hint = f"; did you mean '{close[0]}'?" if close else ""
            raise ProblemError(
                source,
                f"optimizer.free.{name}",
                f"not a value of this problem{hint} (names: {', '.join(names)})",
            )
        if lo is not None and hi is not None and lo > hi:
            raise ProblemError(
                source, f"optimizer.free.{name}", f"lower bound {lo:g} exceeds upper bound {hi:g}"
            )
    flat_plan = spec.planner != "collocation" or spec.collocation.warm_start == "flat"
    if flat_plan:
        _check_gamma(arm, nodes, paths, free, source)
    if spec.planner != "closed_form" and flat_plan:
        _check_optimizer(spec, len(nodes) - 1, source)
    if spec.planner == "collocation":
        _check_collocation(spec, source)
    return arm, nodes


def _check_optimizer(spec: ProblemSpec, phases: int, source: str) -> None:
    o = spec.optimizer
    count = o.coefficients if o.curve == "bspline" else o.degree + 1
    ends = 5 if o.smooth_torque else 4
    if count < 2 * ends or count < o.degree + 1:
        key = "optimizer.coefficients" if o.curve == "bspline" else "optimizer.degree"
        raise ProblemError(
            source,
            key,
            f"{count} coefficients per phase cannot hold {ends} boundary "
            f"conditions at each end (need >= {max(2 * ends, o.degree + 1)})",
        )
    if o.gamma_sign is not None and len(o.gamma_sign) != phases:
        raise ProblemError(
            source,
            "optimizer.gamma_sign",
            f"give one sign per phase ({phases}), got {len(o.gamma_sign)}",
        )
    if weights(o.objective).get("duration") and "duration" not in o.free:
        raise ProblemError(
            source, "optimizer.objective", "a duration objective needs 'duration' in optimizer.free"
        )
    not_squares = sorted(set(weights(o.objective)) - LEAST_SQUARES - LINEAR)
    if o.solver.hessian == "gauss_newton" and not_squares:
        raise ProblemError(
            source,
            "optimizer.solver.hessian",
            f"gauss_newton needs a least-squares objective ({', '.join(sorted(LEAST_SQUARES))}, "
            f"plus {', '.join(sorted(LINEAR))}); {', '.join(not_squares)} is not one: use exact",
        )


def _check_collocation(spec: ProblemSpec, source: str) -> None:
    o = spec.optimizer
    terms = weights(o.objective)
    unsupported = sorted(k for k in terms if k not in COLLOCATION_OBJECTIVES)
    if unsupported:
        raise ProblemError(
            source,
            "optimizer.objective",
            f"the collocation planner minimizes {', '.join(COLLOCATION_OBJECTIVES)}; "
            f"{', '.join(unsupported)} belongs to the flat optimizer (v is the CP's fourth "
            "derivative; |power| under piecewise-constant torques has no smooth transcription)",
        )
    if terms.get("duration") and "duration" not in o.free:
        raise ProblemError(
            source, "optimizer.objective", "a duration objective needs 'duration' in optimizer.free"
        )
    if spec.collocation.solver == "fatrop":
        _check_fatrop(spec, source)


def _check_fatrop(spec: ProblemSpec, source: str) -> None:
    """Fatrop needs the single-stage, fixed-time structure it detects (see docs/problems.md)."""
    why = None
    if spec.motion.via:
        why = (
            f"fatrop solves single-phase problems only (this one has {len(spec.motion.via) + 1} "
            "phases: rockit's multi-stage transcription defeats Fatrop's structure detection)"
        )
    elif spec.collocation.method != "multiple_shooting":
        why = "fatrop needs collocation.method: multiple_shooting (rockit's direct collocation "
        why += "does not give Fatrop its stage structure)"
    elif {"duration"} & set(spec.optimizer.free) or "gamma_margin" in weights(
        spec.optimizer.objective
    ):
        why = "fatrop needs a fixed duration and no gamma_margin objective (a free time or a "
        why += "margin variable is shared by all stages, which Fatrop's structure cannot hold)"
    if why:
        raise ProblemError(source, "collocation.solver", why + "; use solver: ipopt")


def _check_gamma(arm, nodes, paths, free, source) -> None:
    """gamma != 0 at nodes with fixed values, and one sign within each phase."""
    gam = [float(flat.gamma(n.state(), arm.K, arm.gravity)) for n in nodes]
    fixed = [not gamma_is_free(p.removeprefix("motion."), free) for p in paths]
    for g, is_fixed, path in zip(gam, fixed, paths, strict=True):
        if is_fixed and abs(g) < GAMMA_ZERO:
            raise ProblemError(
                source,
                f"{path}.xi",
                f"gamma = xi - K thetadot^2 + g0 sin(theta) = {g:.3g} m/s^2 at "
                "this node: the flat map is singular there; choose xi so that "
                "gamma != 0",
            )
    for i in range(len(nodes) - 1):
        if fixed[i] and fixed[i + 1] and gam[i] * gam[i + 1] < 0:
            raise ProblemError(
                source,
                f"{paths[i + 1]}.xi",
                f"gamma changes sign in phase {i + 1} (gamma = {gam[i]:.3g} at its "
                f"start, {gam[i + 1]:.3g} m/s^2 at its end), so it vanishes in "
                "between; choose xi at the nodes so that gamma keeps one sign",
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
        Default name when the data has none.

    Raises
    ------
    ProblemError
        Naming the source, the key path and what was expected.
    """
    if not isinstance(data, dict):
        kind = "an empty document" if data is None else f"a {type(data).__name__}"
        raise ProblemError(source, "", f"expected a mapping with keys arm, motion, ...; got {kind}")
    _check_removed_keys(data, source)
    try:
        spec = ProblemSpec.model_validate(data)
    except ValidationError as err:
        # a typo shows as an unknown key and a missing one: report the typo
        errors = sorted(err.errors(), key=lambda e: e["type"] != "extra_forbidden")
        path, message = _describe(errors[0])
        raise ProblemError(source, path, message) from None
    arm, nodes = _check_physics(spec, source)
    return Problem(
        name=spec.name or name or "problem",
        source=source,
        arm=arm,
        nodes=nodes,
        spec=spec,
        free=si_bounds(spec.optimizer.free),
        limits=arm_limits(spec.optimizer.limits, arm),
    )


def load_problem(path: str | Path) -> Problem:
    """Read and validate a YAML problem file.

    Raises
    ------
    ProblemError
        For a missing, unreadable, empty or malformed file, or invalid content.
    """
    p = Path(path)
    source = str(path)
    if not p.exists():
        raise ProblemError(source, "", "no such file")
    if p.is_dir():
        raise ProblemError(source, "", "is a directory, expected a YAML problem file")
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as err:
        raise ProblemError(source, "", f"cannot read the file ({err})") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(err, "problem", None) or str(err)
        raise ProblemError(source, "", f"malformed YAML{where}: {problem}") from None
    return parse_problem(data, source, name=p.stem)


def bundled_problems() -> list[Path]:
    """The problem files shipped in ``problems/`` (next to the package in a checkout)."""
    root = Path(__file__).resolve().parent.parent / "problems"
    return sorted(root.glob("*.yaml"))


__all__ = ["ARM_KINDS", "Problem", "ProblemError", "load_problem", "parse_problem"]
