"""Pictures of an arm from MuJoCo's offscreen renderer: a GIF of the planned arm (translucent)
and the tracked one, or one PNG frame.

OpenGL is made in a child process, EGL first and OSMesa where EGL is missing (MuJoCo picks its
backend from ``MUJOCO_GL`` once, when it is first imported, and a failed backend may not leave
the process usable): the child writes the file, the parent only says which backend worked, or
raises :class:`RenderUnavailableError` with each backend's reason. Shadows are off (speed).
"""

from __future__ import annotations

import json
import math
import numbers
import os
import subprocess
import sys
import tempfile
from dataclasses import asdict
from pathlib import Path

import numpy as np

from .io.safe_yaml import echo
from .model.robot import Arm, Link

BACKENDS = ("egl", "osmesa")
"""MuJoCo's offscreen OpenGL backends, tried in this order."""
RENDER_TIMEOUT = 300.0
"""Longest a child process may render [s]."""


SUFFIXES = (".gif", ".png")
"""What :func:`render` writes: an animation, or one frame."""

ImageFile = str | Path
"""A ``.gif`` or ``.png`` file to write, in an existing folder."""
Time = float
"""A time within a plan [s]."""


def _real(value) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def check_render_arguments(path, fps, tracked, at, duration: float) -> Path:
    """Refuse bad arguments of :meth:`cpopt.Solution.render` before any work, naming each.

    Returns
    -------
    Path
        The output file.

    Raises
    ------
    ValueError
        One line naming the argument and what was expected.
    """
    if not isinstance(path, str | Path) or not str(path).strip():
        raise ValueError(f"path: expected a .gif or .png file name, got {echo(path)}")
    out = Path(path)
    if out.suffix.lower() not in SUFFIXES:
        raise ValueError(f"path: expected a .gif or .png file name, got {echo(str(path))}")
    if out.is_dir() or not out.parent.is_dir():
        why = "is a folder" if out.is_dir() else f"{out.parent} is not an existing folder"
        raise ValueError(f"path: {out} {why}; expected a file in an existing folder")
    if not (_real(fps) and math.isfinite(fps) and fps > 0):
        raise ValueError(f"fps: expected a finite number of frames per second > 0, got {echo(fps)}")
    if not isinstance(tracked, bool):
        raise ValueError(f"tracked: expected True or False, got {echo(tracked)}")
    if not (_real(at) and math.isfinite(at) and 0 <= at <= duration):
        raise ValueError(f"at: expected a time in [0, {duration:g}] s, got {echo(at)}")
    return out


class RenderUnavailableError(RuntimeError):
    """No OpenGL context could be made for MuJoCo's offscreen renderer (each backend's reason
    in the message)."""


def _arm_from(data: dict) -> Arm:
    links = tuple(Link(**link) for link in data.pop("links"))
    return Arm(links=links, **{k: tuple(v) if k == "base" else v for k, v in data.items()})


def _camera(mujoco, arm: Arm, q: np.ndarray):
    """A camera looking at the plane (x right, y up) that holds every frame's arm."""
    from .model.kinematics import kinematic_functions

    points = kinematic_functions(arm)["points"]
    pts = np.concatenate([np.asarray(points(qi)).T for qi in q])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.lookat[:] = [(lo[0] + hi[0]) / 2, 0.0, (lo[1] + hi[1]) / 2]
    camera.azimuth, camera.elevation = 90.0, 0.0  # from -y, along the plane's normal
    extent = max(hi[0] - lo[0], hi[1] - lo[1], 1.0)
    camera.distance = 0.62 * extent / np.tan(np.radians(22.5))  # MuJoCo's field of view: 45 deg
    return camera


def _decorated(mujoco, arm: Arm, ghost: bool):
    """The arm's model with a light backdrop, a light and a mark at the base (all drawing only)."""
    from .model.mujoco_arm import arm_spec

    spec = arm_spec(arm, ghost=arm if ghost else None)
    spec.add_texture(
        name="sky",
        type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
        builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT,
        rgb1=[1.0, 1.0, 1.0],
        rgb2=[0.82, 0.86, 0.92],
        width=64,
        height=64,
    )
    spec.worldbody.add_light(pos=[0.0, -6.0, 6.0], dir=[0.0, 1.0, -1.0])
    spec.worldbody.add_geom(
        type=mujoco.mjtGeom.mjGEOM_BOX,
        pos=[arm.base[0], 0.05, arm.base[1] - 0.06],
        size=[0.12, 0.02, 0.06],
        contype=0,
        conaffinity=0,
        rgba=[0.3, 0.3, 0.3, 1.0],
    )
    return spec.compile()


def render_frames(arm: Arm, q_plan, q_tracked=None, width: int = 480, height: int = 480):
    """Frames (N, height, width, 3) of the arm at joint positions ``q_plan`` (N, 3), with the
    tracked arm ``q_tracked`` (N, 3) solid and the plan translucent when given. Needs an OpenGL
    context in this process (``MUJOCO_GL`` set before MuJoCo is imported)."""
    from .model.mujoco_arm import require_mujoco

    mujoco = require_mujoco()
    q_plan = np.atleast_2d(q_plan)
    model = _decorated(mujoco, arm, ghost=q_tracked is not None)
    model.vis.global_.offwidth, model.vis.global_.offheight = width, height
    data = mujoco.MjData(model)
    shown = q_plan if q_tracked is None else np.vstack([q_plan, np.atleast_2d(q_tracked)])
    camera = _camera(mujoco, arm, shown)
    frames = []
    with mujoco.Renderer(model, height, width) as renderer:
        renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
        for i, q in enumerate(q_plan):
            if q_tracked is None:
                data.qpos[:3] = q
            else:
                data.qpos[:3], data.qpos[3:6] = np.atleast_2d(q_tracked)[i], q
            mujoco.mj_forward(model, data)
            renderer.update_scene(data, camera)
            frames.append(renderer.render().copy())
    return np.array(frames)


def _write_images(frames: np.ndarray, path: Path, fps: float) -> None:
    from PIL import Image  # matplotlib's dependency

    from .io.output import atomic_path

    images = [Image.fromarray(f) for f in frames]
    with atomic_path(path) as tmp:
        if path.suffix.lower() == ".png":
            images[0].save(tmp, format="PNG")
        else:
            duration = round(1000 / fps)
            images[0].save(tmp, format="GIF", save_all=True, append_images=images[1:],
                           duration=duration, loop=0)  # fmt: skip


def _child(job: Path) -> None:
    """The child process: read the job, render, write the file."""
    with np.load(job, allow_pickle=False) as saved:
        meta = json.loads(str(saved["meta"]))
        q_plan = saved["q_plan"]
        q_tracked = saved.get("q_tracked")
    frames = render_frames(_arm_from(meta["arm"]), q_plan, q_tracked, *meta["size"])
    _write_images(frames, Path(meta["path"]), meta["fps"])


def render(arm: Arm, q_plan, path: str | Path, q_tracked=None, fps: float = 25.0,
           size: tuple[int, int] = (480, 480)) -> str:  # fmt: skip
    """Write a GIF (or, for a ``.png`` path, the first frame) of the arm.

    Parameters
    ----------
    arm : Arm
        The arm drawn (the plan's).
    q_plan : array_like
        Joint positions of the plan at each frame (N, 3) [rad or m].
    path : str or Path
        Output ``.gif`` or ``.png``.
    q_tracked : array_like, optional
        Joint positions of the tracked arm at the same frames (N, 3), drawn solid with the plan
        translucent.
    fps : float
        Frames per second.
    size : tuple of int
        Width and height [pixels].

    Returns
    -------
    str
        The OpenGL backend that rendered (``egl`` or ``osmesa``).

    Raises
    ------
    RenderUnavailableError
        When neither backend can make an OpenGL context (nothing is written).
    MujocoMissingError
        Without MuJoCo.
    """
    from .model.mujoco_arm import require_mujoco

    require_mujoco()
    path = Path(path)
    reasons = []
    with tempfile.TemporaryDirectory() as folder:
        job = Path(folder) / "job.npz"
        arrays = {"q_plan": np.asarray(q_plan, float)}
        if q_tracked is not None:
            arrays["q_tracked"] = np.asarray(q_tracked, float)
        meta = {"arm": asdict(arm), "path": str(path.resolve()), "fps": fps, "size": list(size)}
        np.savez(job, meta=json.dumps(meta), **arrays)
        for backend in BACKENDS:
            env = {**os.environ, "MUJOCO_GL": backend, "PYOPENGL_PLATFORM": backend}
            done = subprocess.run(
                [sys.executable, "-m", "cpopt.mujoco_render", str(job)],
                env=env, capture_output=True, text=True, timeout=RENDER_TIMEOUT,
            )  # fmt: skip
            if done.returncode == 0:
                return backend
            lines = done.stderr.strip().splitlines()
            reasons.append(f"{backend}: {lines[-1] if lines else f'exit {done.returncode}'}")
    raise RenderUnavailableError(
        "no OpenGL context for MuJoCo's offscreen renderer (" + "; ".join(reasons) + "); "
        "install EGL (apt-get install libegl1) or OSMesa (libosmesa6)"
    )


if __name__ == "__main__":
    _child(Path(sys.argv[1]))
