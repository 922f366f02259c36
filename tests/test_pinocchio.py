"""cpopt's dynamics against Pinocchio's (an outside, independent implementation: recursive
Newton-Euler on the URDF's kinematic tree), built from the arm's URDF export.

Measured: mass matrix, bias, gravity and RNEA agree to 2e-14 at random states on all four kinds;
along every bundled plan the passive joint's torque by Pinocchio's RNEA on ``Solution.sample``'s
exact q, qd, qdd is at most 2.3e-14 N m, and the actuated torques agree with the plan's to 3.4e-13
N m (peaks 26 to 1039 N m).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from conftest import PROBLEMS

import cpopt
from cpopt.model.dynamics import arm_dynamics
from cpopt.problem import bundled_problems, load_problem
from cpopt.urdf import read_urdf, urdf_arm

KINDS = {
    "RRR": "paper_swing_up",
    "RPR": "rpr_transfer",
    "PRR": "prr_swing_up",
    "PPR": "ppr_transfer",
}
TOLERANCE = 1e-10
"""Agreement asked of the dynamics at random states [N m, N, kg m^2]; measured 2e-14."""


def pinocchio_model(urdf: str, gravity: float) -> tuple[pin.Model, pin.Data]:
    """Pinocchio's model of a URDF document, gravity along -z [m/s^2]."""
    model = pin.buildModelFromXML(urdf)
    model.gravity.linear = np.array([0.0, 0.0, -gravity])
    return model, model.createData()


def configuration(model: pin.Model, q) -> np.ndarray:
    """Pinocchio's configuration of joint coordinates q: a continuous joint is (cos q, sin q)."""
    parts = [
        [np.cos(v), np.sin(v)] if joint.nq == 2 else [v]
        for joint, v in zip(list(model.joints)[1:], q, strict=True)
    ]
    return np.concatenate(parts)


def _states(kind: str, count: int = 25, seed: int = 0):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        q, qd, qdd = rng.normal(scale=2.0, size=(3, 3))
        if kind == "RPR":
            q[1] = 0.3 + abs(q[1])  # the extension, > 0
        yield q, qd, qdd


@pytest.mark.parametrize("kind", list(KINDS))
def test_mass_matrix_bias_gravity_and_rnea_agree(kind):
    problem = load_problem(PROBLEMS / f"{KINDS[kind]}.yaml")
    model, data = pinocchio_model(problem.to_urdf(), problem.arm.gravity)
    assert model.nv == 3
    dyn = arm_dynamics(problem.arm)
    for q, qd, qdd in _states(kind):
        c = configuration(model, q)
        M = pin.crba(model, data, c)
        M = np.triu(M) + np.triu(M, 1).T  # crba fills the upper triangle only
        assert np.abs(M - np.asarray(dyn["B"](q))).max() < TOLERANCE
        bias = pin.nonLinearEffects(model, data, c, qd)
        assert np.abs(bias - np.asarray(dyn["n"](q, qd)).ravel()).max() < TOLERANCE
        gravity = pin.computeGeneralizedGravity(model, data, c)
        assert np.abs(gravity - np.asarray(dyn["g"](q)).ravel()).max() < TOLERANCE
        tau = pin.rnea(model, data, c, qd, qdd)
        assert np.abs(tau - np.asarray(dyn["inverse"](q, qd, qdd)).ravel()).max() < TOLERANCE


def test_a_cad_style_file_has_cpopts_dynamics_in_its_own_coordinates():
    """The bundled CAD-style URDF read by Pinocchio as written (hanging links, a reversed elbow,
    a massive mount): with q_urdf = sign (q - offset) its torques are sign times cpopt's."""
    path = PROBLEMS / "arms/rrr_hanging.urdf"
    found = urdf_arm(read_urdf(path))
    problem = load_problem(PROBLEMS / "urdf_swing_up.yaml")
    model, data = pinocchio_model(path.read_text(), problem.arm.gravity)
    sign, offset = np.array(found.sign), np.array(found.offset)
    dyn = arm_dynamics(problem.arm)
    for q, qd, qdd in _states("RRR"):
        c = configuration(model, sign * (q - offset))
        tau = pin.rnea(model, data, c, sign * qd, sign * qdd)
        expected = sign * np.asarray(dyn["inverse"](q, qd, qdd)).ravel()
        assert np.abs(tau - expected).max() < TOLERANCE


@pytest.mark.slow
@pytest.mark.parametrize("path", bundled_problems(), ids=lambda p: p.stem)
def test_the_passive_joint_is_torque_free_along_every_bundled_plan(path):
    problem = load_problem(path)
    solution = cpopt.solve(problem)
    assert solution.ok
    model, data = pinocchio_model(problem.to_urdf(), problem.arm.gravity)
    sample = solution.sample(np.linspace(0.0, solution.plan.duration, 501))
    tau = np.array(
        [
            pin.rnea(model, data, configuration(model, q), qd, qdd)
            for q, qd, qdd in zip(sample.q, sample.qd, sample.qdd, strict=True)
        ]
    )
    peak = np.abs(sample.tau).max()
    assert np.abs(tau[:, 2]).max() < 1e-12 * peak  # measured below 1e-15 of the peak
    assert np.abs(tau[:, :2] - sample.tau).max() < 1e-12 * peak
