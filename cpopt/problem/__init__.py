"""Problem files: the YAML schema, its validation and the :class:`Problem` it yields.

This is the only package that knows the file format (documented in ``docs/problems.md``).
Units are SI; angles are degrees in files (``theta_deg``, ``thetadot_deg`` in deg/s) and
radians everywhere in code.

Modules: :mod:`~cpopt.problem.schema` (the pydantic models), :mod:`~cpopt.problem.validate`
(the checks across keys, with :mod:`~cpopt.problem.gamma` and
:mod:`~cpopt.problem.path_checks`), :mod:`~cpopt.problem.messages` (validation errors as key
paths), :mod:`~cpopt.problem.build` (:class:`Problem` from data or a file) and
:mod:`~cpopt.problem.holding` (which rest ends a plan holds at the holding torque, read by both
planners).
"""

from ..model.robot import ARM_KINDS
from .build import Problem, bundled_problems, load_problem, parse_problem, read_problem
from .gamma import GammaSide, gamma_segments, gamma_sides
from .messages import REMOVED_KEYS
from .schema import (
    DEFAULT_MAX_TIME,
    MAX_COEFFICIENTS,
    MAX_SWITCHES,
    NAME,
    UNION_TAGS,
    ArmSpec,
    ClosedFormSpec,
    CollocationSpec,
    ControlPoint,
    FreePointSpec,
    FrictionSpec,
    LimitsSpec,
    LinkSpec,
    MotionSpec,
    NoiseSpec,
    OptimizerSpec,
    PathSpec,
    PlantLinkSpec,
    PlantSpec,
    ProblemError,
    ProblemSpec,
    SolverSpec,
    StateSpec,
    TimingSpec,
    TrackingSpec,
    UrdfArmSpec,
    VerificationSpec,
    ViaSpec,
    safe_name,
)
from .validate import PHYSICAL_RANGES, check_tracking, plant_links

__all__ = [
    "ARM_KINDS",
    "DEFAULT_MAX_TIME",
    "MAX_COEFFICIENTS",
    "MAX_SWITCHES",
    "NAME",
    "PHYSICAL_RANGES",
    "REMOVED_KEYS",
    "UNION_TAGS",
    "ArmSpec",
    "ClosedFormSpec",
    "CollocationSpec",
    "ControlPoint",
    "FreePointSpec",
    "FrictionSpec",
    "GammaSide",
    "LimitsSpec",
    "LinkSpec",
    "MotionSpec",
    "NoiseSpec",
    "OptimizerSpec",
    "PathSpec",
    "PlantLinkSpec",
    "PlantSpec",
    "Problem",
    "ProblemError",
    "ProblemSpec",
    "SolverSpec",
    "StateSpec",
    "TimingSpec",
    "TrackingSpec",
    "UrdfArmSpec",
    "VerificationSpec",
    "ViaSpec",
    "bundled_problems",
    "check_tracking",
    "gamma_segments",
    "gamma_sides",
    "load_problem",
    "parse_problem",
    "plant_links",
    "read_problem",
    "safe_name",
]
