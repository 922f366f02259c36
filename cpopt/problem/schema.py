"""The problem file's schema: the pydantic models of the YAML format, and :class:`ProblemError`.

The format is documented in ``docs/problems.md``. Units are SI; angles are degrees in files
(``theta_deg``, ``thetadot_deg`` in deg/s). The models check types, required keys and simple
bounds; the checks across keys (physics, key paths) are in :mod:`cpopt.problem.validate`.
"""

from __future__ import annotations

import re
from typing import Annotated, Literal

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
from pydantic_core import PydanticCustomError

from ..model.objectives import OBJECTIVES
from ..tracking.dfl import DEFAULT_POLES
from ..tracking.tvlqr import DEFAULT_Q, DEFAULT_QF

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


class UrdfArmSpec(_Spec):
    """An arm read from a URDF file: its path (relative to the problem file), the three moving
    joints base to tip (None: the chain's own), gravity [m/s^2] and IK branch."""

    urdf: Annotated[str, Field(min_length=1)]
    joints: Triple(Annotated[str, Field(min_length=1)]) | None = None
    gravity: Positive = 9.81
    branch: str | None = None


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

    ``torque`` [N m or N] for joints 1, 2; ``torque_headroom`` the fraction h of each torque
    limit the plan leaves to feedback (one value for every limited joint, or a pair; the plan
    keeps |tau_i| <= (1 - h_i) torque_i); ``joint_position`` pairs [deg or m] and
    ``joint_velocity`` [deg/s or m/s] for joints 1..3.
    """

    torque: Pair(Positive | None) = [None, None]
    torque_headroom: Number | Pair(Number) = 0.0
    joint_position: Triple(Pair(Number) | None) | None = None
    joint_velocity: Triple(Positive | None) | None = None

    @field_validator("torque_headroom", mode="wrap")
    @classmethod
    def _one_or_two_numbers(cls, value, handler):
        # one message for the union, not one per member named by its type
        try:
            return handler(value)
        except ValidationError:
            raise PydanticCustomError(
                "headroom", "expected a number h or a pair [h1, h2] (fractions 0 <= h < 1)"
            ) from None


DEFAULT_MAX_TIME = 300.0
"""Default wall-clock limit of one problem [s]: planning and verification together."""


class SolverSpec(_Spec):
    """Ipopt settings and the problem's wall-clock limit ``max_time`` [s]; ``hessian`` None
    means the objective's default (:func:`cpopt.model.objectives.default_hessian`),
    ``mu_strategy`` None cpopt's choice: ``adaptive``, but ``monotone`` for a flat solve
    started from a seed trajectory (:func:`cpopt.flatopt.ipopt_settings.warm_options`)."""

    max_iter: Annotated[int, WHOLE, Field(gt=0)] = 1000
    tol: Positive = 1e-8
    print_level: Annotated[int, WHOLE, Field(ge=0, le=12)] = 0
    mu_strategy: Literal["adaptive", "monotone"] | None = None
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
MAX_COEFFICIENTS = 60
"""Most B-spline coefficients per phase and coordinate (``optimizer.coefficients``)."""


class OptimizerSpec(_Spec):
    """Optimizer settings (see docs/problems.md)."""

    curve: Literal["bspline", "polynomial", "path_timing"] = "bspline"
    degree: Annotated[int, WHOLE, Field(ge=7, le=15)] = 8
    coefficients: Annotated[int, WHOLE, Field(ge=8, le=MAX_COEFFICIENTS)] = 14
    objective: (
        Literal[OBJECTIVES] | dict[str, Annotated[float, Field(ge=0, allow_inf_nan=False)]]
    ) = "torque"
    gamma_min: Number = 2.0
    gamma_sign: list[Literal["auto", "positive", "negative"]] | None = None
    gamma_switches: Literal["auto"] | Annotated[int, WHOLE, Field(ge=0, le=MAX_SWITCHES)] = 0
    switch_search: Literal["seed", "greedy"] = "seed"
    refine_basis: bool | Literal["auto"] = "auto"
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
    """The simulated arm: link overrides, friction, torque limits [N m or N], actuator gains,
    actuation delay [s], torque noise [N m or N], and the engine that integrates it
    (``cpopt``, the built-in plant, or ``mujoco``)."""

    engine: Literal["cpopt", "mujoco"] = "cpopt"
    links: Triple(PlantLinkSpec | None) | None = None
    friction: FrictionSpec = FrictionSpec()
    torque_limit: Pair(Positive | None) | None = None
    gain: Pair(Annotated[float, Field(gt=0, le=10, allow_inf_nan=False)]) = [1.0, 1.0]
    delay: Annotated[float, Field(ge=0, le=1, allow_inf_nan=False)] = 0.0
    torque_noise: Pair(NonNegative) = [0.0, 0.0]


class NoiseSpec(_Spec):
    """Standard deviations of the measured joint positions [rad or m] and velocities, seed."""

    position: Triple(NonNegative) = [0.0, 0.0, 0.0]
    velocity: Triple(NonNegative) = [0.0, 0.0, 0.0]
    seed: Annotated[int, Field(ge=0)] = 0


class TrackingSpec(_Spec):
    """Tracking of the plan by a controller on a realistic plant (see docs/problems.md)."""

    controller: Literal["tvlqr", "tvlqr_timescaled", "dfl", "flat_mpc"] = "tvlqr"
    rate_hz: Annotated[float, Field(gt=0, le=100000, allow_inf_nan=False)] = 1000.0
    replan_period: Annotated[float, Field(gt=0, le=10, allow_inf_nan=False)] = 0.02
    replan_delay: Annotated[float, Field(gt=0, le=10, allow_inf_nan=False)] | None = None
    replan_deadline: Annotated[float, Field(gt=0, le=10, allow_inf_nan=False)] | None = None
    replan_method: Literal["ipopt", "sqp"] = "ipopt"
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
