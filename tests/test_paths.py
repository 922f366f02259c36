"""Paths and timing laws: the chain rule, the geometric boundary conditions, exact composition."""

import casadi as ca
import numpy as np
import pytest

from cpopt.closedform.bspline import SplineBasis
from cpopt.closedform.paths import (
    PathShape,
    chain_rule,
    compose,
    cross,
    end_conditions,
    node_mismatch,
    path_jet,
    wandering,
)

RNG = np.random.default_rng(14)


def _analytic_jets(t_value: float):
    """Y(s) = (sin 2s + s^3, e^s cos s), s(t) = 0.3 t + 0.2 t^2 + 0.1 sin 3t: the path's jet at
    s(t), the timing's jet, and y(t) = Y(s(t)) differentiated directly (CasADi AD)."""
    t, sig = ca.SX.sym("t"), ca.SX.sym("s")
    Y = ca.vertcat(ca.sin(2 * sig) + sig**3, ca.exp(sig) * ca.cos(sig))
    s = 0.3 * t + 0.2 * t**2 + 0.1 * ca.sin(3 * t)
    y = [ca.substitute(Y, sig, s)]
    Yj, sj = [Y], [s]
    for _ in range(4):
        y.append(ca.jacobian(y[-1], t))
        Yj.append(ca.jacobian(Yj[-1], sig))
        sj.append(ca.jacobian(sj[-1], t))
    f = ca.Function(
        "f", [t], [ca.substitute(ca.horzcat(*Yj), sig, s), ca.vertcat(*sj), ca.horzcat(*y)]
    )
    return (np.asarray(v) for v in f(t_value))


@pytest.mark.parametrize("t", [0.0, 0.7, 1.9])
def test_chain_rule_is_the_derivative_of_the_composition(t):
    Y, s, y = _analytic_jets(t)
    assert np.allclose(np.asarray(chain_rule()(Y, s)), y, rtol=1e-12, atol=1e-12)


def test_chain_rule_is_faa_di_bruno():
    """The derived map against the written formulas (the lead's, the docs')."""
    Y, s = RNG.normal(size=(2, 5)), RNG.normal(size=5)
    y = np.asarray(chain_rule()(Y, s))
    s1, s2, s3, s4 = s[1:]
    assert np.allclose(y[:, 1], Y[:, 1] * s1)
    assert np.allclose(y[:, 2], Y[:, 2] * s1**2 + Y[:, 1] * s2)
    assert np.allclose(y[:, 3], Y[:, 3] * s1**3 + 3 * Y[:, 2] * s1 * s2 + Y[:, 1] * s3)
    fourth = (
        Y[:, 4] * s1**4
        + 6 * Y[:, 3] * s1**2 * s2
        + Y[:, 2] * (3 * s2**2 + 4 * s1 * s3)
        + Y[:, 1] * s4
    )
    assert np.allclose(y[:, 4], fourth, rtol=1e-12)


def test_end_conditions_recover_the_timing_and_vanish_on_a_composition():
    Y, s = RNG.normal(size=(2, 5)), RNG.normal(size=5)
    y = np.asarray(chain_rule()(Y, s))
    found, normal = (np.asarray(v).ravel() for v in end_conditions()(Y, y))
    assert np.allclose(found, s[1:], rtol=1e-10)
    assert np.abs(normal).max() < 1e-10


def _curvature(c1, c2):
    return cross(c1, c2) / np.linalg.norm(c1) ** 3


def _curvature_rate(c1, c2, c3):
    """d kappa / d arc length of a curve from its derivatives 1..3 (any parametrisation)."""
    n = np.linalg.norm(c1)
    return (cross(c1, c3) * n**2 - 3 * cross(c1, c2) * (c1 @ c2)) / n**6


def test_moving_node_conditions_are_curvature_and_its_rate():
    """n2 = |y'|^2 |Y'| (kappa_y - kappa_Y); with the curvatures equal,
    n3 = |y'|^3 |Y'| (kappa'_y - kappa'_Y) (arc-length derivatives)."""
    Y, s = RNG.normal(size=(2, 5)), np.r_[0.0, 1.3, RNG.normal(size=3)]
    y = np.asarray(chain_rule()(Y, s))
    y_any = y.copy()
    y_any[:, 2:] = RNG.normal(size=(2, 3))  # same velocity, another acceleration and jerk
    _, normal = (np.asarray(v).ravel() for v in end_conditions()(Y, y_any))
    v, V = np.linalg.norm(y[:, 1]), np.linalg.norm(Y[:, 1])
    kappa_y, kappa_Y = _curvature(y_any[:, 1], y_any[:, 2]), _curvature(Y[:, 1], Y[:, 2])
    assert normal[0] == pytest.approx(0.0, abs=1e-12)  # tangent along the velocity
    assert normal[1] == pytest.approx(v**2 * V * (kappa_y - kappa_Y), rel=1e-10)
    y_rate = y.copy()
    y_rate[:, 3] = RNG.normal(size=2)  # curvature matched, its rate not
    _, normal = (np.asarray(v).ravel() for v in end_conditions()(Y, y_rate))
    rate_y = _curvature_rate(*y_rate[:, 1:4].T)
    rate_Y = _curvature_rate(*Y[:, 1:4].T)
    assert abs(normal[1]) < 1e-10
    assert normal[2] == pytest.approx(v**3 * V * (rate_y - rate_Y), rel=1e-10)


def test_rest_node_derivatives_lie_along_the_tangent():
    """s' = 0: y'' = Y' s'', y''' = Y' s''', y'''' = 3 Y'' s''^2 + Y' s''''; with s'' = 0 too,
    y'''' = Y' s'''' (orders below 2r, r the first nonzero, lie along the tangent)."""
    Y, s = RNG.normal(size=(2, 5)), np.r_[0.0, 0.0, RNG.normal(size=3)]
    y = np.asarray(chain_rule()(Y, s))
    assert np.allclose(y[:, 1], 0)
    assert np.allclose(y[:, 2], Y[:, 1] * s[2])
    assert np.allclose(y[:, 3], Y[:, 1] * s[3])
    assert np.allclose(y[:, 4], 3 * Y[:, 2] * s[2] ** 2 + Y[:, 1] * s[4])
    s[2] = 0.0
    y = np.asarray(chain_rule()(Y, s))
    assert np.allclose(y[:, 4], Y[:, 1] * s[4])
    # the curvature at a rest node with y'' != 0 and y'''' pinned: (t x y'''') / (3 |y''|^2)
    s[2] = 0.8
    y = np.asarray(chain_rule()(Y, s))
    t_hat = Y[:, 1] / np.linalg.norm(Y[:, 1])
    assert _curvature(Y[:, 1], Y[:, 2]) == pytest.approx(
        cross(t_hat, y[:, 4]) / (3 * np.linalg.norm(y[:, 2]) ** 2), rel=1e-10
    )


def test_node_mismatch_names_the_direction_needed_and_given():
    Y = np.zeros((2, 5))
    Y[:, 1] = [2.0, 0.0]  # leaves along +x
    at_rest = np.zeros((2, 4))
    assert node_mismatch(Y, at_rest, 3, at_end=False) is None  # nothing asks for a direction
    at_rest[:, 2] = [0.0, -3.0]
    msg = node_mismatch(Y, at_rest, 3, at_end=False)
    assert "acceleration y'' = (0, -3)" in msg and "leave along (0, -1)" in msg
    assert "tangent points along (1, 0)" in msg
    at_rest[:, 2] = [3.0, 0.0]
    assert node_mismatch(Y, at_rest, 3, at_end=False) is None
    # arriving at rest the path runs against y'' (decelerating) ...
    assert "arrive along (-1, 0)" in node_mismatch(Y, at_rest, 3, at_end=True)
    # ... and along y''' when y'' = 0 (s''' > 0 as s' -> 0 from above)
    at_rest[:, 2], at_rest[:, 3] = 0.0, [5.0, 0.0]
    assert node_mismatch(Y, at_rest, 3, at_end=True) is None
    at_rest[:, 2], at_rest[:, 3] = [3.0, 0.0], [0.0, 1.0]  # jerk off the tangent
    assert "must all lie along" in node_mismatch(Y, at_rest, 3, at_end=False)
    moving = np.zeros((2, 4))
    moving[:, 1], moving[:, 2] = [1.0, 0.0], [0.0, 2.0]  # curvature 2 1/m, the line's is 0
    assert "curvature must be the motion's, 2 1/m; it is 0 1/m" in node_mismatch(
        Y, moving, 3, at_end=False
    )


def _monotone(m: int) -> np.ndarray:
    c = np.sort(RNG.random(m))
    c[0], c[-1] = 0.0, 1.0
    return c


@pytest.mark.parametrize("shape", [PathShape(1, 2), PathShape(3, 4), PathShape(4, 7)])
def test_composition_is_exact(shape):
    """The composed pieces against the chain rule applied sample by sample."""
    points, timing = RNG.random((shape.count, 2)), SplineBasis(7, 12)
    c = _monotone(timing.count)
    curve = compose(shape, points, timing, c, 0.3, 1.7)
    assert curve.coeffs.shape[1] == shape.degree * 7 + 1
    t = np.linspace(0.3, 2.0, 301)
    lam = (t - 0.3) / 1.7
    s = np.column_stack([timing.matrix(lam, r) @ c / 1.7**r for r in range(5)])
    jet = path_jet(shape)
    want = np.array([np.asarray(chain_rule()(jet(points, si[0]), si)) for si in s])
    got = curve.derivatives(t, 4)
    # degree 28 pieces in the monomial basis (the B-spline path) keep ~8 digits
    assert np.abs(got - want).max() <= 1e-7 * (1 + np.abs(want).max())
    assert np.allclose(curve.timing_law(t, 1), s[:, :2], atol=1e-12)
    assert np.allclose(curve.path(s[:, 0]), got[:, :, 0], atol=1e-10)


def test_gamma_certificate_on_a_composed_curve():
    """The exact piece minima of |y'' + g0 e_y| bound a dense sampling from below, closely."""
    shape, timing = PathShape(3, 4), SplineBasis(7, 12)
    points = np.array([[0.0, 0.0], [0.5, -0.6], [1.0, 0.9], [1.5, 0.2]])
    curve = compose(shape, points, timing, _monotone(12), 0.0, 0.8)
    value, _ = curve.min_norm_of_acceleration_plus((0.0, 9.81))
    acc = curve.derivatives(np.linspace(0, 0.8, 200001), 2)[:, :, 2] + [0.0, 9.81]
    sampled = np.hypot(acc[:, 0], acc[:, 1]).min()
    assert value <= sampled + 1e-9
    assert value == pytest.approx(sampled, rel=1e-6, abs=1e-9)


def test_wandering_of_a_detour():
    """Out 1 m along x, up 1 m, back: length 3 over a chord of 1, excursion 1 m."""
    leg = np.linspace(0, 1, 101)
    points = np.vstack(
        [np.column_stack([leg, 0 * leg]), np.column_stack([1 + 0 * leg, leg]),
         np.column_stack([1 - leg, 1 + 0 * leg])]
    )  # fmt: skip
    ratio, excursion = wandering(points)
    assert ratio == pytest.approx(3.0, rel=1e-12)  # length 3 over the chord (0, 0) -> (0, 1)
    assert excursion == pytest.approx(1.0, rel=1e-12)
    assert wandering(np.column_stack([leg, 2 * leg])) == pytest.approx((1.0, 0.0), abs=1e-12)
