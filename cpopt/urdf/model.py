"""A URDF file read into plain data with the standard library's XML parser.

Only what a planar arm needs is kept: links with their inertials, joints with their origins,
axes, limits and mimic tags, and which joints a ``<transmission>`` drives. Frames are composed
at q = 0 here too (:func:`world_frames`), so that the checks of :mod:`cpopt.urdf.arm` work in
the world frame.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

MAX_BYTES = 20_000_000
"""Largest URDF read [bytes]: a robot description with meshes referenced, not inlined."""

UNLIMITED = 1e9
"""An effort limit at least this large [N m or N] reads as none: what ``cpopt export-urdf``
writes for an actuated prismatic joint without a limit (its ``<limit>`` needs an effort)."""


class UrdfError(ValueError):
    """A URDF that cannot describe a cpopt arm: the file, and what in it (a joint or link by
    name) was not what was expected."""


@dataclass(frozen=True)
class Inertial:
    """A link's ``<inertial>``: mass [kg], centre of mass and the inertia tensor [kg m^2] in the
    link's frame (the tensor rotated by the inertial origin's rpy)."""

    mass: float
    com: np.ndarray
    inertia: np.ndarray


@dataclass(frozen=True)
class UrdfLink:
    """A ``<link>``: its inertial (None when it has none) and the length of a ``<visual>``
    cylinder [m] (None without one), which gives a link the joints do not measure its length."""

    name: str
    inertial: Inertial | None
    cylinder: float | None


@dataclass(frozen=True)
class UrdfJoint:
    """A ``<joint>``: type, parent and child links, origin (a 4 x 4 transform), unit axis in the
    joint frame, effort limit [N m or N] (None when not given) and whether it mimics another."""

    name: str
    type: str
    parent: str
    child: str
    origin: np.ndarray
    axis: np.ndarray
    effort: float | None
    mimic: bool


@dataclass(frozen=True)
class Urdf:
    """A URDF's robot: links and joints by name, the joints a transmission drives, the file."""

    name: str
    links: dict[str, UrdfLink]
    joints: dict[str, UrdfJoint]
    transmitted: frozenset[str]
    source: str


def rotation(rpy) -> np.ndarray:
    """The rotation matrix of URDF's fixed-axis roll, pitch, yaw [rad]: Rz(y) Ry(p) Rx(r)."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = (math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y),
                              math.sin(y))  # fmt: skip
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def _numbers(text: str | None, count: int, what: str, source: str) -> np.ndarray:
    if text is None:
        return np.zeros(count)
    try:
        values = np.array([float(v) for v in text.split()])
    except ValueError:
        values = np.array([])
    if values.shape != (count,) or not np.all(np.isfinite(values)):
        raise UrdfError(f"{source}: {what}: expected {count} finite numbers, got {text!r}")
    return values


def _number(element, key: str, what: str, source: str) -> float | None:
    text = None if element is None else element.get(key)
    return None if text is None else float(_numbers(text, 1, f"{what} {key}", source)[0])


def _origin(element, what: str, source: str) -> np.ndarray:
    """The 4 x 4 transform of an ``<origin xyz rpy>`` (identity when absent)."""
    origin = element.find("origin")
    T = np.eye(4)
    if origin is not None:
        T[:3, :3] = rotation(_numbers(origin.get("rpy"), 3, f"{what} origin rpy", source))
        T[:3, 3] = _numbers(origin.get("xyz"), 3, f"{what} origin xyz", source)
    return T


def _inertial(element, name: str, source: str) -> Inertial | None:
    inertial = element.find("inertial")
    if inertial is None:
        return None
    what = f"link '{name}' inertial"
    mass = _number(inertial.find("mass"), "value", f"{what} mass", source)
    tensor = inertial.find("inertia")
    if mass is None or tensor is None:
        raise UrdfError(f"{source}: {what}: expected a <mass value> and an <inertia>")
    keys = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
    v = {k: _number(tensor, k, f"{what} inertia", source) or 0.0 for k in keys}
    local = np.array(
        [
            [v["ixx"], v["ixy"], v["ixz"]],
            [v["ixy"], v["iyy"], v["iyz"]],
            [v["ixz"], v["iyz"], v["izz"]],
        ]
    )
    T = _origin(inertial, what, source)
    R = T[:3, :3]
    return Inertial(mass=mass, com=T[:3, 3], inertia=R @ local @ R.T)


def _cylinder(element, name: str, source: str) -> float | None:
    cylinder = element.find("visual/geometry/cylinder")
    return _number(cylinder, "length", f"link '{name}' visual cylinder", source)


def _joint(element, source: str) -> UrdfJoint:
    name = element.get("name", "")
    what = f"joint '{name}'"
    parent, child = element.find("parent"), element.find("child")
    if parent is None or child is None or not parent.get("link") or not child.get("link"):
        raise UrdfError(f"{source}: {what}: expected <parent link=...> and <child link=...>")
    axis = _numbers(
        element.find("axis").get("xyz") if element.find("axis") is not None else "1 0 0",
        3,
        f"{what} axis xyz",
        source,
    )
    norm = np.linalg.norm(axis)
    if element.get("type") != "fixed" and not norm > 0:
        raise UrdfError(f"{source}: {what}: the axis must not be zero")
    return UrdfJoint(
        name=name,
        type=element.get("type", ""),
        parent=parent.get("link"),
        child=child.get("link"),
        origin=_origin(element, what, source),
        axis=axis / norm if norm > 0 else axis,
        effort=_number(element.find("limit"), "effort", f"{what} limit", source),
        mimic=element.find("mimic") is not None,
    )


def _transmitted(root) -> frozenset[str]:
    """Names of the joints a ``<transmission>`` drives (the URDF convention for an actuator)."""
    return frozenset(
        joint.get("name", "") for t in root.iter("transmission") for joint in t.findall("joint")
    )


def parse_urdf(text: str, source: str = "<urdf>") -> Urdf:
    """A URDF document read into :class:`Urdf`.

    Raises
    ------
    UrdfError
        For XML that does not parse, a root that is not ``<robot>``, or a value that is not a
        number where one is expected, naming the source and the element.
    """
    try:
        root = ET.fromstring(text)
    except ET.ParseError as err:
        raise UrdfError(f"{source}: not readable XML ({err})") from None
    if root.tag != "robot":
        raise UrdfError(f"{source}: expected a <robot> element at the top, got <{root.tag}>")
    links = {}
    for element in root.findall("link"):
        name = element.get("name", "")
        links[name] = UrdfLink(
            name, _inertial(element, name, source), _cylinder(element, name, source)
        )
    joints = {}
    for element in root.findall("joint"):
        joint = _joint(element, source)
        for end in (joint.parent, joint.child):
            if end not in links:
                raise UrdfError(f"{source}: joint '{joint.name}': no link named '{end}'")
        joints[joint.name] = joint
    return Urdf(root.get("name", ""), links, joints, _transmitted(root), source)


def read_urdf(path: str | Path) -> Urdf:
    """A URDF file read into :class:`Urdf`.

    Raises
    ------
    UrdfError
        For a file that cannot be read, is too large or does not parse.
    """
    path = Path(path)
    try:
        if path.stat().st_size > MAX_BYTES:
            raise UrdfError(f"{path}: larger than {MAX_BYTES // 1_000_000} MB")
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as err:
        reason = err.strerror if isinstance(err, OSError) and err.strerror else str(err)
        raise UrdfError(f"{path}: cannot read the URDF ({reason})") from None
    return parse_urdf(text, str(path))


def world_frames(urdf: Urdf, root: str) -> dict[str, np.ndarray]:
    """The 4 x 4 pose of every link reachable from ``root`` at q = 0, in the root's frame."""
    frames = {root: np.eye(4)}
    todo = [root]
    while todo:
        parent = todo.pop()
        for joint in urdf.joints.values():
            if joint.parent == parent and joint.child not in frames:
                frames[joint.child] = frames[parent] @ joint.origin
                todo.append(joint.child)
    return frames
