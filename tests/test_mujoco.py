"""The MuJoCo plant (``tracking.plant.engine: mujoco``) against cpopt's dynamics and built-in
plant.

Measured: MuJoCo's mass matrix (``mj_fullM``), bias forces and ``mj_inverse`` agree with cpopt's
to 9e-14 at random states on all four kinds; tracked on both engines (RK4 at 0.5 ms each), the
bundled plans' joint states agree to 1.3e-12 and their final CP errors to 5e-15 m, with
friction, saturation and noise as well.
"""

from __future__ import annotations

from dataclasses import replace

import mujoco
import numpy as np
import pytest
from conftest import PROBLEMS

import cpopt
from cpopt.model.dynamics import arm_dynamics
from cpopt.model.mujoco_arm import MAX_TIMESTEP, arm_model, arm_state, mass_matrix, steps_per_period
from cpopt.model.robot import Link
from cpopt.problem import ProblemError, load_problem
from cpopt.tracking import Noise, Plant, track

KINDS = {
    "RRR": "paper_swing_up",
    "RPR": "rpr_transfer",
    "PRR": "prr_swing_up",
    "PPR": "ppr_transfer",
}


def _states(kind: str, count: int = 25, seed: int = 1):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        q, qd, qdd = rng.normal(scale=2.0, size=(3, 3))
        if kind == "RPR":
            q[1] = 0.3 + abs(q[1])
        yield q, qd, qdd


@pytest.mark.parametrize("kind", list(KINDS))
def test_mass_matrix_bias_and_inverse_dynamics_agree(kind):
    arm = load_problem(PROBLEMS / f"{KINDS[kind]}.yaml").arm
    dyn = arm_dynamics(arm)
    model = arm_model(arm)
    data = mujoco.MjData(model)
    for q, qd, qdd in _states(kind):
        arm_state(model, data, q, qd)
        mujoco.mj_forward(model, data)
        assert np.abs(mass_matrix(model, data) - np.asarray(dyn["B"](q))).max() < 1e-12
        assert np.abs(data.qfrc_bias - np.asarray(dyn["n"](q, qd)).ravel()).max() < 1e-12
        data.qacc[:] = qdd
        mujoco.mj_inverse(model, data)
        expected = np.asarray(dyn["inverse"](q, qd, qdd)).ravel()
        assert np.abs(data.qfrc_inverse - expected).max() < 1e-12


def test_the_model_is_rk4_without_contacts_at_half_a_millisecond():
    model = arm_model(load_problem(PROBLEMS / "paper_swing_up.yaml").arm, 1e-3 / 2)
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
    assert model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT
    assert model.opt.timestep == 5e-4
    assert model.nu == 2 and model.nv == 3
    assert steps_per_period(1e-3) == 2  # 1 kHz: 0.5 ms, the built-in plant's RK4 substeps
    assert steps_per_period(4e-3) == 4  # 250 Hz: 1 ms
    assert 4e-3 / steps_per_period(4e-3) <= MAX_TIMESTEP


def test_a_free_swinging_passive_link_keeps_its_energy():
    """RK4 at 0.5 ms: the energy of a swinging third link (joints 1, 2 held by the motors' zero
    torque, all joints free) drifts by less than 1e-9 of its swing in 2 s."""
    arm = load_problem(PROBLEMS / "paper_swing_up.yaml").arm
    model = arm_model(arm)
    data = mujoco.MjData(model)
    arm_state(model, data, [-np.pi / 2, 0.0, 1.0])
    energy = arm_dynamics(arm)["energy"]

    def total():
        return float(sum(np.asarray(e).item() for e in energy(data.qpos[:3], data.qvel[:3])))

    start = total()
    for _ in range(4000):
        mujoco.mj_step(model, data)
    assert abs(total() - start) < 1e-9 * arm.links[2].mass * arm.gravity * arm.links[2].d


@pytest.mark.parametrize("name", ["paper_swing_up", "swing_up_min_torque", "prr_swing_up"])
@pytest.mark.parametrize("controller", ["tvlqr", "dfl"])
def test_a_tracked_plan_ends_the_same_on_both_engines(name, controller):
    plan = cpopt.solve(load_problem(PROBLEMS / f"{name}.yaml")).plan
    builtin = track(plan, controller)
    on_mujoco = track(plan, controller, engine="mujoco")
    assert abs(builtin.final.cp[0] - on_mujoco.final.cp[0]) < 1e-4  # measured 5e-15 m
    assert np.abs(builtin.x - on_mujoco.x).max() < 1e-9  # measured 1.3e-12
    assert builtin.success == on_mujoco.success


def test_friction_saturation_gains_and_noise_are_the_built_in_plants():
    plan = cpopt.solve(load_problem(PROBLEMS / "swing_up_torque_limited.yaml")).plan
    arm = plan.arm
    plant = Plant(
        replace(arm, links=(arm.links[0], Link(1.5, 1.1), arm.links[2])),
        viscous=(0.5, 0.3, 0.01),
        coulomb=(1.0, 0.5, 0.02),
        torque_limit=(110.0, 45.0),
        gain=(0.95, 1.05),
    )
    noise = Noise((1e-4,) * 3, (1e-2,) * 3, seed=3)
    for controller in ("tvlqr", "tvlqr_timescaled"):
        builtin = track(plan, controller, plant, noise)
        on_mujoco = track(plan, controller, plant, noise, engine="mujoco")
        assert builtin.saturated.mean() > 0.1  # the limits act
        assert np.array_equal(builtin.saturated, on_mujoco.saturated)
        assert np.abs(builtin.x - on_mujoco.x).max() < 1e-9  # measured 1.4e-14
        assert mujoco.get_mjcb_passive() is None  # the friction callback is removed after


def test_a_problem_tracks_on_mujoco_when_its_file_says_so(tmp_path):
    text = (PROBLEMS / "paper_swing_up.yaml").read_text()
    path = tmp_path / "p.yaml"
    path.write_text(text + "tracking:\n  controller: dfl\n  plant: {engine: mujoco}\n")
    solution = cpopt.solve(load_problem(path))
    reference = cpopt.solve(load_problem(PROBLEMS / "paper_swing_up.yaml"))
    builtin = track(reference.plan, "dfl")
    assert solution.tracking.final.cp[0] == pytest.approx(builtin.final.cp[0], abs=1e-12)


def test_without_mujoco_the_engine_is_refused_by_key_path(tmp_path, monkeypatch):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a: None if name == "mujoco" else real(name, *a)
    )
    text = (PROBLEMS / "paper_swing_up.yaml").read_text()
    path = tmp_path / "p.yaml"
    path.write_text(text + "tracking:\n  plant: {engine: mujoco}\n")
    with pytest.raises(ProblemError) as err:
        load_problem(path)
    assert err.value.path == "tracking.plant.engine"
    assert "pip install 'cpopt[mujoco]'" in err.value.message
