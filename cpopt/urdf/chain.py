"""The serial chain of a URDF: its three moving joints in order, the rigid bodies they move,
and which of them a motor drives.

Every refusal names the joint or link at fault and what was expected (:class:`UrdfError`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .model import UNLIMITED, Urdf, UrdfError, UrdfJoint

MOVING = ("revolute", "continuous", "prismatic")
"""The joint types of a cpopt arm's three joints; ``fixed`` joints may join links between them."""


@dataclass(frozen=True)
class Chain:
    """A URDF's serial chain: its root link, the three moving joints base to tip, and each
    joint's body (the links it moves that the next moving joint does not)."""

    root: str
    joints: tuple[UrdfJoint, UrdfJoint, UrdfJoint]
    bodies: tuple[tuple[str, ...], tuple[str, ...], tuple[str, ...]]


def _root(urdf: Urdf) -> str:
    children = {j.child for j in urdf.joints.values()}
    roots = [name for name in urdf.links if name not in children]
    if len(roots) != 1:
        raise UrdfError(
            f"{urdf.source}: expected one root link (a link that is no joint's child), got "
            f"{len(roots)}: {', '.join(repr(r) for r in roots) or 'none (a loop)'}"
        )
    return roots[0]


def _check_joint_types(urdf: Urdf, names: list[str]) -> None:
    for name in names:
        if name not in urdf.joints:
            known = ", ".join(repr(j) for j in urdf.joints) or "none"
            raise UrdfError(f"{urdf.source}: no joint named '{name}' (joints: {known})")
        if urdf.joints[name].type not in MOVING:
            raise UrdfError(
                f"{urdf.source}: joint '{name}' is {urdf.joints[name].type}; expected one of "
                f"{', '.join(MOVING)}"
            )
    for joint in urdf.joints.values():
        if joint.type not in (*MOVING, "fixed"):
            raise UrdfError(
                f"{urdf.source}: joint '{joint.name}' is {joint.type or 'untyped'}; a planar arm "
                f"has {', '.join(MOVING)} or fixed joints"
            )
        if joint.mimic:
            raise UrdfError(
                f"{urdf.source}: joint '{joint.name}' mimics another joint; cpopt's three joints "
                "move independently (remove the <mimic>)"
            )
        if joint.type != "fixed" and joint.name not in names:
            raise UrdfError(
                f"{urdf.source}: joint '{joint.name}' is a fourth moving joint; the arm's moving "
                f"joints must be exactly {names} (make the others fixed)"
            )


def _walk(urdf: Urdf, root: str) -> list[UrdfJoint]:
    """The joints from the root to the tip, refusing a link with two child joints (a branch)."""
    order, link = [], root
    while True:
        below = [j for j in urdf.joints.values() if j.parent == link]
        if len(below) > 1:
            raise UrdfError(
                f"{urdf.source}: link '{link}' is a branch (joints "
                f"{', '.join(repr(j.name) for j in below)} below it); expected a serial chain"
            )
        if not below:
            return order
        order.append(below[0])
        link = below[0].child


def serial_chain(urdf: Urdf, names: list[str] | None = None) -> Chain:
    """The chain whose moving joints are ``names`` (base to tip; None: the chain's own three),
    with fixed joints between.

    Raises
    ------
    UrdfError
        For a joint that is not there, floating, planar or mimicking; a fourth moving joint; a
        branch; the joints in another order.
    """
    if names is None:
        _check_joint_types(urdf, [j.name for j in urdf.joints.values() if j.type != "fixed"])
    else:
        _check_joint_types(urdf, list(names))
    root = _root(urdf)
    order = _walk(urdf, root)
    moving = [j.name for j in order if j.type != "fixed"]
    if names is None and len(moving) != 3:
        raise UrdfError(
            f"{urdf.source}: the chain from '{root}' has {len(moving)} moving joint(s) "
            f"{moving}; expected three (two actuated, then the passive one)"
        )
    names = moving if names is None else list(names)
    if moving != names:
        raise UrdfError(
            f"{urdf.source}: the chain from '{root}' passes the moving joints {moving}; expected "
            f"{names} in this order, base to tip"
        )
    bodies, current = [], None
    for joint in order:
        if joint.type != "fixed":
            current = [joint.child]
            bodies.append(current)
        elif current is not None:
            current.append(joint.child)
    joints = tuple(urdf.joints[n] for n in names)
    return Chain(root, joints, tuple(tuple(b) for b in bodies))


def actuation(urdf: Urdf, chain: Chain) -> tuple[float, float]:
    """The effort limits [N m or N] of the two actuated joints (inf where none is written, or
    one of :data:`UNLIMITED` or more).

    A joint is actuated when a ``<transmission>`` drives it and its effort limit is > 0 (an
    absent limit counts as unlimited), as Drake's URDF parser reads it; the third joint must be
    the one passive joint.

    Raises
    ------
    UrdfError
        Naming a first or second joint that is passive, or a third that is actuated.
    """
    efforts = []
    for i, joint in enumerate(chain.joints):
        effort = np.inf if joint.effort is None else joint.effort
        actuated = joint.name in urdf.transmitted and effort > 0
        if i < 2 and not actuated:
            driven = joint.name in urdf.transmitted
            why = f"its effort limit is {effort:g}" if driven else "no <transmission> drives it"
            raise UrdfError(
                f"{urdf.source}: joint '{joint.name}' is passive ({why}); cpopt's first two "
                "joints are actuated (a <transmission> and an effort limit > 0) and its third "
                "is the passive one"
            )
        if i == 2 and actuated:
            raise UrdfError(
                f"{urdf.source}: joint '{joint.name}' is actuated (a <transmission> and an effort "
                f"limit {effort:g} > 0); cpopt's third joint is passive: remove its transmission "
                "or set its effort to 0"
            )
        efforts.append(np.inf if effort >= UNLIMITED else effort)
    return efforts[0], efforts[1]
