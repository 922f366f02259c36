"""tvlqr_timescaled: TVLQR around the plan re-timed online to fit the motors' torque limits."""

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

import cpopt
from cpopt.cli import main
from cpopt.problem import ProblemError, load_problem
from cpopt.tracking import Plant, track
from cpopt.tracking.reference import reference
from cpopt.tracking.robustness import benchmark_plant, run_trials
from cpopt.tracking.run import make_controller
from cpopt.tracking.simulation import Noise, simulate_batch
from cpopt.tracking.timescaled import TimeScaledTVLQR

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def transfer(paper_solutions):
    """The paper's T = 1 s transfer (closed form) and its 1 kHz reference."""
    plan = paper_solutions["paper_transfer"].plan
    return plan, reference(plan, 1000.0)


@pytest.fixture(scope="module")
def torque_limited():
    """The torque-limited swing-up (|tau1| <= 120 N m, |tau2| <= 50 N m), solved."""
    solution = cpopt.solve(ROOT / "problems" / "swing_up_torque_limited.yaml")
    assert solution.status == "solved"
    return solution


def test_on_the_model_it_is_tvlqr(transfer):
    """Motors at 1.5 x the plan's peak on the model itself: the torque always fits, the rate
    stays 1 and the runs are TVLQR's to round-off (both 8.3e-7 m from the plan)."""
    plan, ref = transfer
    limit = tuple(1.5 * np.abs(ref.tau).max(axis=0))
    plant = Plant(plan.arm, torque_limit=limit)
    lqr = track(None, make_controller("tvlqr", ref), plant)
    scaled = track(plan, "tvlqr_timescaled", plant)
    assert scaled.controller == "tvlqr_timescaled" and scaled.success
    assert scaled.max_cp_error < 1e-4
    assert abs(scaled.max_cp_error - lqr.max_cp_error) < 1e-12
    np.testing.assert_allclose(scaled.tau, lqr.tau, rtol=1e-9, atol=1e-9)
    assert scaled.t.size == lqr.t.size == ref.t.size
    assert scaled.delay == pytest.approx(0, abs=1e-12) and scaled.max_lag < 1e-12


def test_the_torque_interface_starts_with_tvlqrs_feed_forward(transfer):
    _, ref = transfer
    controller = TimeScaledTVLQR(ref, (1000.0, 200.0))
    tau = controller.torque(0.0, ref.x[0, :3], ref.x[0, 3:])
    np.testing.assert_allclose(tau, ref.tau_mean[0], rtol=1e-12)
    with pytest.raises(ValueError, match="torque_limit"):
        TimeScaledTVLQR(ref, (1000.0, 0.0))


def _hidden_plant(solution, heavier: float):
    """The benchmark plant (friction, noise) at the problem's limits, links 1 and 2 heavier."""
    ref = reference(solution.plan, 500.0)
    plant, noise = benchmark_plant(ref, (120.0, 50.0))
    values = plant.parameters()
    values[[1, 3, 5, 7]] *= 1 + heavier  # masses and inertias of links 1 and 2
    return ref, plant.with_parameters(values), noise


def test_slowing_down_keeps_a_swing_up_that_tvlqr_loses(torque_limited):
    """500 Hz, links 1 and 2 20 % heavier, motors at 120 and 50 N m, friction, noise (seed 0):
    TVLQR saturates 15 % of the time and ends with a joint at 0.267 rad/s (tolerance 0.25);
    tvlqr_timescaled falls 0.6 ms behind by t = 1 s, has caught up by 1.4 s, falls behind again
    on the final swing and reaches the goal 6 ms after T with the joints at 0.19 rad/s."""
    ref, plant, noise = _hidden_plant(torque_limited, 0.2)
    lqr = track(None, make_controller("tvlqr", ref), plant, noise)
    scaled = track(torque_limited.plan, "tvlqr_timescaled", plant, noise, rate_hz=500.0)
    assert not lqr.success and lqr.saturated.mean() == pytest.approx(0.149, abs=0.02)
    assert lqr.final.joint_velocity[0] == pytest.approx(0.267, abs=0.01)
    assert scaled.success and scaled.final.joint_velocity[0] == pytest.approx(0.19, abs=0.02)
    lag = scaled.t - scaled.progress
    at = {t: lag[np.searchsorted(scaled.t, t)] for t in (1.0, 1.4)}
    assert at[1.0] == pytest.approx(0.6e-3, abs=2e-4)
    assert at[1.4] < 0.5 * at[1.0]  # caught up
    assert scaled.delay == pytest.approx(0.006, abs=0.0021)
    assert scaled.t[-1] == pytest.approx(ref.t[-1] + scaled.delay)
    assert scaled.summary()["delay"] == scaled.delay and scaled.summary()["max_lag"] >= 0.006
    # the reference the controller tracked is the plan's CP at its progress
    np.testing.assert_allclose(scaled.cp_ref[-1], ref.cp[-1, :, 0], atol=1e-12)


def test_a_run_that_does_not_arrive_in_its_extra_time_fails(torque_limited):
    """Without extra time (max_delay = 0) the same run ends at T with its reference behind the
    goal: judged there, it fails, and says it did not arrive."""
    ref, plant, noise = _hidden_plant(torque_limited, 0.2)
    late = make_controller("tvlqr_timescaled", ref, torque_limit=plant.torque_limit, max_delay=0)
    out = track(None, late, plant, noise)
    assert out.t[-1] == pytest.approx(ref.t[-1]) and not out.arrived and not out.success
    assert out.delay > 0 and out.progress[-1] < ref.t[-1]


def test_compiled_batches_run_as_single_runs(torque_limited):
    """The law's interpolant compiles with the period function: a compiled batch of three
    plants gives each run's arrival and end state as the interpreted single runs."""
    ref, plant, _ = _hidden_plant(torque_limited, 0.0)
    controller = make_controller("tvlqr_timescaled", ref, torque_limit=plant.torque_limit)
    rows = []
    for e in (0.0, 0.2, 0.25):
        values = plant.parameters()
        values[[1, 3, 5, 7]] *= 1 + e
        rows.append(values)
    batch = simulate_batch(controller, np.array(rows), Noise(), jit=True)
    for i, values in enumerate(rows):
        alone = track(None, controller, plant.with_parameters(values))
        assert batch.arrival[i] == pytest.approx(alone.t[-1], abs=1e-9)
        np.testing.assert_allclose(batch.x_final[i], alone.x[-1], rtol=1e-7, atol=1e-9)
    assert batch.arrival[2] > batch.arrival[0]  # the heavier plant arrives later
    trials = run_trials(controller, np.array(rows), Noise())
    np.testing.assert_allclose(trials.delay, batch.arrival - ref.t[-1], atol=1e-12)


def test_the_yaml_block_and_the_api_take_the_controller(torque_limited, tmp_path, capsys):
    data = yaml.safe_load((ROOT / "problems" / "swing_up_torque_limited.yaml").read_text())
    data["tracking"] = {"controller": "tvlqr_timescaled", "rate_hz": 500}
    file = tmp_path / "scaled.yaml"
    file.write_text(yaml.safe_dump(data))
    assert main(["solve", str(file), "--out", str(tmp_path / "out")]) == 0
    doc = json.loads((tmp_path / "out" / data["name"] / "solution.json").read_text())
    assert doc["tracking"]["controller"] == "tvlqr_timescaled" and doc["tracking"]["success"]
    assert doc["tracking"]["delay"] == pytest.approx(0, abs=1e-12)  # the model: no slowing
    heavier = {"links": [{"mass": 1.2}, {"mass": 1.2}, None]}
    out = cpopt.track(torque_limited, controller="tvlqr_timescaled", plant=heavier, rate_hz=500)
    assert out.controller == "tvlqr_timescaled" and out.max_cp_error < 0.05
    data["tracking"]["controller"] = "tvlqr_time_scaled"
    file.write_text(yaml.safe_dump(data))
    with pytest.raises(ProblemError) as err:
        load_problem(file)
    assert err.value.path == "tracking.controller"
    assert main(["check", str(file)]) == 2
    message = capsys.readouterr().err
    assert "tracking.controller" in message and "tvlqr_timescaled" in message
