"""The verification's integrator: extrapolated midpoint steps along a piecewise-polynomial
curve, against exact solutions, and its bounds (divergence, step budget)."""

import casadi as ca
import numpy as np
import pytest

from cpopt.closedform.curves import PiecewisePolynomial
from cpopt.verify.extrapolation import extrapolated_step, integrate_along
from cpopt.verify.integrate import DivergenceError

# two cubic pieces on [0, 1] and [1, 2.5]: p_x(t) is the first column, p_y the second
CURVE = PiecewisePolynomial(
    breaks=[0.0, 1.0, 2.5],
    coeffs=[
        [[1.0, 0.5], [2.0, -1.0], [-3.0, 0.0], [1.0, 2.0]],
        [[1.0, 1.5], [-1.5, 2.0], [0.5, 1.0], [2.0, -4.0]],
    ],
)


def _rhs(kind=ca.SX) -> ca.Function:
    """x = (integral of p_x, y, ydot): x0' = p_x, y'' = -y (lam: local time, h: piece length)."""
    x, lam, h = kind.sym("x", 3), kind.sym("lam"), kind.sym("h")
    c = kind.sym("c", 4, 2)
    p_x = sum(c[j, 0] * lam**j for j in range(4))
    return ca.Function("test_rhs", [x, lam, h, c], [ca.vertcat(p_x, x[2], -x[1])])


def _integral(t: np.ndarray) -> np.ndarray:
    """The exact integral of p_x from 0 to t, piece by piece."""
    out = np.zeros_like(t)
    for k, (a, b) in enumerate(zip(CURVE.breaks[:-1], CURVE.breaks[1:], strict=True)):
        h, c = b - a, CURVE.coeffs[k][:, 0]
        lam = np.clip((t - a) / h, 0.0, 1.0)
        out += h * sum(c[j] * lam ** (j + 1) / (j + 1) for j in range(4))
    return out


@pytest.mark.parametrize("kind", [ca.SX, ca.MX])
def test_steps_reproduce_exact_solutions_at_the_output_times(kind):
    t, x = integrate_along(_rhs(kind), CURVE, np.array([0.0, 1.0, 0.0]), 26, 1e-12, 1e-12)
    np.testing.assert_array_equal(t, np.linspace(0.0, 2.5, 26))
    np.testing.assert_allclose(x[:, 0], _integral(t), rtol=0, atol=1e-12)
    np.testing.assert_allclose(x[:, 1], np.cos(t), rtol=0, atol=1e-11)
    np.testing.assert_allclose(x[:, 2], -np.sin(t), rtol=0, atol=1e-11)


def test_a_step_is_order_eight():
    """Halving one step of y'' = -y divides its error by about 2^9 (local error ~ h^9)."""
    step = extrapolated_step(_rhs())
    errors = []
    for H in (0.8, 0.4):
        v = np.concatenate([[0.0, 1.0, 0.0], [0.0, H / 2.5, 2.5], np.zeros(8)])
        x1 = np.asarray(step(v)).ravel()[:3]
        errors.append(abs(x1[1] - np.cos(H)))
    assert 2**8 < errors[0] / errors[1] < 2**10


def _scalar(expression) -> ca.Function:
    x, lam, h, c = ca.SX.sym("x"), ca.SX.sym("lam"), ca.SX.sym("h"), ca.SX.sym("c", 4, 2)
    t = lam * h  # one piece starting at 0
    return ca.Function("scalar", [x, lam, h, c], [expression(x, t)])


def test_a_diverging_system_stops_where_it_diverges():
    # x' = x^2, x(0) = 1 blows up at t = 1
    one_piece = PiecewisePolynomial([0.0, 2.0], np.zeros((1, 4, 2)))
    with pytest.raises(DivergenceError) as err:
        integrate_along(_scalar(lambda x, t: x**2), one_piece, np.ones(1), 5, 1e-10, 1e-10)
    assert err.value.t == pytest.approx(1.0, abs=1e-3)
    assert "left |x|" in err.value.reason


def test_a_stiff_system_stops_at_its_step_budget():
    one_piece = PiecewisePolynomial([0.0, 1.0], np.zeros((1, 4, 2)))
    stiff = _scalar(lambda x, t: -1e7 * (x - ca.cos(t)))
    with pytest.raises(DivergenceError) as err:
        integrate_along(stiff, one_piece, np.ones(1), 5, 1e-10, 1e-10, steps_per_second=0.0)
    assert "more than 1000 integration steps" in err.value.reason and err.value.t < 1.0
