"""The re-plan's condensed SQP (cpopt.flatopt.replan_sqp)."""

from pathlib import Path

import numpy as np
import pytest

import cpopt
from cpopt.closedform.trajectory import sample, sample_at
from cpopt.flatopt.replan import replan
from cpopt.flatopt.replan_sqp import convexified
from cpopt.verify.simulate import simulate_open_loop

ROOT = Path(__file__).resolve().parent.parent


def face_minimiser(H: np.ndarray, g: np.ndarray, A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """argmin 1/2 d'Hd + g'd subject to A d = b (the KKT system)."""
    n, m = H.shape[0], A.shape[0]
    K = np.block([[H, A.T], [A, np.zeros((m, m))]])
    return np.linalg.solve(K, np.r_[-g, b])[:n]


def test_convexified_keeps_the_minimiser_on_the_active_face():
    rng = np.random.default_rng(3)
    n = 5
    A = rng.normal(size=(2, n))
    Z = np.linalg.svd(A)[2][2:].T  # the face's directions
    # positive on the face (eigenvalues 0.2 .. 4), strongly negative off it
    H = Z @ np.diag([0.2, 1.0, 4.0]) @ Z.T - 1e3 * A.T @ A
    scale = np.array([1.0, 10.0, 1e4, 1.0, 0.5])
    convex = convexified(H, scale, A)
    assert np.linalg.eigvalsh(convex * np.outer(scale, scale)).min() > 0
    g, b = rng.normal(size=n), rng.normal(size=2)
    exact = face_minimiser(H, g, A, b)
    assert np.allclose(face_minimiser(convex, g, A, b), exact, rtol=1e-6, atol=1e-9)
    # without the face, a shift: positive definite, the face's minimiser moved
    shifted = convexified(H, scale)
    assert np.linalg.eigvalsh(shifted * np.outer(scale, scale)).min() > 0


@pytest.fixture(scope="module")
def transfer():
    solution = cpopt.solve(cpopt.load(ROOT / "problems" / "transfer_min_torque.yaml"))
    return solution, sample(solution.plan)


@pytest.mark.parametrize("t", [0.1, 0.3])
def test_the_sqp_finds_ipopts_optimum(transfer, t):
    """From the plan's perturbed state, the compensator held: the same optimum (measured
    within 1e-9 relative, in 7 and 5 SQP iterations against Ipopt's 11 and 16; Ipopt's own
    tolerance is 1e-6)."""
    solution, seed = transfer
    now = sample_at(solution.plan, [t], seed)
    q = now.q[0] + np.array([0.002, -0.001, 0.003])  # [rad]
    qd = now.qd[0] + np.array([0.01, 0.0, -0.02])  # [rad/s]
    runs = {
        method: replan(solution.problem, solution.plan, t, q, qd, seed=seed,
                       free_compensator=False, method=method)
        for method in ("ipopt", "sqp")
    }  # fmt: skip
    assert all(r.status == "solved" for r in runs.values())
    assert runs["sqp"].objective == pytest.approx(runs["ipopt"].objective, rel=1e-6)
    assert runs["sqp"].iterations <= 12


def test_an_sqp_stopped_early_returns_its_best_feasible_iterate(transfer):
    """Cut at one iteration, the SQP's iterate keeps every row: a ``feasible`` re-plan, followed
    like a solved one, from the measured state to the goal, 2.8 % above the optimum (measured:
    74222 against 72211; the start, no iteration, 81075)."""
    solution, seed = transfer
    t = 0.1
    now = sample_at(solution.plan, [t], seed)
    q = now.q[0] + np.array([0.002, -0.001, 0.003])  # [rad]
    qd = now.qd[0] + np.array([0.01, 0.0, -0.02])  # [rad/s]
    runs = {
        limit: replan(solution.problem, solution.plan, t, q, qd, seed=seed,
                      free_compensator=False, method="sqp", iterations=limit)
        for limit in (0, 1, None)
    }  # fmt: skip
    optimum, cut = runs[None], runs[1]
    assert optimum.status == "solved"
    assert cut.status == "feasible" and cut.usable and not cut.solved and not cut.kept_previous
    assert cut.message == "SQP_Feasible_Iterate" and cut.iterations == 1
    assert optimum.objective < cut.objective < 1.04 * optimum.objective
    assert cut.objective < runs[0].objective  # the start, itself feasible here
    start = sample_at(cut.plan, [t], sample(cut.plan))
    assert np.allclose(start.q[0], q, atol=1e-10) and np.allclose(start.qd[0], qd, atol=1e-10)
    assert simulate_open_loop(cut.plan).final_state_error < 1e-8  # [m, rad, m/s, rad/s]
