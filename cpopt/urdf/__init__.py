"""Arms from URDF files and back: :func:`read_urdf` and :func:`urdf_arm` read a planar serial
chain into cpopt's arm, :func:`arm_urdf` writes one (see ``docs/problems.md``, "Arms from
URDF")."""

from .arm import TOLERANCE, UrdfArm, urdf_arm
from .export import JOINTS, arm_urdf
from .model import UNLIMITED, Urdf, UrdfError, parse_urdf, read_urdf

__all__ = [
    "JOINTS",
    "TOLERANCE",
    "UNLIMITED",
    "Urdf",
    "UrdfArm",
    "UrdfError",
    "arm_urdf",
    "parse_urdf",
    "read_urdf",
    "urdf_arm",
]
