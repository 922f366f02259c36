"""The flat_mpc controller: TVLQR around a plan re-solved from the measured state."""

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

import cpopt
from cpopt.cli import main
from cpopt.closedform.trajectory import sample_at
from cpopt.io.safe_yaml import read_yaml
from cpopt.problem import ProblemError, parse_problem
from cpopt.tracking import Plant
from cpopt.tracking.mpc import FlatMPC, MPCSettings

ROOT = Path(__file__).resolve().parent.parent
FILE = ROOT / "problems" / "transfer_min_torque.yaml"


@pytest.fixture(scope="module")
def transfer():
    """transfer_min_torque solved (1 s, one phase)."""
    solution = cpopt.solve(cpopt.load(FILE))
    assert solution.status == "solved"
    return solution


def test_flat_mpc_reaches_the_goal_on_the_model_and_reports_its_replans(transfer):
    # a long deadline: the re-plans' success is under test here, not this machine's speed
    outcome = cpopt.track(transfer, controller="flat_mpc", replan_period=0.1, replan_deadline=10.0)
    summary = outcome.summary()
    assert outcome.controller == "flat_mpc" and outcome.success
    assert summary["final_cp_error"] < 1e-3  # [m]
    replans = summary["replans"]
    # measured at 0.1 .. 0.7 s, each starting a delay (0.1 s) later, at 0.2 .. 0.8 s; the
    # one measured at 0.8 s would start where the goal is NEAR_NODE away, and holds
    assert replans["count"] == 7
    assert replans["applied"] >= 4 and replans["misses"] <= 0.5
    assert 0 < replans["median_ms"] <= replans["p99_ms"]


def test_replans_that_miss_their_deadline_leave_tvlqr_on_the_plan(transfer):
    mpc = cpopt.track(transfer, controller="flat_mpc", replan_period=0.1, replan_deadline=1e-6)
    tvlqr = cpopt.track(transfer, controller="tvlqr")
    assert mpc.replans["misses"] == 1.0 and mpc.replans["applied"] == 0
    np.testing.assert_array_equal(mpc.tau, tvlqr.tau)  # the same law on the same plan
    np.testing.assert_array_equal(mpc.x, tvlqr.x)


def test_a_replan_takes_effect_after_its_delay():
    settings = MPCSettings(period=0.02, delay=0.005)
    assert settings.steps(0.001) == (20, 5) and settings.wall_deadline() == 0.005
    assert MPCSettings().steps(0.001) == (20, 20) and MPCSettings().wall_deadline() == 0.02
    assert MPCSettings(deadline=0.5).wall_deadline() == 0.5


@pytest.mark.parametrize("method", ["ipopt", "sqp"])
def test_the_tracking_block_runs_flat_mpc(tmp_path, method):
    data = read_yaml(FILE)
    data["tracking"] = {
        "controller": "flat_mpc",
        "replan_period": 0.25,
        "replan_delay": 0.01,
        "replan_deadline": 10.0,
        "replan_method": method,
    }
    file = tmp_path / "mpc.yaml"
    file.write_text(yaml.safe_dump(data))
    assert main(["solve", str(file), "--out", str(tmp_path / "out")]) == 0
    doc = json.loads((tmp_path / "out" / "transfer_min_torque" / "solution.json").read_text())
    tracking = doc["tracking"]
    assert tracking["controller"] == "flat_mpc" and tracking["success"] is True
    assert tracking["replans"]["count"] == 3  # at 0.25, 0.5, 0.75 s


@pytest.mark.parametrize(
    ("change", "path", "words"),
    [
        ({"planner": "closed_form"}, "tracking.controller", "flat_mpc re-plans with the flat"),
        ({"tracking.replan_period": 0}, "tracking.replan_period", "greater than 0"),
        ({"tracking.replan_delay": -0.01}, "tracking.replan_delay", "greater than 0"),
        ({"tracking.replan_deadline": "soon"}, "tracking.replan_deadline", "number"),
        ({"tracking.replan_method": "acados"}, "tracking.replan_method", "'ipopt' or 'sqp'"),
    ],
)
def test_bad_flat_mpc_settings_are_refused_by_key_path(change, path, words, tmp_path, capsys):
    data = read_yaml(FILE)
    data["tracking"] = {"controller": "flat_mpc"}
    for key, value in change.items():
        if key.startswith("tracking."):
            data["tracking"][key.split(".")[1]] = value
        else:
            data[key] = value
    with pytest.raises(ProblemError) as err:
        parse_problem(data, "mpc.yaml")
    assert err.value.path == path and words in err.value.message
    file = tmp_path / "bad.yaml"
    file.write_text(yaml.safe_dump(data))
    assert main(["check", str(file)]) == 2
    assert path in capsys.readouterr().err


@pytest.mark.slow
def test_benchmark_prints_replan_and_score_lines():
    """Re-plans that all miss their deadline leave flat_mpc tvlqr's figures, plant by plant."""
    done = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "robustness.py"),
         "--plans", "transfer_min_torque", "--controllers", "tvlqr,flat_mpc", "--trials", "2",
         "--steps", "2", "--score-values", "2", "--headroom", "0", "--replan-deadline", "1e-6"],
        capture_output=True,
        text=True,
        timeout=900,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    lines = done.stdout.splitlines()
    robust = [ln.split(" ", 3)[3] for ln in lines if ln.startswith("ROBUST ")]
    assert len(robust) == 2 and robust[0] == robust[1]
    (replan,) = [ln for ln in lines if ln.startswith("REPLAN ")]
    assert re.fullmatch(
        r"REPLAN transfer_min_torque median_ms=\d+\.\d p99_ms=\d+\.\d misses=1\.000"
        r" feasible=0\.000",
        replan,
    )
    scores = [ln.split(" ", 3) for ln in lines if ln.startswith("SCORE ")]
    assert [s[2] for s in scores] == ["tvlqr", "flat_mpc"] and scores[0][3] == scores[1][3]
    assert re.fullmatch(
        r"model=[01]\.\d{3} velocity_noise=[01]\.\d{3} torque_noise=[01]\.\d{3} gain=[01]\.\d{3} "
        r"delay=[01]\.\d{3} "
        r"overall=[01]\.\d{3}",
        scores[0][3],
    )


@pytest.mark.parametrize("predict", [True, False])
def test_a_replan_starts_where_the_arm_is_when_it_takes_effect(transfer, predict):
    """On the model, no noise: the state predicted over the delay is the arm's own, so each
    applied re-plan starts exactly where the arm is when it takes over; re-planned from the
    measured state instead, it starts where the arm was a delay earlier."""
    settings = MPCSettings(period=0.1, deadline=10.0, predict=predict)
    mpc = FlatMPC(transfer.problem, transfer.plan, 1000.0, settings)
    run = mpc.run(Plant(transfer.plan.arm).parameters())
    solved = [r for r in run.replans if r.solved]
    assert len(solved) >= 4
    errors = []
    for r in solved:
        k = round(r.t / mpc.period) + (0 if predict else 100)  # where it takes effect
        start = sample_at(r.plan, [r.t], r.samples)
        errors.append(np.abs(np.r_[run.x[k, :3] - start.q[0], run.x[k, 3:] - start.qd[0]]))
    worst = np.max(errors)
    if predict:
        assert worst < 1e-9  # [rad, rad/s], measured 3e-14
    else:
        assert worst > 0.1  # measured 3.5 (a 0.1 s delay)
