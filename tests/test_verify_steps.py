"""The verification's compiled steps: the parametric right-hand sides equal the numeric arm's
maps, a padded piece steps as its own degree does, and the cache serves every arm of a kind."""

from dataclasses import replace

import casadi as ca
import numpy as np
import pytest

from cpopt.flatopt.samples import TAU, arm_vector, sample_library
from cpopt.model.dynamics import arm_dynamics
from cpopt.problem import load_problem
from cpopt.tracking.dfl import dfl_law, pole_placement_gains
from cpopt.verify.extrapolation import extrapolated_step
from cpopt.verify.verify_steps import (
    closed_loop_rhs,
    jet,
    library_degree,
    open_loop_rhs,
    step_function,
)

RNG = np.random.default_rng(7)


def _arm(name: str):
    return load_problem(f"problems/{name}.yaml").arm


def _piece(degree: int):
    return RNG.uniform(-1, 1, (degree + 1, 2)) * 0.3


@pytest.mark.parametrize("name", ["paper_swing_up", "rpr_transfer", "ppr_transfer"])
def test_the_parametric_closed_loop_is_the_numeric_arms(name):
    """Against the controller's law and the plant's forward dynamics of the numeric arms (a
    heavier plant): equal to 1e-9 relative at random states."""
    model = _arm(name)
    heavier = tuple(replace(link, mass=1.1 * link.mass) for link in model.links)
    plant = replace(model, links=heavier)
    rhs = closed_loop_rhs(model.kind, 7)
    gains = pole_placement_gains((-10, -10, -10, -10))
    lam, h, c = ca.SX.sym("lam"), ca.SX.sym("h"), ca.SX.sym("c", 8, 2)
    pd = ca.Function("pd", [lam, h, c], [jet(lam, h, c)])
    for _ in range(3):
        X = np.r_[RNG.uniform(0.2, 1.0, 3), RNG.uniform(-1, 1, 3), RNG.uniform(5, 15), 0.0]
        c0, lam0 = _piece(7), 0.4
        got = np.asarray(rhs(X, lam0, 0.8, c0, gains, arm_vector(model), arm_vector(plant)))
        tau, c_dot = dfl_law(model)(X[:3], X[3:6], X[6:], pd(lam0, 0.8, c0), gains)
        qdd = arm_dynamics(plant)["forward"](X[:3], X[3:6], tau)
        want = np.r_[X[3:6], np.ravel(qdd), np.ravel(c_dot)]
        assert np.allclose(got.ravel(), want, rtol=1e-9, atol=1e-9)


def test_the_parametric_open_loop_uses_the_sample_librarys_torques():
    model = _arm("paper_transfer")
    rhs = open_loop_rhs(model.kind, 7)
    lam, h, c = ca.SX.sym("lam"), ca.SX.sym("h"), ca.SX.sym("c", 8, 2)
    pd = ca.Function("pd", [lam, h, c], [jet(lam, h, c)])
    c0 = np.zeros((8, 2))
    c0[0] = (1.0, 1.2)  # a CP at rest at a reachable point: gamma = g0 > 0
    x = np.r_[0.4, 0.3, -0.2, 0.1, -0.2, 0.3]
    got = np.asarray(rhs(x, 0.5, 1.0, c0, 1.0, arm_vector(model), arm_vector(model))).ravel()
    y = sample_library(model.kind).functions["sample"](pd(0.5, 1.0, c0), 1.0, arm_vector(model))
    qdd = arm_dynamics(model)["forward"](x[:3], x[3:], np.asarray(y)[TAU])
    assert np.allclose(got, np.r_[x[3:], np.ravel(qdd)], rtol=1e-10, atol=1e-10)


def test_a_padded_piece_steps_as_its_own_degree():
    """A degree-7 piece through the compiled degree-9 step: the interpreted degree-7 step's
    state to 1e-12."""
    model = _arm("paper_swing_up")
    assert library_degree(7) == 9 and library_degree(30) is None
    own = extrapolated_step(closed_loop_rhs(model.kind, 7))
    padded = step_function("closed_loop", model.kind, 7)
    c0 = _piece(7)
    gains = pole_placement_gains((-10, -10, -10, -10))
    X = np.r_[0.5, 0.6, 0.7, 0.1, 0.0, -0.1, 9.0, 0.0]
    tail = np.r_[gains, arm_vector(model), arm_vector(model)]
    v_own = np.r_[X, 0.2, 0.05, 0.9, np.ravel(c0, order="F"), tail]
    c9 = np.vstack([c0, np.zeros((2, 2))])
    v_padded = np.r_[X, 0.2, 0.05, 0.9, np.ravel(c9, order="F"), tail]
    assert np.allclose(np.asarray(padded(v_padded)), np.asarray(own(v_own)), rtol=0, atol=1e-12)


def test_one_library_serves_every_arm_of_a_kind():
    assert step_function("open_loop", "RRR", 8) is step_function("open_loop", "RRR", 9)
    assert step_function("reduced", "RRR", 7) is step_function("reduced", "PPR", 7)
