"""The Python API: cpopt.load, cpopt.solve, cpopt.track and the Solution they return."""

import json
import subprocess
import sys

import matplotlib.pyplot as plt
import numpy as np
import pytest
import yaml
from conftest import PROBLEMS, ROOT

import cpopt
from cpopt.cli import main
from cpopt.tracking import TrackingOutcome

SWING_UP = PROBLEMS / "paper_swing_up.yaml"
MIN_TORQUE = PROBLEMS / "swing_up_min_torque.yaml"
TRANSFER = ROOT / "benchmarks" / "problems" / "transfer.yaml"


@pytest.fixture(scope="module")
def swing_up():
    return cpopt.solve(SWING_UP)


def test_import_cpopt_loads_nothing_heavy():
    code = (
        "import sys, cpopt; "
        "print(sorted(m for m in ('casadi', 'pydantic', 'cpopt.api', 'cpopt.pipeline') "
        "if m in sys.modules)); print('solve' in dir(cpopt))"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert run.stdout.split("\n")[:2] == ["[]", "True"]


def test_the_names_are_the_modules_names():
    from cpopt.problem import Problem, ProblemError
    from cpopt.solution import Solution

    assert (cpopt.Problem, cpopt.ProblemError, cpopt.Solution) == (Problem, ProblemError, Solution)
    with pytest.raises(AttributeError, match="no attribute 'frobnicate'"):
        cpopt.frobnicate  # noqa: B018


def test_load_with_an_override_changes_the_plans_duration():
    problem = cpopt.load(SWING_UP, **{"motion.duration": 1.7})
    assert problem.nodes[-1].t == 1.7
    assert problem.nodes[1].t == 1.0  # the via state's time is the file's
    solution = cpopt.solve(problem)
    assert solution.status == "solved"
    assert solution.plan.duration == pytest.approx(1.7, abs=1e-12)
    assert solution.trajectory.t[-1] == pytest.approx(1.7, abs=1e-12)
    # a longer second phase (0.7 s instead of 0.6 s) costs more here: 27600.6 vs 12953.3
    assert solution.metrics.torque_sq_integral == pytest.approx(27600.6, rel=1e-5)


def test_load_from_a_dict_leaves_the_dict_alone():
    data = yaml.safe_load(SWING_UP.read_text())
    problem = cpopt.load(data, **{"arm.links[2].mass": 0.8})
    assert data["arm"]["links"][2]["mass"] == 0.5
    assert problem.arm.links[2].mass == 0.8
    assert problem.source == "<python>"


def test_replace_validates_again_and_keeps_the_original():
    problem = cpopt.load(MIN_TORQUE)
    longer = problem.replace(**{"motion.duration": 2.5}, planner="closed_form")
    assert (longer.nodes[-1].t, longer.planner) == (2.5, "closed_form")
    assert (problem.nodes[-1].t, problem.planner) == (1.6, "optimize")
    assert longer.name == problem.name == "swing_up_min_torque"
    # replace of a replaced problem starts from its data, overrides included
    assert longer.replace(**{"motion.via[0].t": 1.2}).nodes[-1].t == 2.5


@pytest.mark.parametrize(
    ("overrides", "path", "words"),
    [
        ({"motion.durration": 2.0}, "motion.durration", "did you mean 'duration'"),
        ({"motion.via[5].t": 1.0}, "motion.via[5].t", "no item [5]"),
        ({"motion.duration": -1.0}, "motion.duration", "greater than 0"),
        ({"motion..duration": 1.0}, "motion..duration", ""),
        ({"arm.links[2].mass.value": 1.0}, "arm.links[2].mass.value", ""),
    ],
)
def test_a_bad_override_is_a_problem_error_naming_the_key_path(overrides, path, words):
    with pytest.raises(cpopt.ProblemError) as caught:
        cpopt.load(MIN_TORQUE, **overrides)
    err = caught.value
    assert (err.source, err.path) == (str(MIN_TORQUE), path)
    assert words in err.message


def test_load_refuses_what_is_not_a_problem(tmp_path):
    with pytest.raises(cpopt.ProblemError, match=r"nope\.yaml"):
        cpopt.load(tmp_path / "nope.yaml")
    with pytest.raises(cpopt.ProblemError, match="path_or_dict: expected a problem file"):
        cpopt.load(42)


def test_solve_gives_the_command_lines_numbers_and_files(swing_up, tmp_path, capsys):
    assert main(["solve", str(SWING_UP), "--out", str(tmp_path / "cli")]) == 0
    cli_dir = tmp_path / "cli" / "paper_swing_up"
    cli = json.loads((cli_dir / "solution.json").read_text())
    document = swing_up.to_dict()
    assert document["metrics"] == cli["metrics"]
    assert document["metrics"]["torque_sq_integral"] == pytest.approx(12953.3, rel=1e-5)
    for key in ("name", "status", "planner", "duration_s", "verification", "free_values"):
        assert document[key] == cli[key], key
    written = swing_up.save(tmp_path / "api")
    assert sorted(p.name for p in written) == sorted(p.name for p in cli_dir.iterdir())
    api_dir = tmp_path / "api"
    assert (api_dir / "trajectory.csv").read_bytes() == (cli_dir / "trajectory.csv").read_bytes()
    assert json.loads((api_dir / "solution.json").read_text())["metrics"] == cli["metrics"]


def test_repr_is_one_line_with_status_cost_peaks_and_gamma(swing_up):
    m = swing_up.metrics
    text = repr(swing_up)
    assert "\n" not in text
    assert text.startswith("<Solution paper_swing_up: solved, planner=closed_form")
    assert f"torque_sq_integral={m.torque_sq_integral:.6g}" in text
    assert f"peak_torque=({m.peak_torque[0]:.4g} N m, {m.peak_torque[1]:.4g} N m)" in text
    assert f"min|gamma|={m.min_abs_gamma:.4g} m/s^2" in text
    page = swing_up._repr_html_()
    assert page.startswith("<table>") and f"{m.min_abs_gamma:.4g} m/s^2" in page


def test_a_failure_shows_its_status_and_message():
    solution = cpopt.solve(MIN_TORQUE, time_limit=1e-3)
    assert solution.status == "time_limit"
    assert solution.to_dict()["status"] == "time_limit"
    assert "time_limit" in repr(solution) and "wall-clock limit" in repr(solution)
    with pytest.raises(ValueError, match="no plan to sample"):
        solution.sample(0.5)


def test_sample_at_the_trajectorys_times_is_the_trajectory(swing_up):
    traj = swing_up.trajectory
    # every sample but the left ends of phase joins (sample(t) there is the right limit)
    join_left = np.flatnonzero(np.diff(traj.t) == 0)
    keep = np.setdiff1d(np.arange(traj.t.size), join_left)[::7]
    got = swing_up.sample(traj.t[keep])
    for name in ("z", "q", "qd", "qdd", "tau", "cp", "gamma"):
        want = getattr(traj, name)[keep]
        np.testing.assert_allclose(getattr(got, name), want, rtol=1e-9, atol=1e-9, err_msg=name)
    assert np.array_equal(got.phase, traj.phase[keep])


def test_sample_between_samples_follows_the_plan(swing_up):
    traj = swing_up.trajectory
    i = np.arange(3, 390, 17)  # inside the first phase
    mid = (traj.t[i] + traj.t[i + 1]) / 2
    got = swing_up.sample(mid)
    np.testing.assert_allclose(
        got.cp[:, :, 0], swing_up.plan.phases[0].curve.derivatives(mid, 0)[:, :, 0]
    )
    # 401 samples over 1 s: the midpoint lies within the neighbours' chord to second order
    np.testing.assert_allclose(got.q, (traj.q[i] + traj.q[i + 1]) / 2, atol=1e-3)
    np.testing.assert_allclose(got.tau, (traj.tau[i] + traj.tau[i + 1]) / 2, rtol=1e-3, atol=0.5)
    one = swing_up.sample(0.25)
    assert one.tau.shape == (1, 2) and one.z.shape == (1, 8)
    with pytest.raises(ValueError, match=r"within the plan, \[0, 1.6\] s"):
        swing_up.sample([0.5, 1.7])


def test_free_values_are_the_optimizers():
    solution = cpopt.solve(MIN_TORQUE)
    assert solution.status == "solved"
    assert set(solution.free_values) == set(cpopt.load(MIN_TORQUE).free)
    assert solution.free_values == solution.to_dict()["free_values"]
    assert solution.free_values["start.xi"] == pytest.approx(0.0, abs=1e-6)
    # gamma_min = 2 is active at the via state: xi there sits on the margin
    assert solution.free_values["via[0].xi"] == pytest.approx(-2.004, abs=1e-3)


def test_planner_override_and_progress(capsys):
    solution = cpopt.solve(MIN_TORQUE, planner="closed_form", progress=True)
    assert (solution.planner, solution.status) == ("closed_form", "solved")
    assert solution.free_values == {}
    err = capsys.readouterr().err
    assert "cpopt: swing_up_min_torque: planning (closed form)" in err
    assert "cpopt: swing_up_min_torque: verifying by simulation" in err
    cpopt.solve(SWING_UP)
    assert capsys.readouterr().err == ""
    with pytest.raises(cpopt.ProblemError, match="planner"):
        cpopt.solve(SWING_UP, planner="newton")


@pytest.mark.parametrize("kind", ["third_link", "arm", "torques", "gamma"])
def test_plot_returns_the_figure(swing_up, kind):
    fig = swing_up.plot(kind)
    try:
        assert fig.axes and fig.axes[0].lines
        if kind == "torques":  # tau1 and tau2 over the plan's 802 samples
            assert [line.get_xdata().size for line in fig.axes[0].lines[:2]] == [802, 802]
    finally:
        plt.close(fig)


def test_plot_refuses_what_it_cannot_draw(swing_up):
    with pytest.raises(ValueError, match="kind must be one of third_link, arm"):
        swing_up.plot("bode")
    with pytest.raises(ValueError, match="not tracked"):
        swing_up.plot("tracking")


def test_track_is_the_tracking_block(swing_up):
    plant = {"links": [None, None, {"mass": 0.55}], "friction": {"viscous": [0.1, 0.1, 0.0]}}
    block = {"controller": "tvlqr", "rate_hz": 500.0, "plant": plant}
    with_block = cpopt.solve(cpopt.load(SWING_UP, tracking=block))
    outcome = cpopt.track(swing_up, controller="tvlqr", plant=plant, rate_hz=500.0)
    assert isinstance(outcome, TrackingOutcome)
    assert outcome.summary() == with_block.tracking.summary()
    assert outcome.summary()["success"] is True
    assert outcome.rate_hz == 500.0
    tracked = cpopt.Solution.of(with_block, with_block.problem)
    fig = tracked.plot("tracking")
    plt.close(fig)


def test_track_refuses_bad_settings_with_the_key_path(swing_up):
    with pytest.raises(cpopt.ProblemError) as caught:
        cpopt.track(swing_up, plant={"links": [None, None, {"mas": 0.5}]})
    assert caught.value.path == "tracking.plant.links[2].mas"
    with pytest.raises(cpopt.ProblemError, match=r"tracking\.controller"):
        cpopt.track(swing_up, controller="pid")
    failed = cpopt.solve(MIN_TORQUE, time_limit=1e-3)
    with pytest.raises(ValueError, match="no plan to track"):
        cpopt.track(failed)


def test_a_collocation_solution_samples_its_polynomials():
    problem = cpopt.load(TRANSFER, planner="collocation", **{"collocation.intervals": 30})
    solution = cpopt.solve(problem)
    assert solution.status == "solved"
    traj = solution.trajectory
    idx = np.arange(0, traj.t.size, 5)
    got = solution.sample(traj.t[idx])
    for name in ("q", "qd", "tau", "gamma"):
        np.testing.assert_allclose(getattr(got, name), getattr(traj, name)[idx], err_msg=name)
    assert np.isnan(got.z[:, 7]).all()  # eta is undefined under piecewise-constant torques


def test_start_is_a_solution_with_a_plan_for_the_flat_optimizer(swing_up):
    with pytest.raises(ValueError, match="applies to planner optimize, not 'closed_form'"):
        cpopt.solve(SWING_UP, start=swing_up)
    with pytest.raises(ValueError, match="start must be a Solution"):
        cpopt.solve(SWING_UP, planner="optimize", start="plan.json")


def test_a_start_solution_starts_the_optimizer(swing_up):
    """The paper swing-up's closed-form plan starts the optimizer on the same motion: one
    solve of its sign, reported as such."""
    sol = cpopt.solve(SWING_UP, planner="optimize", start=swing_up)
    assert sol.status == "solved"
    assert sol.to_dict()["solver"]["search"]["method"] == "start"
