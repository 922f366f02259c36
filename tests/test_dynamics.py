"""Lagrangian dynamics of the four arm kinds."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from cpopt.model.dynamics import arm_dynamics, holding_torque, inverse_dynamics
from cpopt.model.kinematics import forward_pose, kinematic_functions
from cpopt.model.robot import Arm, Link, paper_arm

ARMS = [
    paper_arm((10, 5, 1)),
    Arm("RPR", (Link(1.2, 2), Link(1.0, 1, com=0.3), Link(0.8, 0.5, inertia=0.05))),
    Arm("PRR", (Link(0.5, 2), Link(1.0, 1), Link(0.6, 0.3))),
    Arm("PPR", (Link(0.5, 2), Link(0.5, 1), Link(1, 1))),
]
Q = np.array([0.4, 0.9, -0.6])
QD = np.array([0.7, -0.3, 1.1])


@pytest.mark.parametrize("arm", ARMS, ids=lambda a: a.kind)
def test_inertia_matrix_is_symmetric_positive_definite(arm):
    B = np.asarray(arm_dynamics(arm)["B"](Q))
    np.testing.assert_allclose(B, B.T, atol=1e-12)
    assert np.linalg.eigvalsh(B).min() > 1e-3


@pytest.mark.parametrize("arm", ARMS, ids=lambda a: a.kind)
def test_unforced_motion_conserves_energy(arm):
    """With tau = 0 the total energy is constant: checks the Coriolis and gravity terms."""
    fns = arm_dynamics(arm)

    def rhs(t, x):
        return np.concatenate([x[3:], np.asarray(fns["forward"](x[:3], x[3:], [0, 0])).ravel()])

    sol = solve_ivp(rhs, (0, 1.0), np.concatenate([Q, QD]), rtol=1e-11, atol=1e-11, method="DOP853")
    energy = [float(sum(fns["energy"](x[:3], x[3:]))) for x in sol.y.T]
    assert np.ptp(energy) < 1e-7 * max(1.0, abs(energy[0]))


@pytest.mark.parametrize("arm", ARMS, ids=lambda a: a.kind)
def test_track_gives_requested_base_acceleration_with_free_passive_joint(arm):
    fns = arm_dynamics(arm)
    a = np.array([1.3, -0.7])
    qdd, tau = (np.asarray(v).ravel() for v in fns["track"](Q, QD, a))
    torques = inverse_dynamics(arm, Q[None], QD[None], qdd[None])[0]
    np.testing.assert_allclose(torques[:2], tau, atol=1e-10)
    assert abs(torques[2]) < 1e-10
    kin = kinematic_functions(arm)
    J = np.asarray(kin["jacobian"](Q))
    acc = J @ qdd + np.asarray(kin["jdot_qdot"](Q, QD)).ravel()
    np.testing.assert_allclose(acc[:2], a, atol=1e-10)
    np.testing.assert_allclose(np.asarray(fns["forward"](Q, QD, tau)).ravel(), qdd, atol=1e-9)


def test_reduced_model_3_holds_for_the_full_arm():
    """theta_ddot = (sin a_x - cos (a_y + g0)) / K whenever the passive joint is torque-free."""
    arm = paper_arm((10, 5, 1))
    fns = arm_dynamics(arm)
    kin = kinematic_functions(arm)
    a = np.array([2.0, 0.5])
    qdd, _ = (np.asarray(v).ravel() for v in fns["track"](Q, QD, a))
    acc = np.asarray(kin["jacobian"](Q)) @ qdd + np.asarray(kin["jdot_qdot"](Q, QD)).ravel()
    th = forward_pose(arm, Q)[2]
    expected = (np.sin(th) * a[0] - np.cos(th) * (a[1] + arm.gravity)) / arm.K
    assert abs(acc[2] - expected) < 1e-10


def test_holding_torque_of_paper_arm_with_vertical_link():
    arm = paper_arm((10, 5, 1))
    q = np.array([np.pi / 2, 0.0, 0.0])  # straight up: no gravity torque on any joint
    np.testing.assert_allclose(holding_torque(arm, q), [0.0, 0.0], atol=1e-12)
    q = np.array([0.0, 0.0, np.pi / 2])  # links 1-2 horizontal, link 3 up
    # tau1 = g (m1 l1/2 + m2 (l1 + l2/2) + m3 (l1 + l2)), tau2 = g (m2 l2/2 + m3 l2)
    expected = 9.81 * np.array([10 * 0.75 + 5 * 2.25 + 1 * 3.0, 5 * 0.75 + 1 * 1.5])
    np.testing.assert_allclose(holding_torque(arm, q), expected, rtol=1e-12)


def test_cp_distance_of_uniform_rod():
    assert abs(paper_arm((1, 1, 0.5)).K - 2 / 3) < 1e-15
