"""Problem files: the YAML schema, its validation and the :class:`Problem` it yields.

This is the only module that knows the file format (documented in ``docs/problems.md``).
Units are SI; angles are degrees in files (``theta_deg``, ``thetadot_deg`` in deg/s) and
radians everywhere in code.
"""

from __future__ import annotations

import difflib
import itertools
import math
import re
import typing
from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Discriminator,
    Field,
    Tag,
    ValidationError,
    field_validator,
)

from . import flat
from .dynamics import holding_torque
from .kinematics import ReachError, inverse_derivatives, inverse_position
from .limits import Limit, arm_limits
from .nodes import (
    free_value_names,
    freed_fields,
    gamma_is_free,
    has_reset,
    node_names,
    node_values,
    si_bounds,
)
from .objectives import COLLOCATION_OBJECTIVES, LEAST_SQUARES, LINEAR, OBJECTIVES, weights
from .paths import PathShape, node_mismatch, order_fields
from .plan import GAMMA_ZERO, Node
from .robot import ARM_KINDS, BRANCHES, G0, Arm, Link
from .safe_yaml import YamlInputError, echo, key_path, read_yaml
from .tracking.dfl import DEFAULT_POLES
from .tracking.tvlqr import DEFAULT_Q, DEFAULT_QF

Number = Annotated[float, Field(allow_inf_nan=False)]


def _whole(value):
    """``1e3`` (a float in YAML) where a count is expected: the integer 1000."""
    return int(value) if isinstance(value, float) and value.is_integer() else value


WHOLE = BeforeValidator(_whole)
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
    """A via state at time ``t`` [s]; ``xi_after`` [m/s^2] and ``eta_after`` [m/s^3] reset xi
    and eta there (a xi reset lets the next phase take the other sign of gamma)."""

    t: Number
    xi_after: Number | None = None
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


DEFAULT_MAX_TIME = 300.0
"""Default wall-clock limit of one problem [s]: planning and verification together."""


class SolverSpec(_Spec):
    """Ipopt settings and the problem's wall-clock limit ``max_time`` [s]; ``hessian`` None
    means the objective's default (:func:`cpopt.objectives.default_hessian`)."""

    max_iter: Annotated[int, WHOLE, Field(gt=0)] = 1000
    tol: Positive = 1e-8
    print_level: Annotated[int, WHOLE, Field(ge=0, le=12)] = 0
    mu_strategy: Literal["adaptive", "monotone"] = "adaptive"
    hessian: Literal["exact", "gauss_newton"] | None = None
    max_time: Positive = DEFAULT_MAX_TIME


class FreePointSpec(_Spec):
    """A free control point: its initial guess ``x``, ``y`` [m] and ``bounds``
    [[x_lo, x_hi], [y_lo, y_hi]] [m] (null for none)."""

    x: Number
    y: Number
    bounds: Pair(Pair(Number | None)) = [[None, None], [None, None]]


class TimingSpec(_Spec):
    """A phase's timing law s(t): a clamped uniform B-spline of ``degree`` with
    ``coefficients`` coefficients on the phase's normalised time."""

    degree: Annotated[int, Field(ge=5, le=11)] = 7
    coefficients: Annotated[int, Field(ge=8, le=60)] = 16


def _point_kind(value) -> str:
    return "free" if isinstance(value, dict | FreePointSpec) else "fixed"


ControlPoint = Annotated[
    Annotated[Pair(Number), Tag("fixed")] | Annotated[FreePointSpec, Tag("free")],
    Discriminator(_point_kind),
]
"""A control point: fixed ``[x, y]`` or free ``{x, y, bounds}`` (a mapping is validated as the
free kind only, so its errors name its keys)."""
UNION_TAGS = frozenset({"fixed", "free"})


class PathSpec(_Spec):
    """A phase's CP path Y(s), s in [0, 1]: ``degree`` and ``control_points``, each fixed
    ``[x, y]`` [m] or free ``{x, y, bounds}``; the first and last are the nodes' CPs."""

    degree: Annotated[int, Field(ge=1, le=7)]
    control_points: Annotated[list[ControlPoint], Field(min_length=2)]
    timing: TimingSpec = TimingSpec()


MAX_SWITCHES = 8
"""Most switches of the sign of gamma the optimizer may add to a motion."""


class OptimizerSpec(_Spec):
    """Optimizer settings (see docs/problems.md)."""

    curve: Literal["bspline", "polynomial", "path_timing"] = "bspline"
    degree: Annotated[int, WHOLE, Field(ge=7, le=15)] = 8
    coefficients: Annotated[int, WHOLE, Field(ge=8, le=60)] = 14
    objective: (
        Literal[OBJECTIVES] | dict[str, Annotated[float, Field(ge=0, allow_inf_nan=False)]]
    ) = "torque"
    gamma_min: Number = 2.0
    gamma_sign: list[Literal["auto", "positive", "negative"]] | None = None
    gamma_switches: Literal["auto"] | Annotated[int, WHOLE, Field(ge=0, le=MAX_SWITCHES)] = 0
    switch_search: Literal["seed", "greedy"] = "seed"
    smooth_torque: bool = True
    samples: Annotated[int, WHOLE, Field(ge=10, le=1000)] = 50
    limits: LimitsSpec = LimitsSpec()
    free: dict[str, Pair(Number | None)] = {}
    solver: SolverSpec = SolverSpec()
    path: list[PathSpec] | None = None

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

    intervals: Annotated[int, WHOLE, Field(ge=4, le=2000)] = 100
    method: Literal["collocation", "multiple_shooting"] = "collocation"
    degree: Annotated[int, WHOLE, Field(ge=1, le=9)] = 3
    steps: Annotated[int, WHOLE, Field(ge=1, le=20)] = 1
    gamma_constraint: bool = True
    solver: Literal["ipopt", "fatrop"] = "ipopt"
    warm_start: Literal["none", "flat"] = "none"
    replay_tolerance: Positive = 1e-3


class VerificationSpec(_Spec):
    """Verification settings: tracking poles [1/s] and trajectory samples per phase."""

    poles: Annotated[
        list[Annotated[float, Field(lt=0, allow_inf_nan=False)]], Field(min_length=4, max_length=4)
    ] = [-10.0, -10.0, -10.0, -10.0]
    samples: Annotated[int, WHOLE, Field(ge=11, le=20001)] = 401


NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,99}")
"""A problem name: one safe folder name under ``--out`` (no '/', not '.' or '..')."""


def safe_name(text: str) -> str:
    """A file stem turned into a valid problem name (unsafe characters become '_')."""
    name = re.sub(r"[^A-Za-z0-9_.-]", "_", text).lstrip(".-")[:100]
    return name or "problem"


NonNegative = Annotated[float, Field(ge=0, allow_inf_nan=False)]


class PlantLinkSpec(_Spec):
    """Overrides of one link of the arm for the simulated plant (same meaning as ``LinkSpec``)."""

    length: Positive | None = None
    mass: Positive | None = None
    com: Number | None = None
    inertia: NonNegative | None = None


class FrictionSpec(_Spec):
    """Joint friction of joints 1..3: viscous [N m s/rad or N s/m], Coulomb [N m or N]."""

    viscous: Triple(NonNegative) = [0.0, 0.0, 0.0]
    coulomb: Triple(NonNegative) = [0.0, 0.0, 0.0]


class PlantSpec(_Spec):
    """The simulated arm: link overrides, friction, torque limits [N m or N]."""

    links: Triple(PlantLinkSpec | None) | None = None
    friction: FrictionSpec = FrictionSpec()
    torque_limit: Pair(Positive | None) | None = None


class NoiseSpec(_Spec):
    """Standard deviations of the measured joint positions [rad or m] and velocities, seed."""

    position: Triple(NonNegative) = [0.0, 0.0, 0.0]
    velocity: Triple(NonNegative) = [0.0, 0.0, 0.0]
    seed: Annotated[int, Field(ge=0)] = 0


class TrackingSpec(_Spec):
    """Tracking of the plan by a controller on a realistic plant (see docs/problems.md)."""

    controller: Literal["tvlqr", "dfl"] = "tvlqr"
    rate_hz: Annotated[float, Field(gt=0, le=100000, allow_inf_nan=False)] = 1000.0
    Q: Annotated[list[NonNegative], Field(min_length=6, max_length=6)] = list(DEFAULT_Q)
    R: Pair(Positive) | None = None  # absent: relative to the plan's peak torques
    Qf: Annotated[list[NonNegative], Field(min_length=6, max_length=6)] = list(DEFAULT_QF)
    poles: Annotated[
        list[Annotated[float, Field(lt=0, allow_inf_nan=False)]], Field(min_length=4, max_length=4)
    ] = list(DEFAULT_POLES)
    noise: NoiseSpec = NoiseSpec()
    plant: PlantSpec = PlantSpec()


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
    tracking: TrackingSpec | None = None

    @field_validator("name")
    @classmethod
    def _safe_name(cls, value):
        if value is not None and not NAME.fullmatch(value):
            raise ValueError(
                "the name becomes a folder under --out: use letters, digits, '_', '.' and '-' "
                "(at most 100, the first a letter, digit or '_'; no '/', '.' or '..')"
            )
        return value


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

    def with_print_level(self, level: int) -> Problem:
        """A copy whose Ipopt output level is ``level`` (0 silent .. 12)."""
        return self._with_solver(print_level=level)

    def with_time_limit(self, seconds: float) -> Problem:
        """A copy whose wall-clock limit ``optimizer.solver.max_time`` is ``seconds``."""
        return self._with_solver(max_time=float(seconds))

    def _with_solver(self, **update) -> Problem:
        opt = self.spec.optimizer
        solver = opt.solver.model_copy(update=update)
        spec = self.spec.model_copy(update={"optimizer": opt.model_copy(update={"solver": solver})})
        return replace(self, spec=spec)


def _model_in(annotation) -> type[BaseModel] | None:
    """The first pydantic model inside a type annotation (through lists, unions, Annotated)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in typing.get_args(annotation):
        found = _model_in(arg)
        if found is not None:
            return found
    return None


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


def _allowed_keys(loc) -> list[str]:
    model: type[BaseModel] | None = ProblemSpec
    for part in loc[:-1]:
        if model is None or isinstance(part, int):
            continue
        field = model.model_fields.get(part)
        if field is None:
            return []
        model = _model_in(field.annotation)
    return list(model.model_fields) if model else []


FREE_NAME = re.compile(r"(start|goal|via\[\d+\])\.\w+")
"""A free value's name (``via[0].xi_after``): a key of ``optimizer.free``, not a type tag."""


def _user_keys(loc: tuple) -> tuple:
    """The parts of a pydantic error location that are the user's keys and indices: type tags
    (``list[...]``) and the tags of the control points' union (after an index) are dropped."""
    keys = []
    for part in loc:
        tag = isinstance(part, str) and (
            ("[" in part and not FREE_NAME.fullmatch(part))
            or (part in UNION_TAGS and keys and isinstance(keys[-1], int))
        )
        if not tag:
            keys.append(part)
    return tuple(keys)


def _describe(error: dict) -> tuple[str, str]:
    loc = _user_keys(error["loc"])
    path = key_path(loc)
    kind = error["type"]
    given = error.get("input")
    if kind == "extra_forbidden":
        allowed = _allowed_keys(loc)
        return (
            path,
            f"unknown key{_suggestion(str(loc[-1]), allowed)} (allowed here: {', '.join(allowed)})",
        )
    if kind == "missing":
        return path, "required key is missing"
    msg = error["msg"]
    msg = msg[0].lower() + msg[1:]
    return path, f"{msg}, got {echo(given)}"


def _suggestion(given: str, allowed: list[str]) -> str:
    """``; did you mean 'theta_deg'?``: a name that only lacks its unit first, then the closest."""
    low = given.lower()
    for name in allowed:
        if low in (name.lower(), name.lower().removesuffix("_deg")):
            return f"; did you mean '{name}'?"
    close = difflib.get_close_matches(given, allowed, n=1)
    return f"; did you mean '{close[0]}'?" if close else ""


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
        xi_after=getattr(state, "xi_after", None),
    )


def _check_physics(spec: ProblemSpec, source: str) -> tuple[Arm, tuple[Node, ...]]:
    _check_ranges(spec, source)
    arm = _arm(spec.arm, source)
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
    joints = [_joint_position(arm, n, p, source) for n, p in zip(nodes, paths, strict=True)]
    _check_limits(spec, arm, nodes, joints, source)
    free = spec.optimizer.free if spec.planner != "closed_form" else {}
    _check_free(spec, free, source)
    flat_plan = spec.planner != "collocation" or spec.collocation.warm_start == "flat"
    _check_switches(spec, source)
    if flat_plan:
        sides = _check_gamma(spec, arm, nodes, paths, free, source)
    if spec.planner != "closed_form" and flat_plan:
        _check_optimizer(spec, len(nodes) - 1, source)
        _check_signs(spec.optimizer, sides, source)
        _check_paths(spec, arm, nodes, free, source)
    if spec.planner == "collocation":
        _check_collocation(spec, source)
    if spec.tracking is not None:
        check_tracking(spec, source)
    return arm, nodes


def _arm(a: ArmSpec, source: str) -> Arm:
    """The arm of the file, with ``branch: none`` read as the single branch of RPR and PPR."""
    allowed = BRANCHES[a.kind]
    branch = None if a.branch is None or a.branch.lower() == "none" else a.branch
    if a.branch is not None and branch not in allowed:
        choices = ", ".join("none" if b is None else b for b in allowed)
        raise ProblemError(
            source, "arm.branch", f"a {a.kind} arm has branches {choices}, got {echo(a.branch)}"
        )
    arm = Arm(
        kind=a.kind,
        links=tuple(Link(l.length, l.mass, l.com, l.inertia) for l in a.links),  # noqa: E741
        base=a.base,
        gravity=a.gravity,
        branch=branch,
    )
    l3 = a.links[2].length
    if arm.K / l3 > 100:  # (I3 + m3 d3^2) / (m3 d3) grows without bound as d3 -> 0
        raise ProblemError(
            source,
            "arm.links[2].com" if a.links[2].com is not None else "arm.links[2].inertia",
            f"the centre of percussion lies K = {arm.K:.4g} m from the third joint, more than "
            f"100 link lengths ({100 * l3:g} m): the centre of mass is too close to the joint "
            "for its inertia",
        )
    return arm


def _joint_position(arm: Arm, node: Node, path: str, source: str) -> np.ndarray:
    """The joint position (3,) of a node's state, or a ProblemError when it is out of reach."""
    try:
        q = inverse_position(arm, node.x, node.y, node.theta)
        inverse_derivatives(
            arm, q, np.array([[node.xdot, node.ydot, node.thetadot]]), np.zeros((1, 3))
        )
    except ReachError as err:
        raise ProblemError(source, path, f"state not reachable: {err}") from None
    return np.asarray(q, float).ravel()


PHYSICAL_RANGES = {
    "arm.base[]": (-1e3, 1e3, "m"),
    "arm.gravity": (0.1, 100.0, "m/s^2"),
    "arm.links[].length": (1e-3, 100.0, "m"),
    "arm.links[].mass": (1e-3, 1e4, "kg"),
    "motion.duration": (0.01, 1e4, "s"),
    "motion.<node>.theta_deg": (-3600.0, 3600.0, "deg"),
    "motion.<node>.xdot": (-1e3, 1e3, "m/s"),
    "motion.<node>.ydot": (-1e3, 1e3, "m/s"),
    "motion.<node>.thetadot_deg": (-1e5, 1e5, "deg/s"),
    "motion.<node>.xi": (-1e4, 1e4, "m/s^2"),
    "motion.<node>.eta": (-1e6, 1e6, "m/s^3"),
    "motion.<node>.eta_after": (-1e6, 1e6, "m/s^3"),
    "optimizer.gamma_min": (GAMMA_ZERO, 1e3, "m/s^2"),
    "optimizer.limits.torque[]": (0.0, 1e7, "N m or N"),
    "optimizer.limits.joint_position[][]": (-3600.0, 3600.0, "deg or m"),
    "optimizer.limits.joint_velocity[]": (0.0, 1e5, "deg/s or m/s"),
    "optimizer.solver.tol": (1e-12, 1.0, ""),
    "optimizer.solver.max_time": (0.0, 1e6, "s"),
    "verification.poles[]": (-100.0, -1e-2, "1/s"),
}
"""Values cpopt accepts, by key (``[]`` any index, ``<node>`` start, via[i] or goal): outside
them the dynamics are so ill-conditioned that a solve or a simulation would only crawl."""


def _leaves(data, parts=()):
    """(key parts, value) of every number in nested dicts and lists."""
    if isinstance(data, dict):
        for key, value in data.items():
            yield from _leaves(value, (*parts, key))
    elif isinstance(data, list):
        for i, value in enumerate(data):
            yield from _leaves(value, (*parts, i))
    elif isinstance(data, int | float) and not isinstance(data, bool):
        yield parts, float(data)


def _range_key(parts) -> str:
    pattern = key_path(["[]" if isinstance(p, int) else p for p in parts]).replace(".[]", "[]")
    for node in ("motion.start.", "motion.goal.", "motion.via[]."):
        pattern = pattern.replace(node, "motion.<node>.")
    return pattern


def _check_ranges(spec: ProblemSpec, source: str) -> None:
    """Every number within :data:`PHYSICAL_RANGES`; gamma_min > 0; com and inertia vs length."""
    gamma_min = spec.optimizer.gamma_min
    if gamma_min <= 0:
        raise ProblemError(
            source,
            "optimizer.gamma_min",
            f"must be > 0, got {gamma_min:g}: the flat map is singular at gamma = 0 (theta and "
            "the torques are undetermined there), so a plan keeps |gamma| >= gamma_min > 0",
        )
    for parts, value in _leaves(spec.model_dump(exclude={"optimizer": {"free"}})):
        bounds = PHYSICAL_RANGES.get(_range_key(parts))
        if bounds is not None and not bounds[0] <= value <= bounds[1]:
            lo, hi, unit = bounds
            raise ProblemError(
                source,
                key_path(parts),
                f"{value:g} {unit} lies outside the physical range cpopt accepts, "
                f"[{lo:g}, {hi:g}] {unit} (see 'Physical ranges' in docs/problems.md)",
            )
    for i, link in enumerate(spec.arm.links):
        reach = 10 * link.length
        if link.com is not None and not (0 if i == 2 else -reach) < link.com <= reach:
            where = "beyond its joint, " if i == 2 else ""
            raise ProblemError(
                source,
                f"arm.links[{i}].com",
                f"the centre of mass must lie {where}within 10 link lengths of the joint "
                f"({'0' if i == 2 else f'{-reach:g}'} < com <= {reach:g} m), got {link.com:g} m",
            )
        if link.inertia is not None and link.inertia > link.mass * reach**2:
            raise ProblemError(
                source,
                f"arm.links[{i}].inertia",
                f"{link.inertia:g} kg m^2 exceeds mass * (10 length)^2 = "
                f"{link.mass * reach**2:g} kg m^2, more than any link of this size can have",
            )


def _check_limits(spec, arm: Arm, nodes, joints, source: str) -> None:
    """Joint position bounds in order; torque limits able to hold the arm at its rest ends."""
    lim = spec.optimizer.limits
    for i, pair in enumerate(lim.joint_position or ()):
        if pair is not None and pair[0] > pair[1]:
            raise ProblemError(
                source,
                f"optimizer.limits.joint_position[{i}]",
                f"lower bound {pair[0]:g} exceeds upper bound {pair[1]:g} (give [lower, upper])",
            )
    if all(t is None for t in lim.torque):
        return
    units = ["N m" if r else "N" for r in arm.revolute]
    free = spec.optimizer.free if spec.planner != "closed_form" else {}
    for index, name in ((0, "start"), (len(nodes) - 1, "goal")):
        node = nodes[index]
        # the arm rests at the start before the motion (and at a goal with xi = 0 after it)
        fields = ["x", "y", "theta_deg", "xdot", "ydot", "thetadot_deg"] + ["xi"] * (name == "goal")
        holds = node.at_rest and (name == "start" or node.xi == 0)
        if not holds or any(f"{name}.{f}" in free for f in fields):
            continue
        tau = holding_torque(arm, joints[index])
        for i, tmax in enumerate(lim.torque):
            if tmax is not None and abs(tau[i]) > tmax:
                raise ProblemError(
                    source,
                    f"optimizer.limits.torque[{i}]",
                    f"|tau{i + 1}| <= {tmax:g} {units[i]} cannot even hold the arm at rest at "
                    f"motion.{name}: the static holding torque there is {tau[i]:.4g} "
                    f"{units[i]}",
                )


def _file_value(spec: ProblemSpec, name: str) -> float:
    """The file's value of a free value's name (its initial guess), in the file's units."""
    if name == "duration":
        return spec.motion.duration
    node, field = name.split(".", 1)
    m = spec.motion
    state = {"start": m.start, "goal": m.goal}.get(node) or m.via[int(node[4:-1])]
    if field.endswith("_after") and getattr(state, field) is None:  # no reset in the file
        return getattr(state, field.removesuffix("_after"))
    return getattr(state, field)


def _interval(lo: float | None, hi: float | None) -> str:
    """``[lo, hi]`` with a missing bound as -inf or inf."""
    return f"[{'-inf' if lo is None else f'{lo:g}'}, {'inf' if hi is None else f'{hi:g}'}]"


def _check_free(spec: ProblemSpec, free: dict, source: str) -> None:
    """Known names, bounds in order and each guess (the file's value) within its bounds."""
    names = free_value_names(len(spec.motion.via))
    for name, (lo, hi) in free.items():
        key = f"optimizer.free.{key_path([name])}"
        if name not in names:
            raise ProblemError(
                source,
                key,
                f"not a value of this problem{_suggestion(name, names)} "
                f"(names: {', '.join(names)})",
            )
        if lo is not None and hi is not None and lo > hi:
            raise ProblemError(source, key, f"lower bound {lo:g} exceeds upper bound {hi:g}")
        guess = _file_value(spec, name)
        if (lo is not None and guess < lo) or (hi is not None and guess > hi):
            raise ProblemError(
                source,
                key,
                f"the initial guess motion.{name} = {guess:g} lies outside the bounds "
                f"{_interval(lo, hi)}; "
                "the file's value is where the optimizer starts",
            )


def _check_switches(spec: ProblemSpec, source: str) -> None:
    """``optimizer.gamma_switches`` only where the flat optimizer's B-spline or polynomial
    curves can take the switches (a path_timing path is drawn through the file's nodes)."""
    o = spec.optimizer
    if o.gamma_switches == 0:
        return
    if spec.planner != "optimize":
        raise ProblemError(
            source,
            "optimizer.gamma_switches",
            f"switches of the sign of gamma are added by planner: optimize, not {spec.planner}",
        )
    if o.curve == "path_timing":
        raise ProblemError(
            source,
            "optimizer.gamma_switches",
            "curve: path_timing draws one path per phase of the file, so the optimizer cannot "
            "add a switch inside one; place the switch by hand (a via state with xi_after) or "
            "use curve: bspline",
        )


def _check_optimizer(spec: ProblemSpec, phases: int, source: str) -> None:
    o = spec.optimizer
    ends = 5 if o.smooth_torque else 4
    why = f"{ends} boundary conditions at each end{' (smooth_torque)' if o.smooth_torque else ''}"
    if o.curve == "path_timing":  # the path block has its own checks (_check_paths)
        pass
    elif o.curve == "bspline" and o.coefficients < o.degree + 1:
        # blame the value the file changed: a high degree, unless only coefficients was set
        only_coefficients = {"coefficients"} <= o.model_fields_set and "degree" not in (
            o.model_fields_set
        )
        raise ProblemError(
            source,
            "optimizer.coefficients" if only_coefficients else "optimizer.degree",
            f"a B-spline of degree {o.degree} needs at least {o.degree + 1} coefficients per "
            f"phase, and optimizer.coefficients is {o.coefficients}: lower the degree or raise "
            "the coefficients",
        )
    count = o.coefficients if o.curve == "bspline" else o.degree + 1
    if o.curve != "path_timing" and count < 2 * ends:
        key = "optimizer.coefficients" if o.curve == "bspline" else "optimizer.degree"
        raise ProblemError(
            source,
            key,
            f"{count} coefficients per phase cannot hold {why} (need >= {2 * ends})",
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


def _check_paths(spec: ProblemSpec, arm: Arm, nodes, free: dict, source: str) -> None:
    """``optimizer.path``: one per phase with ``curve: path_timing`` (and only then), shapes
    that make the CP smooth enough, ends at the nodes' CPs, and paths that can meet the nodes'
    CP derivatives wherever these are fixed."""
    o = spec.optimizer
    if o.path is None:
        if o.curve == "path_timing":
            raise ProblemError(
                source, "optimizer.path", "curve: path_timing needs a path per phase (degree, "
                "control_points, timing)",
            )  # fmt: skip
        return
    if o.curve != "path_timing":
        raise ProblemError(
            source, "optimizer.path", f"a path is used with curve: path_timing, not {o.curve}"
        )
    if len(o.path) != len(nodes) - 1:
        raise ProblemError(
            source,
            "optimizer.path",
            f"give one path per phase ({len(nodes) - 1}), got {len(o.path)}",
        )
    names = node_names(len(nodes))
    for k, path in enumerate(o.path):
        key = f"optimizer.path[{k}]"
        _check_path_shape(path, key, 5 if o.smooth_torque else 4, source)
        _check_point_bounds(path, key, source)
        points = _tied_points(arm, nodes, names, path, k, free, source)
        for i, at_end in ((k, False), (k + 1, True)):
            _check_path_end(arm, nodes[i], names[i], path, points, key, at_end, free, source)


def _check_point_bounds(path: PathSpec, key: str, source: str) -> None:
    """Each free control point: bounds in order, and its guess (x, y) within them."""
    for i, point in enumerate(path.control_points):
        if not isinstance(point, FreePointSpec):
            continue
        where = f"{key}.control_points[{i}]"
        for axis, guess, (lo, hi) in zip("xy", (point.x, point.y), point.bounds, strict=True):
            if lo is not None and hi is not None and lo > hi:
                raise ProblemError(
                    source,
                    f"{where}.bounds[{'xy'.index(axis)}]",
                    f"lower bound {lo:g} exceeds upper bound {hi:g} (bounds are [[x_lo, x_hi], "
                    "[y_lo, y_hi]] [m])",
                )
            if (lo is not None and guess < lo) or (hi is not None and guess > hi):
                raise ProblemError(
                    source,
                    f"{where}.{axis}",
                    f"the initial guess {axis} = {guess:g} m lies outside the bounds "
                    f"{_interval(lo, hi)}",
                )


def _tied_points(arm: Arm, nodes, names, path: PathSpec, k: int, free, source) -> np.ndarray:
    """Phase k's control points (free ones at their guess) with the ends at the nodes' CPs,
    having checked the file's ends against the nodes whose position is fixed."""
    points = np.array([p if isinstance(p, list) else [p.x, p.y] for p in path.control_points])
    for i, end, at_end in ((k, 0, False), (k + 1, len(points) - 1, True)):
        cp = flat.output(nodes[i].state(after=not at_end), arm.K, arm.gravity)[:, 0]
        fixed = not {"x", "y", "theta_deg"} & freed_fields(names[i], free, nodes[i], not at_end)
        if fixed and np.hypot(*(points[end] - cp)) > 1e-4:
            raise ProblemError(
                source, f"optimizer.path[{k}].control_points[{end}]", f"the path's ends are "
                f"the nodes' CPs: {names[i]}'s CP is at ({cp[0]:.7g}, {cp[1]:.7g}) m, got "
                f"[{points[end][0]:g}, {points[end][1]:g}]",
            )  # fmt: skip
        points[end] = cp
    return points


def _check_path_shape(path: PathSpec, key: str, ends: int, source: str) -> None:
    n, d = len(path.control_points), path.degree
    if n < d + 1:
        raise ProblemError(
            source, f"{key}.control_points", f"a degree-{d} path needs at least {d + 1} control "
            f"points, got {n}",
        )  # fmt: skip
    if n > d + 1 and d < 4:
        raise ProblemError(
            source, f"{key}.degree", f"a B-spline path (more than degree + 1 control points) must "
            "be three times differentiable where the CP crosses its knots (the arm's state "
            f"depends on the CP's jerk): degree >= 4, got {d}; or give {d + 1} control points "
            "(a Bezier curve)",
        )  # fmt: skip
    need = max(2 * ends, path.timing.degree + 1)
    if path.timing.coefficients < need:
        raise ProblemError(
            source, f"{key}.timing.coefficients", f"{path.timing.coefficients} coefficients "
            f"cannot hold {ends} conditions at each end of a degree-{path.timing.degree} timing "
            f"law (need >= {need})",
        )  # fmt: skip
    for i in (0, n - 1):
        if not isinstance(path.control_points[i], list):
            raise ProblemError(
                source, f"{key}.control_points[{i}]", "the path's ends are tied to the nodes' "
                "CPs: write them as [x, y] (free the node's x, y or theta_deg to move them)",
            )  # fmt: skip


def _check_path_end(
    arm: Arm, node: Node, name: str, path: PathSpec, points: np.ndarray, key: str,
    at_end: bool, free: dict, source: str,
) -> None:  # fmt: skip
    """Can the path meet the node's CP derivatives of the orders whose values are fixed (and
    whose control points are fixed)? ``points`` holds the control points (free ones at their
    guess), the ends at the nodes' CPs."""
    n = len(points)
    P = flat.output(node.state(after=not at_end), arm.K, arm.gravity)
    freed = freed_fields(name, free, node, after=not at_end)
    fields = order_fields(arm.K, arm.gravity)
    fixed = 0  # highest order whose node values and control points are all fixed
    order = [n - 1 - j for j in range(n)] if at_end else list(range(n))
    for r in range(4):
        if fields[r] & freed or (r < n and not isinstance(path.control_points[order[r]], list)):
            break
        fixed = r
    shape = PathShape(path.degree, n)
    Y = (shape.end_matrix(at_end) @ np.asarray(points, float)).T
    problem = node_mismatch(Y, P, fixed, at_end) if fixed else None
    if problem:
        raise ProblemError(source, f"{key}.control_points[{order[1]}]", f"{name}: {problem}")


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


def plant_links(spec: ProblemSpec) -> list[Link]:
    """The plant's links: each key of ``tracking.plant.links[i]`` overrides the arm's value;
    a key given nowhere takes the usual default (uniform rod), so a link given only a new
    mass stays a uniform rod."""
    overrides = (spec.tracking.plant.links if spec.tracking else None) or [None] * 3
    links = []
    for model, new in zip(spec.arm.links, overrides, strict=True):
        values = model.model_dump()
        if new is not None:
            values.update({k: v for k, v in new.model_dump().items() if v is not None})
        links.append(Link(values["length"], values["mass"], values["com"], values["inertia"]))
    return links


def check_tracking(spec: ProblemSpec, source: str) -> None:
    """The ``tracking`` block's physics: a valid plant third link, a controller for the plan."""
    com3 = plant_links(spec)[2].d
    if not com3 > 0:
        raise ProblemError(
            source,
            "tracking.plant.links[2].com",
            "the plant's third link needs its centre of mass beyond its joint (> 0 m), "
            f"got {com3!r}",
        )
    if (
        spec.tracking.controller == "dfl"
        and spec.planner == "collocation"
        and not spec.collocation.gamma_constraint
    ):
        raise ProblemError(
            source,
            "tracking.controller",
            "dfl needs gamma away from zero along the plan, which a collocation plan without "
            "collocation.gamma_constraint does not guarantee; use tvlqr or set "
            "collocation.gamma_constraint: true",
        )


@dataclass(frozen=True)
class GammaSide:
    """gamma on one side of a node: on arrival, or on departure after a xi reset.

    Attributes
    ----------
    gamma : float
        Its value at the file's values [m/s^2].
    fixed : bool
        True when no freed value moves it.
    path : str
        The key path of the xi that sets it (``motion.via[0].xi_after``).
    index : int
        The node's index in the motion.
    after : bool
        True on departure from a via state that resets xi.
    """

    gamma: float
    fixed: bool
    path: str
    index: int = 0
    after: bool = False


def gamma_sides(arm: Arm, nodes, paths, free) -> tuple[list[GammaSide], list[GammaSide]]:
    """gamma on arrival at each node and on departure (after a via state's xi reset; the same
    object as on arrival where xi is not reset)."""
    arrive, leave = [], []
    for i, (node, path) in enumerate(zip(nodes, paths, strict=True)):
        name = path.removeprefix("motion.")
        gam = float(flat.gamma(node.state(), arm.K, arm.gravity))
        arrive.append(GammaSide(gam, not gamma_is_free(name, free), f"{path}.xi", i))
        if 0 < i < len(nodes) - 1 and has_reset(node, name, "xi", free):
            after = float(flat.gamma(node.state(after=True), arm.K, arm.gravity))
            fixed = not gamma_is_free(name, free, "xi_after")
            leave.append(GammaSide(after, fixed, f"{path}.xi_after", i, True))
        else:
            leave.append(arrive[-1])
    return arrive, leave


def gamma_segments(arrive: list[GammaSide], leave: list[GammaSide]) -> list[list[GammaSide]]:
    """The fixed sides of gamma in order, split where xi is reset: within one segment gamma is
    continuous, so it keeps one sign unless the optimizer adds switches."""
    segments = [[arrive[0]]]
    for i in range(1, len(arrive)):
        segments[-1].append(arrive[i])
        if leave[i] is not arrive[i]:
            segments.append([leave[i]])
    return [[s for s in seg if s.fixed] for seg in segments]


def _check_gamma(spec, arm, nodes, paths, free, source) -> tuple[list, list]:
    """gamma != 0 where it is fixed, and one sign between xi resets unless the optimizer may
    add switches (as many as the sign changes); returns the sides of :func:`gamma_sides`."""
    switches = 0 if spec.planner == "closed_form" else spec.optimizer.gamma_switches
    arrive, leave = gamma_sides(arm, nodes, paths, free)
    for side in (*arrive, *leave):
        if side.fixed and abs(side.gamma) < GAMMA_ZERO:
            raise ProblemError(
                source,
                side.path,
                f"gamma = xi - K thetadot^2 + g0 sin(theta) = {side.gamma:.3g} m/s^2 at "
                "this node: the flat map is singular there; choose xi so that gamma != 0",
            )
    needed = 0
    for segment in gamma_segments(arrive, leave):
        changes = sum(a.gamma * b.gamma < 0 for a, b in itertools.pairwise(segment))
        if changes and switches == 0:
            _refuse_sign_change(spec, arm, nodes, segment, source)
        needed += changes
    if switches != "auto" and needed > switches:
        raise ProblemError(
            source,
            "optimizer.gamma_switches",
            f"the fixed values of gamma change sign {needed} times where xi is not reset and "
            f"need a switch each, got {switches}",
        )
    return arrive, leave


def _refuse_sign_change(spec, arm: Arm, nodes, segment: list[GammaSide], source: str) -> None:
    """Refuse fixed values of gamma of both signs between two xi resets, blaming the odd
    side (or ``arm.gravity``) and saying which xi gives it the others' sign."""
    values = ", ".join(
        f"{s.gamma:+.3g} {'after' if s.after else 'at'} {s.path.rsplit('.', 1)[0]}" for s in segment
    )
    where = "over the motion" if len(segment) == len(nodes) else "between xi resets"
    intro = (
        f"gamma = xi - K thetadot^2 + g0 sin(theta) changes sign {where} ({values} "
        "m/s^2), so it vanishes in between; it keeps one sign where xi is not reset (it is "
        "continuous at via states)"
    )
    hint = "; or reset xi at a via state (xi_after), or let the optimizer add switches "
    hint += "(optimizer.gamma_switches)"
    if _gravity_at_fault(spec, arm, nodes, segment):
        raise ProblemError(
            source,
            "arm.gravity",
            f"{intro}. With the standard {G0} m/s^2 the signs agree: the node values look chosen "
            f"for it; choose xi for gravity {arm.gravity:g} m/s^2 or change arm.gravity{hint}",
        )
    odd = _odd_one_out(nodes, segment)
    sign = -1.0 if odd.gamma > 0 else 1.0
    margin = max(spec.optimizer.gamma_min, 1.0)
    xi = nodes[odd.index].state(odd.after)[6] - odd.gamma + sign * margin
    raise ProblemError(
        source,
        odd.path,
        f"{intro}. Here it has the sign of the fewer nodes: {odd.path.rsplit('.', 1)[1]} "
        f"{'>=' if sign > 0 else '<='} "
        f"{xi:.4g} m/s^2 gives it the others' sign with |gamma| >= {margin:g}{hint}",
    )


def _gravity_at_fault(spec, arm: Arm, nodes, segment: list[GammaSide]) -> bool:
    """True when the file changed gravity and the standard one gives every fixed side one sign."""
    if "gravity" not in spec.arm.model_fields_set or arm.gravity == G0:
        return False
    gam = [float(flat.gamma(nodes[s.index].state(s.after), arm.K, G0)) for s in segment]
    return min(abs(g) for g in gam) >= GAMMA_ZERO and len({g > 0 for g in gam}) == 1


def _odd_one_out(nodes, segment: list[GammaSide]) -> GammaSide:
    """The side to blame for a sign change: the first of the smaller group of signs.

    On a tie, the group whose xi the file set away from 0 (chosen by hand; xi = 0 at a rest
    state is a physical fact), else the group holding the later node.
    """
    pos = [s for s in segment if s.gamma > 0]
    neg = [s for s in segment if s.gamma < 0]
    if len(pos) != len(neg):
        return min(pos, neg, key=len)[0]
    pos_set, neg_set = (any(nodes[s.index].state(s.after)[6] != 0 for s in g) for g in (pos, neg))
    if pos_set != neg_set:
        return (pos if pos_set else neg)[0]
    return (pos if segment.index(pos[-1]) > segment.index(neg[-1]) else neg)[0]


def _check_signs(o: OptimizerSpec, sides: tuple[list, list], source: str) -> None:
    """``gamma_sign`` (the sign at each phase's start) against the fixed values of gamma, and,
    without switches, against the phase's end and the via states that do not reset xi."""
    if o.gamma_sign is None:
        return
    arrive, leave = sides
    wanted = [{"positive": 1, "negative": -1}.get(s, 0) for s in o.gamma_sign]
    for k, sign in enumerate(wanted):
        ends = [leave[k]] if o.gamma_switches else [leave[k], arrive[k + 1]]
        for side in ends:
            if sign and side.fixed and sign * side.gamma < 0:
                raise ProblemError(
                    source,
                    f"optimizer.gamma_sign[{k}]",
                    f"phase {k + 1} is asked to keep gamma {o.gamma_sign[k]}, but "
                    f"{side.path} fixes gamma = {side.gamma:.3g} m/s^2 at its "
                    f"{'start' if side is leave[k] else 'end'}",
                )
        joined = k and leave[k] is arrive[k]  # no xi reset between phases k and k + 1
        if sign and joined and not o.gamma_switches and wanted[k - 1] == -sign:
            raise ProblemError(
                source,
                f"optimizer.gamma_sign[{k}]",
                f"phases {k} and {k + 1} meet at {arrive[k].path.rsplit('.', 1)[0]} where xi "
                "is not reset, so gamma keeps its sign there; give the same sign, a xi reset "
                "(xi_after) or optimizer.gamma_switches",
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
        name=spec.name or safe_name(name or "problem"),
        source=source,
        arm=arm,
        nodes=nodes,
        spec=spec,
        free=si_bounds(spec.optimizer.free),
        limits=arm_limits(spec.optimizer.limits, arm),
    )


def load_problem(path: str | Path) -> Problem:
    """Read and validate a YAML problem file (see :mod:`cpopt.safe_yaml` for the limits).

    Raises
    ------
    ProblemError
        For a missing, unreadable, empty, oversized or malformed file, or invalid content.
    """
    source = str(path)
    try:
        data = read_yaml(path)
    except YamlInputError as err:
        raise ProblemError(source, err.path, err.message) from None
    return parse_problem(data, source, name=safe_name(Path(path).stem))


def bundled_problems() -> list[Path]:
    """The problem files shipped with cpopt.

    They are package data, ``cpopt/problems/`` in an installed wheel; in a checkout that is a
    link to ``problems/`` at the top (and ``problems/`` is used where links are not checked
    out as links).
    """
    package = Path(__file__).resolve().parent
    for root in (package / "problems", package.parent / "problems"):
        files = sorted(root.glob("*.yaml"))
        if files:
            return files
    return []


__all__ = [
    "ARM_KINDS",
    "MAX_SWITCHES",
    "GammaSide",
    "Problem",
    "ProblemError",
    "gamma_segments",
    "gamma_sides",
    "load_problem",
    "parse_problem",
]
