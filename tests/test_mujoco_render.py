"""Pictures from MuJoCo's offscreen renderer (``Solution.render``, ``cpopt solve --animate
--engine mujoco``), skipped with the renderer's reason where no OpenGL context can be made."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import PROBLEMS
from PIL import Image

import cpopt
from cpopt import mujoco_render
from cpopt.cli import main
from cpopt.mujoco_render import RenderUnavailableError

TRACKED = "tracking:\n  controller: tvlqr\n  plant:\n    links: [null, {mass: 1.3}, null]\n"


@pytest.fixture(scope="module")
def tracked_solution(tmp_path_factory):
    path = tmp_path_factory.mktemp("render") / "tracked.yaml"
    path.write_text((PROBLEMS / "paper_swing_up.yaml").read_text() + TRACKED)
    return cpopt.solve(path)


def _render(solution, path, **kwargs) -> str:
    try:
        return solution.render(path, **kwargs)
    except RenderUnavailableError as err:
        pytest.skip(str(err))


def test_a_gif_of_the_tracked_arm_beside_the_plan(tracked_solution, tmp_path):
    path = tmp_path / "arm.gif"
    backend = _render(tracked_solution, path, fps=10)
    assert backend in ("egl", "osmesa")
    with Image.open(path) as gif:
        assert gif.size == (480, 480)
        assert gif.n_frames == 17  # 1.6 s at 10 frames per second, both ends
        gif.seek(8)
        frame = np.asarray(gif.convert("RGB"), float)
    assert frame.std() > 5  # an arm on the backdrop, not a blank image


def test_the_tracked_arm_moves_the_picture(tracked_solution, tmp_path):
    """The heavier plant's arm is drawn where it is, not where the plan is."""
    with_tracking, plan_only = tmp_path / "a.png", tmp_path / "b.png"
    _render(tracked_solution, with_tracking, fps=2)
    _render(tracked_solution, plan_only, fps=2, tracked=False)
    a = np.asarray(Image.open(with_tracking), float)
    b = np.asarray(Image.open(plan_only), float)
    assert a.shape == b.shape == (480, 480, 3)
    assert np.abs(a - b).max() > 50  # the translucent plan over the solid tracked arm


def test_solve_animate_with_mujoco_writes_arm_gif(tmp_path, capsys):
    out = tmp_path / "out"
    code = main(["solve", str(PROBLEMS / "rpr_transfer.yaml"), "--out", str(out), "--animate",
                 "--engine", "mujoco", "--quiet"])  # fmt: skip
    assert code == 0
    err = capsys.readouterr().err
    if "arm.gif skipped" in err:
        pytest.skip(err.strip())
    with Image.open(out / "rpr_transfer" / "arm.gif") as gif:
        assert gif.n_frames == 39  # 1.5 s at 25 frames per second


def test_without_an_opengl_context_the_gif_is_skipped_with_a_reason(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(mujoco_render, "BACKENDS", ("no-such-backend",))
    out = tmp_path / "out"
    code = main(["solve", str(PROBLEMS / "rpr_transfer.yaml"), "--out", str(out), "--animate",
                 "--engine", "mujoco", "--quiet"])  # fmt: skip
    assert code == 0  # the results are written all the same
    err = capsys.readouterr().err
    assert "rpr_transfer: arm.gif skipped: no OpenGL context for MuJoCo's offscreen renderer" in err
    assert "no-such-backend: " in err and "Traceback" not in err
    assert (out / "rpr_transfer" / "solution.json").exists()
    assert not (out / "rpr_transfer" / "arm.gif").exists()


def test_without_mujoco_the_engine_is_refused_before_any_work(tmp_path, capsys, monkeypatch):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a: None if name == "mujoco" else real(name, *a)
    )
    out = tmp_path / "out"
    code = main(["solve", str(PROBLEMS / "rpr_transfer.yaml"), "--out", str(out), "--animate",
                 "--engine", "mujoco"])  # fmt: skip
    assert code == 2
    err = capsys.readouterr().err
    assert err == "error: --engine mujoco: MuJoCo is not installed: pip install 'cpopt[mujoco]'\n"
    assert not out.exists()
