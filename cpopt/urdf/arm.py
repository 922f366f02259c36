"""A cpopt arm from a URDF: the plane of motion, the kind, and each link's length, mass, centre
of mass and inertia in cpopt's conventions (:mod:`cpopt.model.robot`).

The checks are made in the world frame at q = 0 (every ``origin rpy`` composed along the
chain), with URDF's gravity along -z. The plane's normal n is the third (passive) joint's axis;
cpopt's y axis points up (+z) and its x axis is ``z x n``, so that a positive angle turns
counter-clockwise about n. Revolute axes must be parallel or antiparallel to n (the sign is
kept), prismatic axes perpendicular to it; offsets along n do not matter.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .chain import Chain, actuation, serial_chain
from .model import Urdf, UrdfError, world_frames

TOLERANCE = 1e-5
"""Planarity and alignment tolerance [rad, or m for offsets]: CAD files write pi as 3.1416."""

UP = np.array([0.0, 0.0, 1.0])
"""Against URDF's gravity (-z)."""


@dataclass(frozen=True)
class Body:
    """A moving body in the plane at q = 0: mass [kg], centre of mass (x, y) [m], inertia about
    the normal through the centre of mass [kg m^2], the main link's name and its visual
    cylinder's length [m] (None without one)."""

    mass: float
    com: np.ndarray
    inertia: float
    link: str
    cylinder: float | None


@dataclass(frozen=True)
class UrdfArm:
    """The arm a URDF describes, in the keys of a problem file's ``arm`` (``kind``, ``base``,
    ``links``), the two actuated joints' effort limits [N m or N] (inf for none), and how
    cpopt's joint coordinates follow the URDF's: ``q_cpopt = sign * q_urdf + offset``."""

    kind: str
    base: tuple[float, float]
    links: tuple[dict, dict, dict]
    effort: tuple[float, float]
    sign: tuple[float, float, float]
    offset: tuple[float, float, float]

    def spec(self) -> dict:
        """The ``arm`` mapping of a problem file (without gravity and branch)."""
        return {"kind": self.kind, "base": list(self.base), "links": [dict(k) for k in self.links]}


@dataclass(frozen=True)
class Plane:
    """The plane of motion: unit normal n and cpopt's x and y axes, in the world frame."""

    normal: np.ndarray
    ex: np.ndarray
    ey: np.ndarray

    def point(self, p) -> np.ndarray:
        """Plane coordinates (x, y) [m] of a world point (its offset along n dropped)."""
        return np.array([p @ self.ex, p @ self.ey])


def _angle(v) -> float:
    return math.atan2(v[1], v[0])


def _cross(a, b) -> float:
    return float(a[0] * b[1] - a[1] * b[0])


def _plane(urdf: Urdf, chain: Chain, frames) -> Plane:
    third = chain.joints[2]
    if third.type == "prismatic":
        raise UrdfError(
            f"{urdf.source}: joint '{third.name}' is prismatic; cpopt's third (passive) joint is "
            "revolute or continuous"
        )
    n = frames[third.child][:3, :3] @ third.axis
    if abs(n @ UP) > TOLERANCE:
        raise UrdfError(
            f"{urdf.source}: joint '{third.name}' turns about {np.round(n, 6).tolist()} in the "
            "world frame; the arm moves in a vertical plane, so its axis (the plane's normal) "
            "must be horizontal, perpendicular to gravity along -z"
        )
    n = _unit(n - (n @ UP) * UP)  # within the tolerance of horizontal: made exactly so
    return Plane(normal=n, ex=np.cross(UP, n), ey=UP)


def _axes(urdf: Urdf, chain: Chain, frames, plane: Plane) -> tuple[list, list]:
    """Each joint's sign (revolute: +1 counter-clockwise about n) and in-plane axis (prismatic)."""
    signs, slides = [], []
    for joint in chain.joints:
        a = frames[joint.child][:3, :3] @ joint.axis
        if joint.type == "prismatic":
            if abs(a @ plane.normal) > TOLERANCE:
                raise UrdfError(
                    f"{urdf.source}: joint '{joint.name}' slides along {np.round(a, 6).tolist()} "
                    f"in the world frame, out of the plane of motion (normal "
                    f"{np.round(plane.normal, 6).tolist()}); expected an axis in the plane"
                )
            signs.append(1.0)
            slides.append(plane.point(a))
        else:
            if np.linalg.norm(np.cross(a, plane.normal)) > TOLERANCE:
                raise UrdfError(
                    f"{urdf.source}: joint '{joint.name}' turns about {np.round(a, 6).tolist()} "
                    f"in the world frame; expected the plane's normal "
                    f"{np.round(plane.normal, 6).tolist()} (the third joint's axis) or its "
                    "opposite"
                )
            signs.append(float(np.sign(a @ plane.normal)))
            slides.append(None)
    return signs, slides


def _body(urdf: Urdf, links: tuple[str, ...], frames, plane: Plane) -> Body:
    """Mass, centre of mass and inertia about the normal of the links one joint moves."""
    main = urdf.links[links[0]]
    if main.inertial is None:
        raise UrdfError(
            f"{urdf.source}: link '{main.name}' has no <inertial>; expected its mass, centre of "
            "mass and inertia"
        )
    parts = []
    for name in links:
        inertial = urdf.links[name].inertial
        if inertial is None:
            continue  # a frame fixed to the body (a sensor, a tool point): no mass
        R, p = frames[name][:3, :3], frames[name][:3, 3]
        inertia = float(plane.normal @ (R @ inertial.inertia @ R.T) @ plane.normal)
        if not (inertial.mass > 0 and inertia > 0):
            raise UrdfError(
                f"{urdf.source}: link '{name}' has mass {inertial.mass:g} kg and inertia "
                f"{inertia:g} kg m^2 about the plane's normal; expected both > 0"
            )
        parts.append((inertial.mass, plane.point(p + R @ inertial.com), inertia))
    mass = sum(m for m, _, _ in parts)
    com = sum(m * c for m, c, _ in parts) / mass
    inertia = sum(i + m * float((c - com) @ (c - com)) for m, c, i in parts)
    return Body(mass, com, inertia, main.name, main.cylinder)


def _on_line(urdf: Urdf, body: Body, start, direction) -> float:
    """The centre of mass's distance along ``direction`` from ``start``, refusing one that lies
    off that line (cpopt's turning links carry their centre of mass on it)."""
    offset = body.com - start
    if abs(_cross(direction, offset)) > TOLERANCE:
        raise UrdfError(
            f"{urdf.source}: link '{body.link}' has its centre of mass "
            f"{abs(_cross(direction, offset)):.3g} m off the line through its joints; cpopt's "
            "links carry it on that line"
        )
    return float(direction @ offset)


def _length(urdf: Urdf, body: Body, fallback: float) -> float:
    """A link length the joints do not fix: its visual cylinder's, else ``fallback`` (a
    uniform rod's), which must be positive."""
    length = body.cylinder if body.cylinder is not None else fallback
    if not length > 0:
        raise UrdfError(
            f"{urdf.source}: link '{body.link}': its joints do not fix its length; expected a "
            "<visual> with a <cylinder length=...> (the length draws the arm)"
        )
    return float(length)


def _segment(urdf: Urdf, joint, a, b) -> tuple[float, np.ndarray]:
    length = float(np.linalg.norm(b - a))
    if not length > TOLERANCE:
        raise UrdfError(
            f"{urdf.source}: joint '{joint.name}' is where the joint before it is at q = 0; "
            "expected a link of positive length between them"
        )
    return length, (b - a) / length


def _link(length: float, body: Body, com: float) -> dict:
    return {"length": length, "mass": body.mass, "com": com, "inertia": body.inertia}


def _unit(v) -> np.ndarray:
    return np.asarray(v, float) / np.linalg.norm(v)


def urdf_arm(urdf: Urdf, names: list[str] | None = None) -> UrdfArm:
    """The cpopt arm of a URDF whose moving joints are ``names`` (base to tip; None: the
    chain's three moving joints).

    Raises
    ------
    UrdfError
        Naming the joint or link that is not planar, not in cpopt's model or not physical.
    """
    chain = serial_chain(urdf, names)
    effort = actuation(urdf, chain)
    frames = world_frames(urdf, chain.root)
    plane = _plane(urdf, chain, frames)
    signs, slides = _axes(urdf, chain, frames, plane)
    P = [plane.point(frames[j.child][:3, 3]) for j in chain.joints]
    bodies = [_body(urdf, links, frames, plane) for links in chain.bodies]
    kind = "".join("P" if s is not None else "R" for s in slides[:2]) + "R"
    build = {"RRR": _rrr, "RPR": _rpr, "PRR": _prr, "PPR": _ppr}[kind]
    base, links, offsets, signs = build(urdf, chain, P, bodies, slides, signs)
    b3 = bodies[2]
    d3 = float(np.linalg.norm(b3.com - P[2]))
    if not d3 > TOLERANCE:
        raise UrdfError(
            f"{urdf.source}: link '{b3.link}' has its centre of mass on joint "
            f"'{chain.joints[2].name}'s axis; cpopt's third link needs it beyond the joint"
        )
    links.append(_link(_length(urdf, b3, 2 * d3), b3, d3))
    offsets.append(_angle(b3.com - P[2]) - offsets.pop())  # theta's offset minus link 2's
    return UrdfArm(
        kind=kind,
        base=(float(base[0]), float(base[1])),
        links=tuple(links),
        effort=effort,
        sign=tuple(signs),
        offset=tuple(float(o) for o in offsets),
    )


# Each kind returns the base, links 1-2, the offsets of joints 1-2 and, last, the absolute angle
# at q = 0 of what the third joint turns from (link 2, or link 1 of RPR, or 0 for PPR).


def _rrr(urdf, chain, P, bodies, slides, signs):
    l1, u1 = _segment(urdf, chain.joints[1], P[0], P[1])
    l2, u2 = _segment(urdf, chain.joints[2], P[1], P[2])
    links = [
        _link(l1, bodies[0], _on_line(urdf, bodies[0], P[0], u1)),
        _link(l2, bodies[1], _on_line(urdf, bodies[1], P[1], u2)),
    ]
    a1, a2 = _angle(u1), _angle(u2)
    return P[0], links, [a1, a2 - a1, a2], signs


def _rpr(urdf, chain, P, bodies, slides, signs):
    slide = _unit(slides[1])
    reach = float(np.linalg.norm(P[2] - P[0]))
    u = (P[2] - P[0]) / reach if reach > TOLERANCE else slide
    if abs(_cross(u, slide)) > TOLERANCE:
        raise UrdfError(
            f"{urdf.source}: joint '{chain.joints[1].name}' slides along "
            f"{np.round(slide, 6).tolist()} in the plane, not along the line from joint "
            f"'{chain.joints[0].name}' to joint '{chain.joints[2].name}'; an RPR arm's slide "
            "carries the third joint along that line"
        )
    signs[1] = float(np.sign(u @ slide))
    d1 = _on_line(urdf, bodies[0], P[0], u)
    e2 = _on_line(urdf, bodies[1], P[2], u)  # link 2's centre of mass from the third joint
    l2 = _length(urdf, bodies[1], -2 * e2)
    links = [_link(_length(urdf, bodies[0], 2 * d1), bodies[0], d1), _link(l2, bodies[1], l2 + e2)]
    a1 = _angle(u)
    return P[0], links, [a1, reach, a1], signs


def _horizontal(urdf, joint, slide, axis: int, what: str) -> float:
    slide = _unit(slide)
    if abs(slide[1 - axis]) > TOLERANCE:
        raise UrdfError(
            f"{urdf.source}: joint '{joint.name}' slides along {np.round(slide, 6).tolist()} in "
            f"the plane (x, y up); cpopt's {what} slide is {'vertical' if axis else 'horizontal'}"
        )
    return float(np.sign(slide[axis]))


def _carried(urdf, body: Body, at, axis: int) -> dict:
    """A sliding link whose far end is at ``at``: its centre of mass's offset along the slide."""
    e = float(body.com[axis] - at[axis])
    length = _length(urdf, body, -2 * e)
    return _link(length, body, length + e)


def _prr(urdf, chain, P, bodies, slides, signs):
    signs[0] = _horizontal(urdf, chain.joints[0], slides[0], 0, "first")
    l2, u2 = _segment(urdf, chain.joints[2], P[1], P[2])
    links = [
        _carried(urdf, bodies[0], P[1], 0),
        _link(l2, bodies[1], _on_line(urdf, bodies[1], P[1], u2)),
    ]
    a2 = _angle(u2)
    return P[1], links, [0.0, a2, a2], signs


def _ppr(urdf, chain, P, bodies, slides, signs):
    signs[0] = _horizontal(urdf, chain.joints[0], slides[0], 0, "first")
    signs[1] = _horizontal(urdf, chain.joints[1], slides[1], 1, "second")
    links = [_carried(urdf, bodies[0], P[2], 0), _carried(urdf, bodies[1], P[2], 1)]
    return P[2], links, [0.0, 0.0, 0.0], signs
