"""A cpopt arm as a MuJoCo model, built in code (``mujoco.MjSpec``), for the MuJoCo plant and
the MuJoCo pictures. MuJoCo is an optional extra (``pip install 'cpopt[mujoco]'``), imported
only here and only when asked for.

The frames are those of the URDF export (:mod:`cpopt.urdf.export`): cpopt's plane is the
world's x-z plane (y up becomes z), hinges turn about ``(0, -1, 0)`` (counter-clockwise in the
plane), and every MuJoCo joint coordinate equals cpopt's. Each body carries its link's mass,
centre of mass and inertia explicitly (geoms only draw: no mass, no contacts). The integrator
is RK4: Euler and implicitfast lose most of the energy of a free-swinging passive link.
"""

from __future__ import annotations

import math

import numpy as np

from .robot import Arm

HINGE = (0.0, -1.0, 0.0)
"""A hinge's axis in the world: the plane's normal, so that a positive angle turns x to z."""
MAX_TIMESTEP = 1e-3
"""Largest MuJoCo time step [s]: a control period is split into steps of at most this, and
into two at least (0.5 ms at 1 kHz, as the built-in plant's RK4 substeps)."""
MUJOCO_MISSING = "MuJoCo is not installed: pip install 'cpopt[mujoco]'"


class MujocoMissingError(ImportError):
    """MuJoCo was asked for and is not installed."""


def require_mujoco():
    """The ``mujoco`` module.

    Raises
    ------
    MujocoMissingError
        Saying how to install it.
    """
    try:
        import mujoco
    except ImportError:
        raise MujocoMissingError(MUJOCO_MISSING) from None
    return mujoco


def steps_per_period(period: float) -> int:
    """MuJoCo steps per control period [s]: at least two, each at most :data:`MAX_TIMESTEP`."""
    return max(2, math.ceil(period / MAX_TIMESTEP - 1e-9))


def _xyz(x: float, y: float) -> list[float]:
    return [x, 0.0, y]


def _frames(arm: Arm) -> dict:
    """Per link: its joint's type and axis, its body's position in the parent's frame, its
    centre of mass in its own frame, and the segment drawn (two points) — as in the export."""
    l1, l2, l3 = arm.links
    kind = arm.kind
    slide_x, slide_z = ("slide", (1.0, 0.0, 0.0)), ("slide", (0.0, 0.0, 1.0))
    hinge = ("hinge", HINGE)
    joint1 = hinge if kind[0] == "R" else slide_x
    joint2 = slide_z if kind == "PPR" else (hinge if kind[1] == "R" else slide_x)
    at2 = (l1.length, 0.0) if kind == "RRR" else (0.0, 0.0)
    at3 = (l2.length, 0.0) if kind in ("RRR", "PRR") else (0.0, 0.0)
    com1 = (l1.d, 0.0) if kind[0] == "R" else (l1.d - l1.length, 0.0)
    com2 = {"RRR": (l2.d, 0.0), "RPR": (l2.d - l2.length, 0.0), "PRR": (l2.d, 0.0),
            "PPR": (0.0, l2.d - l2.length)}[kind]  # fmt: skip
    seg1 = ((0.0, 0.0), (l1.length, 0.0)) if kind[0] == "R" else ((-l1.length, 0.0), (0.0, 0.0))
    seg2 = {"RRR": ((0.0, 0.0), (l2.length, 0.0)), "RPR": ((-l2.length, 0.0), (0.0, 0.0)),
            "PRR": ((0.0, 0.0), (l2.length, 0.0)),
            "PPR": ((0.0, -l2.length), (0.0, 0.0))}[kind]  # fmt: skip
    return {
        "joint": (joint1, joint2, hinge),
        "at": (arm.base, at2, at3),
        "com": (com1, com2, (l3.d, 0.0)),
        "segment": (seg1, seg2, ((0.0, 0.0), (l3.length, 0.0))),
    }


def add_arm(spec, arm: Arm, prefix: str = "", viscous=(0.0, 0.0, 0.0), rgba=None) -> None:
    """Add the arm's three bodies, joints and (massless, contact-free) link geoms to ``spec``;
    joint i is named ``{prefix}joint{i}`` and its body ``{prefix}link{i}``. ``viscous`` [N m s/rad
    or N s/m] becomes each joint's damping (inside the integrator's stages)."""
    mujoco = require_mujoco()
    frames = _frames(arm)
    parent = spec.worldbody
    for i in range(3):
        link = arm.links[i]
        body = parent.add_body(name=f"{prefix}link{i + 1}", pos=_xyz(*frames["at"][i]))
        body.mass, body.ipos = link.mass, _xyz(*frames["com"][i])
        body.inertia = [link.I, link.I, link.I]  # only the part about the normal moves the arm
        body.explicitinertial = True
        kind, axis = frames["joint"][i]
        body.add_joint(
            name=f"{prefix}joint{i + 1}",
            type=mujoco.mjtJoint.mjJNT_HINGE if kind == "hinge" else mujoco.mjtJoint.mjJNT_SLIDE,
            axis=list(axis),
            damping=float(viscous[i]),
        )
        a, b = frames["segment"][i]
        body.add_geom(
            type=mujoco.mjtGeom.mjGEOM_CAPSULE,
            fromto=[*_xyz(*a), *_xyz(*b)],
            size=[0.04 if i < 2 else 0.03, 0, 0],
            contype=0,
            conaffinity=0,
            mass=0.0,
            rgba=list(rgba or ((0.25, 0.45, 0.8, 1.0) if i < 2 else (0.85, 0.35, 0.2, 1.0))),
        )
        parent = body


def arm_model(arm: Arm, timestep: float = 5e-4, viscous=(0.0, 0.0, 0.0)):
    """The compiled ``mujoco.MjModel`` of :func:`arm_spec`.

    Raises
    ------
    MujocoMissingError
        Without MuJoCo.
    """
    return arm_spec(arm, timestep, viscous).compile()


def arm_spec(arm: Arm, timestep: float = 5e-4, viscous=(0.0, 0.0, 0.0), ghost: Arm | None = None):
    """The ``mujoco.MjSpec`` of an arm: motors on joints 1 and 2 (unlimited; the caller
    saturates), gravity along -z, no contacts, RK4 at ``timestep`` [s], joint damping
    ``viscous``; with ``ghost``, a second, translucent arm (prefix ``ghost_``) for pictures of a
    plan beside a tracked arm.

    Raises
    ------
    MujocoMissingError
        Without MuJoCo.
    """
    mujoco = require_mujoco()
    spec = mujoco.MjSpec()
    spec.modelname = "cpopt_arm"
    spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
    spec.option.timestep = timestep
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_RK4
    spec.option.gravity = [0.0, 0.0, -arm.gravity]
    spec.option.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    add_arm(spec, arm, viscous=viscous)
    for i in (1, 2):
        spec.add_actuator(
            name=f"motor{i}",
            target=f"joint{i}",
            trntype=mujoco.mjtTrn.mjTRN_JOINT,
            gear=[1.0, 0, 0, 0, 0, 0],
        )
    if ghost is not None:
        add_arm(spec, ghost, prefix="ghost_", rgba=(0.55, 0.55, 0.55, 0.35))
    return spec


def arm_state(model, data, q, qd=None) -> None:
    """Set the arm's joint positions (3,) [rad or m] and velocities in ``data``."""
    data.qpos[:3] = q
    data.qvel[:3] = 0.0 if qd is None else qd


def mass_matrix(model, data) -> np.ndarray:
    """The dense joint-space inertia matrix of the arm's three joints (``mj_fullM``)."""
    mujoco = require_mujoco()
    M = np.zeros((model.nv, model.nv))
    try:
        mujoco.mj_fullM(model, data, M)  # MuJoCo 4
    except TypeError:
        mujoco.mj_fullM(model, M, data.qM)  # MuJoCo 3
    return M[:3, :3]
