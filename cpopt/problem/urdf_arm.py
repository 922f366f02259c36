"""``arm: {urdf: PATH, joints: [j1, j2, j3]}``: a problem's arm read from a URDF file, turned
into the plain ``arm`` keys (kind, base, links) before the schema checks the whole file.

The path is relative to the problem file (to the working folder for problem data given in
Python). The joints' effort limits become ``optimizer.limits.torque`` when the problem gives
none.
"""

from __future__ import annotations

import copy
import math
from pathlib import Path

from pydantic import ValidationError

from ..io.safe_yaml import echo
from ..urdf import UrdfError, read_urdf, urdf_arm
from .messages import describe_error
from .schema import ProblemError, UrdfArmSpec

PLAIN_KEYS = ("kind", "base", "links")
"""Keys of a plain arm that a URDF gives: refused beside ``urdf``."""


def _spec(arm: dict, source: str) -> UrdfArmSpec:
    for key in PLAIN_KEYS:
        if key in arm:
            raise ProblemError(
                source,
                f"arm.{key}",
                f"the arm is read from the URDF {echo(arm['urdf'])}, which gives its {key}: "
                f"delete arm.{key}, or arm.urdf to describe the arm here",
            )
    try:
        return UrdfArmSpec.model_validate(arm)
    except ValidationError as err:
        error = dict(err.errors()[0])
        if error["type"] == "extra_forbidden":
            allowed = ", ".join(UrdfArmSpec.model_fields)
            key = error["loc"][-1]
            raise ProblemError(
                source, f"arm.{key}", f"unknown key beside urdf (allowed here: {allowed})"
            ) from None
        path, message = describe_error({**error, "loc": ("arm", *error["loc"])})
        raise ProblemError(source, path, message) from None


def urdf_path(urdf: str, source: str) -> Path:
    """The URDF's path: relative to the problem file's folder, or to the working folder."""
    path = Path(urdf).expanduser()
    if path.is_absolute():
        return path
    where = Path(source)
    return (where.parent if where.is_file() else Path.cwd()) / path


def absolute_urdf(data, source: str):
    """Problem data whose relative ``arm.urdf`` is made absolute from ``source``'s folder (a
    copy; other data returned as it is): for data validated later under another name (a
    sweep's points, a Dask worker's working folder)."""
    arm = data.get("arm") if isinstance(data, dict) else None
    if not (isinstance(arm, dict) and isinstance(arm.get("urdf"), str) and arm["urdf"].strip()):
        return data
    out = copy.deepcopy(data)
    out["arm"]["urdf"] = str(urdf_path(arm["urdf"], source).resolve())
    return out


def expand_urdf(data: dict, source: str) -> dict:
    """Problem data whose ``arm`` is read from a URDF, as plain problem data (a copy); other
    data unchanged.

    Raises
    ------
    ProblemError
        For a URDF that cannot be read or is not a cpopt arm (key path ``arm.urdf``; the message
        names the joint or link and what was expected), or arm keys beside ``urdf`` that the
        URDF gives.
    """
    arm = data.get("arm")
    if not (isinstance(arm, dict) and "urdf" in arm):
        return data
    spec = _spec(arm, source)
    try:
        found = urdf_arm(read_urdf(urdf_path(spec.urdf, source)), spec.joints)
    except UrdfError as err:
        raise ProblemError(source, "arm.urdf", str(err)) from None
    out = copy.deepcopy(data)
    out["arm"] = {**found.spec(), "gravity": spec.gravity}
    if spec.branch is not None:
        out["arm"]["branch"] = spec.branch
    optimizer = out.get("optimizer")
    limits = optimizer.get("limits") if isinstance(optimizer, dict) else None
    given = isinstance(limits, dict) and "torque" in limits
    if not given and any(math.isfinite(e) for e in found.effort):
        torque = [e if math.isfinite(e) else None for e in found.effort]
        out.setdefault("optimizer", {})
        if isinstance(out["optimizer"], dict):
            out["optimizer"].setdefault("limits", {})
            if isinstance(out["optimizer"]["limits"], dict):
                out["optimizer"]["limits"]["torque"] = torque
    return out
