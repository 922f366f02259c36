"""Tracking on a realistic arm: controllers, plant, sampled-data loop, YAML block, outputs."""

import json
import re
import subprocess
import sys
import textwrap
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.integrate import solve_ivp

from cpopt.cli import main
from cpopt.closedform.plan import closed_form
from cpopt.model.dynamics import arm_dynamics
from cpopt.model.robot import Link
from cpopt.problem import ProblemError, load_problem, parse_problem
from cpopt.tracking import CSV_COLUMNS, Noise, Plant, track
from cpopt.tracking.dfl import SingularTrackingError
from cpopt.tracking.plant import PARAMETER_NAMES, plant_period
from cpopt.tracking.reference import reference
from cpopt.tracking.robustness import benchmark_plant
from cpopt.tracking.run import make_controller
from cpopt.tracking.simulation import simulate_batch
from cpopt.tracking.tvlqr import relative_R, riccati_gains

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def transfer():
    """The paper's T = 1 s transfer (closed form) on a 1 kHz grid."""
    problem = load_problem(ROOT / "problems" / "paper_transfer.yaml")
    plan = closed_form(problem.arm, problem.nodes)
    return plan, reference(plan, 1000.0)


def _heavier(arm, e):
    """Links 1 and 2 heavier by the fraction e (uniform rods: their inertias scale too)."""
    links = [Link(lk.length, lk.mass * (1 + e)) if i < 2 else lk for i, lk in enumerate(arm.links)]
    return Plant(replace(arm, links=tuple(links)))


def test_plant_period_is_the_exact_flow(transfer):
    """Two RK4 steps per 1 ms period of the parametrised plant against DOP853 on the model."""
    plan, ref = transfer
    arm = plan.arm
    x0, tau = ref.x[300], np.array([200.0, -30.0])
    step = plant_period(arm.kind, arm.base, arm.gravity, 1e-3)
    x1 = np.asarray(step(x0, tau, Plant(arm).parameters(), np.zeros(2))[0]).ravel()
    forward = arm_dynamics(arm)["forward"]

    def rhs(_t, x):
        return np.r_[x[3:], np.asarray(forward(x[:3], x[3:], tau)).ravel()]

    exact = solve_ivp(rhs, (0, 1e-3), x0, "DOP853", rtol=1e-13, atol=1e-13).y[:, -1]
    assert np.abs(x1 - exact).max() < 1e-9
    assert np.abs(x1 - x0).max() > 1e-3  # the state did move


def test_plant_parameters_round_trip(transfer):
    arm = transfer[0].arm
    plant = Plant(arm, (0.1, 0.2, 0.3), (1.0, 2.0, 3.0), (500.0, None))
    values = plant.parameters()
    assert values.shape == (len(PARAMETER_NAMES),)
    back = plant.with_parameters(values)
    np.testing.assert_allclose(back.parameters(), values)
    assert back.torque_limit == (500.0, None)
    assert pytest.approx(10.0 * 1.5**2 / 12) == back.arm.links[0].I


@pytest.mark.parametrize(("name", "bound"), [("tvlqr", 1e-5), ("dfl", 5e-5)])
def test_controllers_follow_the_plan_on_the_model(transfer, name, bound):
    """Perfect plant, no noise, 1 kHz: measured 2.9e-6 m (tvlqr) and 1.5e-5 m (dfl)."""
    _, ref = transfer
    out = track(None, make_controller(name, ref))
    assert out.max_cp_error < bound
    assert out.final.state[0] < 1e-3 and out.success
    assert out.t[-1] == pytest.approx(1.0) and out.tau.shape == (1000, 2)


def test_torque_interface_gives_the_feed_forward_on_the_plan(transfer):
    """On the plan, tvlqr applies the plan's torque averaged over the period exactly; dfl's
    midpoint law does to second order in the period (measured 2.4e-4 relative)."""
    _, ref = transfer
    for name, rtol in (("tvlqr", 1e-12), ("dfl", 1e-3)):
        controller = make_controller(name, ref)
        tau = controller.torque(0.0, ref.x[0, :3], ref.x[0, 3:])
        np.testing.assert_allclose(tau, ref.tau_mean[0], rtol=rtol)
    assert np.abs(ref.tau_mean[0] - ref.tau[0]).max() > 0.5  # the mean is not the start value


def test_tvlqr_beats_dfl_with_links_one_and_two_5_percent_heavier(transfer):
    """Measured max CP errors: tvlqr 5.9e-4 m (0.013 m with the former weights Q = 100,
    R = 3e-5), dfl 0.043 m."""
    plan, ref = transfer
    plant = _heavier(plan.arm, 0.05)
    lqr = track(None, make_controller("tvlqr", ref), plant)
    dfl = track(None, make_controller("dfl", ref), plant)
    assert lqr.max_cp_error == pytest.approx(5.9e-4, rel=0.15)
    assert dfl.max_cp_error == pytest.approx(0.0434, rel=0.15)
    assert lqr.success and not dfl.success


def test_default_tvlqr_weights_track_a_longer_arm_with_friction(transfer):
    """The benchmark plant (friction on every joint, noise, saturation at 1.5 x the plan's
    peak torques) with link 1 5 % longer: the default weights (R relative to the plan's peak
    torques) end 3.7e-4 m from the goal; the former Q = 100, R = 3e-5 end 2.3 cm off with
    the joints at 0.42 rad/s, a failure."""
    _, ref = transfer
    controller = make_controller("tvlqr", ref)
    peak = np.abs(ref.tau).max(axis=0)
    np.testing.assert_allclose(relative_R(ref), 0.2 / peak**2, rtol=1e-12)
    np.testing.assert_allclose(controller.gains[0], riccati_gains(ref, R=relative_R(ref))[0])
    plant, noise = benchmark_plant(controller)
    values = plant.parameters()
    values[0] *= 1.05  # links[0].length
    longer = plant.with_parameters(values)
    new = track(None, controller, longer, noise)
    former = (100.0, 100.0, 100.0, 1.0, 1.0, 1.0)
    old = track(
        None, make_controller("tvlqr", ref, Q=former, R=(3e-5, 3e-5), Qf=former), longer, noise
    )
    assert new.final.cp[0] == pytest.approx(3.7e-4, rel=0.3) and new.success
    assert old.final.cp[0] == pytest.approx(0.023, rel=0.15) and not old.success


def test_a_batch_runs_each_plant_as_if_alone(transfer):
    """One mapped call over different plants gives each run its own parameters."""
    plan, ref = transfer
    controller = make_controller("tvlqr", ref)
    plants = [_heavier(plan.arm, e) for e in (0.0, 0.05, -0.1)]
    batch = simulate_batch(controller, np.array([p.parameters() for p in plants]))
    alone = [track(None, controller, p).max_cp_error for p in plants]
    np.testing.assert_allclose(batch.max_cp_error, alone, rtol=1e-9)
    assert alone[2] > 1.5 * alone[1] > 1000 * alone[0]  # the plants differ


def test_the_compiled_step_is_cached_on_disk_and_runs_as_the_interpreted(
    transfer, tmp_path, monkeypatch
):
    """jit: the period function compiled once through cpopt.runtime.compiled's cache (named by the
    function itself), found again without building, and the same runs as interpreted."""
    from cpopt.runtime import compiled
    from cpopt.tracking import simulation

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    if compiled.compiler() is None:
        pytest.skip("no C compiler")
    plan, ref = transfer
    controller = make_controller("dfl", ref)  # model, gains and period are constants in it
    step = simulation.step_function(controller, jit=False)
    fast = simulation.compiled_step(step)
    libraries = list((tmp_path / "cpopt").glob("tracking-step-*.so"))
    assert len(libraries) == 1
    assert isinstance(fast, type(step)) and fast.name() == "step"
    rng = np.random.default_rng(3)
    args = [rng.standard_normal(step.size1_in(i)) for i in range(step.n_in())]
    args[4] = Plant(plan.arm).parameters()
    for slow_out, fast_out in zip(step.call(args), fast.call(args), strict=True):
        np.testing.assert_allclose(np.asarray(fast_out), np.asarray(slow_out), rtol=1e-12)
    name = simulation.library_name(step)
    assert libraries[0].name.startswith(name + "-casadi")
    found = compiled.load_library(
        name, simulation.SOURCES, lambda: pytest.fail("the cached step must be found, not built")
    )
    assert found.path == libraries[0]
    plants = np.array([_heavier(plan.arm, e).parameters() for e in (0.0, 0.1)])
    jit = simulate_batch(controller, plants, jit=True)
    interpreted = simulate_batch(controller, plants, jit=False)
    np.testing.assert_allclose(jit.max_cp_error, interpreted.max_cp_error, rtol=1e-9)
    np.testing.assert_allclose(jit.x_final, interpreted.x_final, rtol=1e-9, atol=1e-12)
    assert len(list((tmp_path / "cpopt").glob("tracking-step-*.so"))) == 1


def test_friction_noise_and_saturation_each_show(transfer):
    plan, ref = transfer
    arm = plan.arm
    clean = track(None, make_controller("tvlqr", ref))
    friction = track(None, make_controller("tvlqr", ref), Plant(arm, (10, 5, 0.01), (10, 5, 0.01)))
    assert friction.max_cp_error == pytest.approx(0.0053, rel=0.15)  # clean: 8e-7 m
    noise = Noise((1e-3,) * 3, (1e-2,) * 3, seed=1)
    noisy = track(None, make_controller("tvlqr", ref), noise=noise)
    again = track(None, make_controller("tvlqr", ref), noise=noise)
    other = track(None, make_controller("tvlqr", ref), noise=replace(noise, seed=2))
    assert noisy.max_cp_error == pytest.approx(1.26e-3, rel=0.3)
    np.testing.assert_array_equal(noisy.tau, again.tau)  # seeded
    assert np.abs(noisy.tau - other.tau).max() > 10.0
    limited = track(None, make_controller("tvlqr", ref), Plant(arm, torque_limit=(600.0, 100.0)))
    summary = limited.summary()
    assert summary["peak_torque"] == [600.0, 100.0]
    assert summary["saturated_fraction"] == pytest.approx(0.046, abs=0.005)
    assert limited.max_cp_error > 100 * clean.max_cp_error
    assert not clean.saturated.any()


def test_actuator_gain_and_torque_noise_scale_and_add_to_the_applied_torque(transfer):
    """One period of the plant: gain g on tau is gain 1 on g tau; noise w adds to it."""
    arm = transfer[0].arm
    x0, tau, w = transfer[1].x[300], np.array([200.0, -30.0]), np.array([3.0, -1.0])
    step = plant_period(arm.kind, arm.base, arm.gravity, 1e-3)
    gained = Plant(arm, gain=(0.7, 1.3)).parameters()
    a = step(x0, tau, gained, w)
    b = step(x0, np.array([0.7, 1.3]) * tau + w, Plant(arm).parameters(), np.zeros(2))
    np.testing.assert_allclose(np.asarray(a[0]), np.asarray(b[0]), rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.asarray(a[2]).ravel(), [143.0, -40.0], rtol=1e-12)
    limited = Plant(arm, torque_limit=(100.0, 100.0), gain=(0.5, 0.5)).parameters()
    saturated = np.asarray(step(x0, tau, limited, np.zeros(2))[2]).ravel()
    np.testing.assert_allclose(saturated, [50.0, -15.0])  # saturated, then the gain


def test_torque_noise_is_drawn_apart_from_the_measurement_noise():
    measured = Noise((1e-3,) * 3, (1e-2,) * 3, seed=4)
    both = replace(measured, torque=(5.0, 1.0))
    a = measured.draw(measured.generators(2), 20000)
    b = both.draw(both.generators(2), 20000)
    np.testing.assert_array_equal(a[:6], b[:6])  # adding torque noise keeps the measurements'
    assert not a[6:].any()
    np.testing.assert_allclose(b[6:].std(axis=1), [5.0, 1.0], rtol=0.03)
    np.testing.assert_allclose(b[:6].std(axis=1), measured.std, rtol=0.03)


def test_gain_delay_and_torque_noise_each_show(transfer):
    """On the model, 1 kHz (clean: 8e-7 m): an actuation delay holds the plan's initial
    torque first; measured errors 1.5e-4 m (1 ms delay), 3.6e-3 m (gains 0.8), 2.9e-4 m
    (torque noise of 50 and 10 N m, seeded)."""
    plan, ref = transfer
    arm = plan.arm
    delayed = track(None, make_controller("tvlqr", ref), Plant(arm, delay=0.003))
    np.testing.assert_array_equal(delayed.tau[:3], np.tile(ref.tau[0], (3, 1)))
    assert np.abs(delayed.tau[3] - ref.tau[0]).max() > 1.0
    late = track(None, make_controller("tvlqr", ref), Plant(arm, delay=0.001))
    assert late.max_cp_error == pytest.approx(1.5e-4, rel=0.2)
    weak = track(None, make_controller("tvlqr", ref), Plant(arm, gain=(0.8, 0.8)))
    assert weak.max_cp_error == pytest.approx(3.6e-3, rel=0.2)
    noise = Noise(torque=(50.0, 10.0), seed=1)
    shaken = track(None, make_controller("tvlqr", ref), noise=noise)
    again = track(None, make_controller("tvlqr", ref), noise=noise)
    assert shaken.max_cp_error == pytest.approx(2.9e-4, rel=0.2)
    np.testing.assert_array_equal(shaken.tau, again.tau)


@pytest.fixture(scope="module")
def collocation_plans():
    pytest.importorskip("rockit")
    from cpopt.collocation import collocate

    data = load_problem(ROOT / "benchmarks" / "problems" / "transfer.yaml").spec.model_dump()
    data["planner"] = "collocation"
    problem = parse_problem(data, "transfer", "transfer")
    return {g: collocate(problem, intervals=30, gamma_constraint=g).plan for g in (True, False)}


@pytest.mark.slow
def test_controllers_follow_a_collocation_plan(collocation_plans):
    """Piecewise-constant torques: tvlqr 7e-6 m; dfl resets its compensator at every knot
    (5e-5 m with poles -20; at -10 the resets, up to a period late, add up to centimetres)."""
    plan = collocation_plans[True]
    ref = reference(plan, 1000.0)
    assert np.count_nonzero(np.abs(ref.resets).sum(axis=1)) == 29  # the inner knots
    assert track(None, make_controller("tvlqr", ref)).max_cp_error < 2e-5
    assert track(None, make_controller("dfl", ref, poles=(-20.0,) * 4)).max_cp_error < 2e-4
    unconstrained = reference(collocation_plans[False], 1000.0)
    with pytest.raises(SingularTrackingError, match="gamma crosses zero at t = "):
        make_controller("dfl", unconstrained)
    assert track(None, make_controller("tvlqr", unconstrained)).max_cp_error < 2e-5


TRACKING = textwrap.dedent("""\
    tracking:
      controller: tvlqr
      rate_hz: 500
      Q: [100, 100, 100, 1, 1, 1]
      R: [1.0e-4, 1.0e-4]
      Qf: [100, 100, 100, 1, 1, 1]
      poles: [-10, -10, -10, -10]
      noise: {position: [1.0e-4, 1.0e-4, 1.0e-4], velocity: [0.01, 0.01, 0.01], seed: 3}
      plant:
        links: [{mass: 10.5}, null, {length: 1.0, com: 0.5, inertia: 0.08}]
        friction: {viscous: [1, 1, 0.01], coulomb: [2, 1, 0.01]}
        torque_limit: [900, 150]
        gain: [0.98, 1.02]
        delay: 0.002
        torque_noise: [1.0, 0.5]
    """)


def _data():
    """The paper's transfer with a tracking block that sets every key."""
    data = yaml.safe_load((ROOT / "problems" / "paper_transfer.yaml").read_text())
    return {**data, "name": "tracked", **yaml.safe_load(TRACKING)}


def test_the_tracking_block_builds_the_plant():
    problem = parse_problem(_data())
    from cpopt.problem import plant_links

    links = plant_links(problem.spec)
    assert links[0].mass == 10.5 and pytest.approx(10.5 * 1.5**2 / 12) == links[0].I
    assert links[1] == problem.arm.links[1]
    assert (links[2].d, links[2].I) == (0.5, 0.08)
    plant = problem.spec.tracking.plant
    assert (plant.gain, plant.delay, plant.torque_noise) == ([0.98, 1.02], 0.002, [1.0, 0.5])


@pytest.mark.parametrize(
    ("path", "value"),
    [
        ("controller", "pid"),
        ("rate_hz", 0),
        ("Q", [1, 2, 3]),
        ("Q", [1, 1, 1, 1, 1, -1]),
        ("R", [0, 1e-4]),
        ("Qf", [1, 1, 1, 1, 1]),
        ("poles", [-1, -1, -1, 1]),
        ("noise.position", [0, 0]),
        ("noise.velocity", [0, 0, -0.1]),
        ("noise.seed", -1),
        ("noise.sigma", 1),
        ("plant.links", [{}, {}]),
        ("plant.links[0].mass", 0),
        ("plant.links[0].lenght", 1),
        ("plant.links[2].com", -0.1),
        ("plant.friction.viscous", [0, 0, -1]),
        ("plant.friction.coulomb", "none"),
        ("plant.torque_limit", [100, 0]),
        ("plant.gain", [1.0, 0.0]),
        ("plant.gain", [1.0]),
        ("plant.delay", -0.001),
        ("plant.delay", 2.0),
        ("plant.torque_noise", [0.0, -1.0]),
        ("plant.torque_noise", "loud"),
        ("plant.mass", 1),
    ],
)
def test_every_tracking_key_is_validated(path, value, tmp_path, capsys):
    data = _data()
    node = data["tracking"]
    keys = re.findall(r"[^.\[\]]+|\[\d+\]", path)
    for key in keys[:-1]:
        node = node[int(key[1:-1])] if key.startswith("[") else node[key]
    last = keys[-1]
    if last.startswith("["):
        node[int(last[1:-1])] = value
    else:
        node[last] = value
    file = tmp_path / "bad.yaml"
    file.write_text(yaml.safe_dump(data))
    with pytest.raises(ProblemError) as err:
        load_problem(file)
    assert err.value.path.startswith(f"tracking.{path.split('[')[0]}")
    assert main(["check", str(file)]) == 2
    assert f"tracking.{path.split('[')[0]}" in capsys.readouterr().err


@pytest.mark.parametrize(("key", "value"), [("delay", 0.01), ("torque_noise", [1.0, 0.0])])
def test_the_mujoco_plant_refuses_delay_and_torque_noise(key, value, tmp_path, capsys):
    pytest.importorskip("mujoco")
    data = _data()
    data["tracking"]["plant"].update(engine="mujoco", delay=0.0, torque_noise=[0.0, 0.0])
    data["tracking"]["plant"][key] = value
    file = tmp_path / "bad.yaml"
    file.write_text(yaml.safe_dump(data))
    with pytest.raises(ProblemError) as err:
        load_problem(file)
    assert err.value.path == f"tracking.plant.{key}"
    assert main(["check", str(file)]) == 2
    assert f"tracking.plant.{key}" in capsys.readouterr().err


def test_dfl_on_an_unconstrained_collocation_plan_is_refused_at_load():
    data = _data()
    data.update(planner="collocation", collocation={"gamma_constraint": False})
    data["tracking"]["controller"] = "dfl"
    with pytest.raises(ProblemError, match=r"tracking\.controller: dfl needs gamma"):
        parse_problem(data, "x.yaml")


def test_solve_writes_tracking_outputs(tmp_path, capsys):
    file = tmp_path / "tracked.yaml"
    file.write_text(yaml.safe_dump(_data()))
    assert main(["solve", str(file), "--out", str(tmp_path / "out"), "--plot"]) == 0
    out = tmp_path / "out" / "tracked"
    doc = json.loads((out / "solution.json").read_text())["tracking"]
    assert set(doc) == {
        "controller", "rate_hz", "max_cp_error", "final_state_error", "final_cp_error",
        "final_theta_error_deg", "final_joint_velocity_error", "peak_torque",
        "saturated_fraction", "diverged_at", "delay", "max_lag", "success", "tolerance",
    }  # fmt: skip
    assert doc["controller"] == "tvlqr" and doc["rate_hz"] == 500 and doc["success"] is True
    assert abs(doc["delay"]) < 1e-12 and abs(doc["max_lag"]) < 1e-12  # at the plan's pace
    assert doc["tolerance"] == {"cp": 0.02, "theta_deg": 5.0, "joint_velocity": 0.25}
    assert 1e-3 < doc["max_cp_error"] < 0.02 and doc["diverged_at"] is None
    lines = (out / "tracking.csv").read_text().splitlines()
    assert tuple(lines[0].split(",")) == CSV_COLUMNS
    assert CSV_COLUMNS == (
        "t", "q1", "q2", "q3", "q1dot", "q2dot", "q3dot", "q1ddot", "q2ddot", "q3ddot",
        "tau1", "tau2", "cp_x", "cp_y", "cp_x_ref", "cp_y_ref",
    )  # fmt: skip
    table = np.loadtxt(out / "tracking.csv", delimiter=",", skiprows=1)
    assert table.shape == (500, 16)
    np.testing.assert_allclose(np.diff(table[:, 0]), 1 / 500)
    assert np.abs(table[:, 10]).max() <= 900 and np.abs(table[:, 11]).max() <= 150
    assert (out / "tracking.png").stat().st_size > 10_000


@pytest.mark.slow
def test_quick_benchmark_prints_robust_lines():
    done = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "robustness.py"), "--quick"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    lines = [ln for ln in done.stdout.splitlines() if ln.startswith("ROBUST ")]
    assert [ln.split()[1:3] for ln in lines] == [
        ["paper_transfer", "tvlqr"],
        ["paper_transfer", "tvlqr_timescaled"],
        ["paper_transfer", "dfl"],
    ]
    rates = {}
    for line in lines:
        match = re.fullmatch(
            r"ROBUST \w+ (tvlqr|tvlqr_timescaled|dfl) sweep=([01]\.\d{3}) "
            r"monte_carlo=([01]\.\d{3})",
            line,
        )
        assert match, line
        rates[match[1]] = float(match[2]), float(match[3])
    assert rates["tvlqr"] > rates["dfl"]  # measured: tvlqr 0.852 and 0.6, dfl 0 and 0


def test_a_diverging_run_stops_and_says_when():
    """The sampled dfl on the paper's swing-up with links 1 and 2 10 % heavier: the CP leaves
    the plan by more than 1 m (measured at t = 1.075 s) and the run stops there."""
    problem = load_problem(ROOT / "problems" / "paper_swing_up.yaml")
    plan = closed_form(problem.arm, problem.nodes)
    out = track(plan, "dfl", _heavier(plan.arm, 0.1))
    assert out.diverged_at == pytest.approx(1.075, abs=0.05)
    assert out.t[-1] == out.diverged_at and out.tau.shape == (out.t.size - 1, 2)
    assert out.cp_error[-1] > 1.0 and not out.success
    assert out.summary()["diverged_at"] == out.diverged_at


@pytest.mark.slow
def test_benchmark_prints_a_headroom_line_per_optimized_plan():
    done = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "robustness.py"), "--quick",
         "--plans", "paper_transfer,swing_up_torque_limited", "--headroom", "0.2",
         "--controllers", "tvlqr"],  # flat_mpc's lines: tests/test_flat_mpc.py (4 min here)
        capture_output=True,
        text=True,
        timeout=600,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    lines = [ln for ln in done.stdout.splitlines() if ln.startswith("HEADROOM ")]
    assert len(lines) == 1  # the closed-form paper_transfer has none
    match = re.fullmatch(
        r"HEADROOM swing_up_torque_limited h=0.2 cost=(\d\.\d{3}) duration=(\d\.\d{3}) "
        r"monte_carlo=([01]\.\d{3})",
        lines[0],
    )
    assert match, lines[0]
    # 20 % of 120 N m and 50 N m left to feedback: 13.5 % more torque, the same duration
    assert float(match[1]) == pytest.approx(1.135, abs=0.003)
    assert match[2] == "1.000"
    assert "ROBUST swing_up_torque_limited tvlqr " in done.stdout


def test_a_buffered_call_equals_casadis_own_call_repeated_inputs_included():
    """call_buffered (NumPy in and out through CasADi's buffer, no DM conversion) gives
    exactly the values of the function's own call, an input of one instance repeated for
    every instance of a map as CasADi repeats it."""
    import casadi as ca

    from cpopt.tracking.simulation import call_buffered

    x, u = ca.SX.sym("x", 3), ca.SX.sym("u", 2)
    f = ca.Function("f", [x, u], [ca.sin(x) * u[0] + u[1], ca.vertcat(x[0] * x[1], u[0])])
    mapped = f.map(7)
    rng = np.random.default_rng(3)
    X, U = rng.normal(size=(3, 7)), rng.normal(size=(2, 1))
    own = [np.asarray(o) for o in mapped(X, U)]
    got = call_buffered(mapped, X, U)
    assert [g.shape for g in got] == [(3, 7), (2, 7)]
    for g, o in zip(got, own, strict=True):
        np.testing.assert_array_equal(g, o)
    with pytest.raises(ValueError, match="input 1"):
        call_buffered(mapped, X, rng.normal(size=(2, 3)))


def test_a_score_measures_every_category(transfer):
    """tvlqr on the paper's transfer, 3 values a category, on the model with 1.5 x peak motors:
    a delay of 20 or 40 ms and the gains 0.5 fail it; 10 % torque noise does not."""
    from cpopt.tracking.scores import batch_judge, scores

    ref = transfer[1]
    controller = make_controller("tvlqr", ref)
    plant, _ = benchmark_plant(controller)
    nominal = Plant(plant.arm, torque_limit=plant.torque_limit).parameters()
    figures = scores(batch_judge(controller), nominal, ref.period, 3)
    expected = {"model": 30 / 36, "velocity_noise": 1.0, "torque_noise": 1.0, "gain": 2 / 3}
    assert figures == pytest.approx({**expected, "delay": 1 / 3, "overall": 0.7666667})
