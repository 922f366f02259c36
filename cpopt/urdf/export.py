"""A cpopt arm written as URDF, in the frames :mod:`cpopt.urdf.arm` reads back exactly.

cpopt's plane (x, y up) is the world's x-z plane: revolute axes are ``0 -1 0`` (counter-
clockwise in the plane), a point (x, y) is at ``x 0 y``, and every URDF joint coordinate equals
cpopt's (same zero, same sign). The two actuated joints get a ``<transmission>`` and their
torque limits as effort (an unlimited revolute joint is ``continuous`` with no limit; an
unlimited prismatic one, whose ``<limit>`` needs an effort, gets :data:`UNLIMITED`); the
passive third joint is ``continuous`` without a transmission. Each link's length is the length
of a ``<visual>`` cylinder along it.
"""

from __future__ import annotations

from xml.sax.saxutils import quoteattr

from ..model.robot import Arm
from .model import UNLIMITED

NORMAL = "0 -1 0"
"""The axis of a revolute joint: the plane's normal, so that a positive angle turns x to y."""


def _xyz(x: float, y: float) -> str:
    """World coordinates of a plane point: cpopt's y is up (+z)."""
    return f"{x!r} 0 {y!r}"


def _link(name: str, mass: float, com: tuple[float, float], inertia: float, length: float,
          middle: tuple[float, float]) -> str:  # fmt: skip
    """A ``<link>`` with an isotropic inertia tensor (only its part about y moves the arm) and
    a visual cylinder of the link's length centred at ``middle``, along x or, for a middle on
    the z axis, along z."""
    rpy = "0 0 0" if middle[0] == 0 and middle[1] != 0 else "0 1.5707963267948966 0"
    half = _xyz(*middle)
    return (
        f'  <link name="{name}">\n'
        f"    <inertial>\n"
        f'      <origin xyz="{_xyz(*com)}" rpy="0 0 0"/>\n'
        f'      <mass value="{mass!r}"/>\n'
        f'      <inertia ixx="{inertia!r}" ixy="0" ixz="0" iyy="{inertia!r}" iyz="0" '
        f'izz="{inertia!r}"/>\n'
        f"    </inertial>\n"
        f"    <visual>\n"
        f'      <origin xyz="{half}" rpy="{rpy}"/>\n'
        f'      <geometry><cylinder radius="0.02" length="{length!r}"/></geometry>\n'
        f"    </visual>\n"
        f"  </link>\n"
    )


def _joint(name: str, kind: str, parent: str, child: str, at: tuple[float, float], axis: str,
           effort: float | None) -> str:  # fmt: skip
    if kind == "revolute" and effort is None:
        kind = "continuous"
    if kind == "prismatic" and effort is None:
        effort = UNLIMITED
    bounds = f'velocity="{UNLIMITED!r}" lower="-1e3" upper="1e3"'
    limit = "" if effort is None else f'    <limit effort="{effort!r}" {bounds}/>\n'
    return (
        f'  <joint name="{name}" type="{kind}">\n'
        f'    <parent link="{parent}"/>\n'
        f'    <child link="{child}"/>\n'
        f'    <origin xyz="{_xyz(*at)}" rpy="0 0 0"/>\n'
        f'    <axis xyz="{axis}"/>\n'
        f"{limit}"
        f"  </joint>\n"
    )


def _transmission(joint: str) -> str:
    return (
        f'  <transmission name="{joint}_transmission">\n'
        f"    <type>transmission_interface/SimpleTransmission</type>\n"
        f'    <joint name="{joint}">'
        f"<hardwareInterface>hardware_interface/EffortJointInterface</hardwareInterface>"
        f"</joint>\n"
        f'    <actuator name="{joint}_motor"><mechanicalReduction>1</mechanicalReduction>'
        f"</actuator>\n"
        f"  </transmission>\n"
    )


JOINTS = ("joint1", "joint2", "joint3")
"""The joint names export writes (``arm: {urdf: ..., joints: [joint1, joint2, joint3]}``)."""


def arm_urdf(arm: Arm, torque: tuple[float | None, float | None] = (None, None),
             name: str = "cpopt_arm") -> str:  # fmt: skip
    """The arm as a URDF document.

    Parameters
    ----------
    arm : Arm
        The arm; its gravity and branch are the problem file's, not the URDF's.
    torque : pair of float or None
        Torque or force limits of joints 1 and 2 [N m or N], written as effort limits.
    name : str
        The robot's name.

    Returns
    -------
    str
        The URDF text; its joints are :data:`JOINTS`.
    """
    l1, l2, l3 = arm.links
    bx, by = arm.base
    slide = {"R": ("revolute", "0 -1 0"), "P": ("prismatic", "1 0 0")}
    k1, k2 = arm.kind[0], arm.kind[1]
    t1, a1 = slide[k1]
    t2, a2 = ("prismatic", "0 0 1") if arm.kind == "PPR" else slide[k2]
    # where each link's frame sits relative to its parent's (cpopt's kinematics.link_geometry)
    at2, at3 = {
        "RRR": ((l1.length, 0.0), (l2.length, 0.0)),
        "RPR": ((0.0, 0.0), (0.0, 0.0)),
        "PRR": ((0.0, 0.0), (l2.length, 0.0)),
        "PPR": ((0.0, 0.0), (0.0, 0.0)),
    }[arm.kind]
    com1 = (l1.d, 0.0) if k1 == "R" else (l1.d - l1.length, 0.0)
    com2 = {"RRR": (l2.d, 0.0), "RPR": (l2.d - l2.length, 0.0), "PRR": (l2.d, 0.0),
            "PPR": (0.0, l2.d - l2.length)}[arm.kind]  # fmt: skip
    mid1 = (com1[0] - l1.d + l1.length / 2, 0.0)
    mid2 = (com2[0] - l2.d + l2.length / 2, 0.0) if arm.kind != "PPR" else (0.0, -l2.length / 2)
    parts = [
        f'<?xml version="1.0"?>\n<robot name={quoteattr(name)}>\n',
        '  <link name="world"/>\n',
        _joint("joint1", t1, "world", "link1", (bx, by), a1, torque[0]),
        _link("link1", l1.mass, com1, l1.I, l1.length, mid1),
        _joint("joint2", t2, "link1", "link2", at2, a2, torque[1]),
        _link("link2", l2.mass, com2, l2.I, l2.length, mid2),
        _joint("joint3", "continuous", "link2", "link3", at3, NORMAL, None),
        _link("link3", l3.mass, (l3.d, 0.0), l3.I, l3.length, (l3.length / 2, 0.0)),
        _transmission("joint1"),
        _transmission("joint2"),
        "</robot>\n",
    ]
    return "".join(parts)
