"""The flat maps, derived symbolically, against round trips and the paper's formulas."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from cpopt.model import flat

K, G0 = 2.0 / 3.0, 9.81
finite = st.floats(-3.0, 3.0)
state = st.tuples(*([finite] * 8)).map(np.array)


def _rot(th):
    c, s = np.cos(th), np.sin(th)
    return np.array([[c, -s], [s, c]])


@settings(max_examples=200, deadline=None)
@given(state)
def test_round_trip_state_to_cp_and_back(z):
    gam = flat.gamma(z, K, G0)
    if abs(gam) < 0.05:  # the map is singular at gamma = 0
        return
    back = flat.inverse(flat.output(z, K, G0), np.sign(gam), K, G0)
    err = back - z
    err[2] = (err[2] + np.pi) % (2 * np.pi) - np.pi
    assert np.abs(err).max() < 1e-9 * max(1.0, 1.0 / abs(gam))


@settings(max_examples=100, deadline=None)
@given(
    st.tuples(*([st.floats(-2.0, 2.0)] * 8)).map(lambda a: np.array(a).reshape(2, 4)),
    st.sampled_from([-1.0, 1.0]),
)
def test_round_trip_cp_to_state_and_back(P, sigma):
    if np.hypot(P[0, 2], P[1, 2] + G0) < 0.05:
        return
    z = flat.inverse(P, sigma, K, G0)
    assert np.sign(flat.gamma(z, K, G0)) == sigma
    np.testing.assert_allclose(flat.output(z, K, G0), P, atol=1e-9)


@settings(max_examples=100, deadline=None)
@given(state, st.tuples(finite, finite).map(np.array), st.tuples(finite, finite).map(np.array))
def test_relative_degree_four_and_compensator_gives_v(z, alpha, v):
    fns = flat.flat_functions(K, G0)
    # derivatives 1..3 of the CP do not depend on the compensator inputs
    assert np.abs(np.asarray(fns["lie_alpha"](z, alpha))).max() < 1e-9
    if abs(flat.gamma(z, K, G0)) < 0.05:
        return
    a_v = np.asarray(fns["compensator"](z, v)[0]).ravel()
    np.testing.assert_allclose(np.asarray(fns["fourth"](z, a_v)).ravel(), v, atol=1e-8)


@settings(max_examples=100, deadline=None)
@given(state, st.tuples(finite, finite).map(np.array))
def test_paper_equations_10_to_12_and_corrected_7(z, v):
    _x, _y, th, xd, yd, thd, xi, eta = z
    c, s = np.cos(th), np.sin(th)
    gam = xi - K * thd**2 + G0 * s
    P = flat.output(z, K, G0)
    np.testing.assert_allclose(P[:, 1], [xd - K * thd * s, yd + K * thd * c], atol=1e-12)  # (10)
    np.testing.assert_allclose(P[:, 2], _rot(th) @ [xi - K * thd**2, -G0 * c], atol=1e-12)  # (11)
    np.testing.assert_allclose(
        P[:, 3], _rot(th) @ [eta + 3 * G0 * c * thd, thd * gam], atol=1e-11
    )  # (12)
    if abs(gam) < 0.05:
        return
    # (7) with the sign the extracted text lost: M22 = -K / gamma
    n1 = thd**2 * (K * thd**2 - xi - 4 * G0 * s) - 3 * G0**2 / K * c**2
    n2 = 2 * eta * thd + 6 * G0 * thd**2 * c + G0 / K * c * (K * thd**2 - xi - G0 * s)
    M = np.array([[1.0, -3 * G0 * c / gam], [0.0, -K / gam]])
    alpha_paper = M @ (_rot(th).T @ v - [n1, n2])
    alpha = np.asarray(flat.flat_functions(K, G0)["compensator"](z, v)[0]).ravel()
    np.testing.assert_allclose(alpha, alpha_paper, rtol=1e-9, atol=1e-9)


def test_as_printed_eq7_sign_is_wrong():
    """With M22 = +K/gamma (the extracted text) the fourth derivative is not v."""
    z = np.array([0.1, 0.2, 0.7, 0.3, -0.2, 0.9, 1.5, -0.4])
    v = np.array([0.5, -1.2])
    th, thd, xi, eta = z[2], z[5], z[6], z[7]
    c, s = np.cos(th), np.sin(th)
    gam = xi - K * thd**2 + G0 * s
    n1 = thd**2 * (K * thd**2 - xi - 4 * G0 * s) - 3 * G0**2 / K * c**2
    n2 = 2 * eta * thd + 6 * G0 * thd**2 * c + G0 / K * c * (K * thd**2 - xi - G0 * s)
    printed = np.array([[1.0, -3 * G0 * c / gam], [0.0, K / gam]]) @ (_rot(th).T @ v - [n1, n2])
    fourth = np.asarray(flat.flat_functions(K, G0)["fourth"](z, printed)).ravel()
    assert np.abs(fourth - v).max() > 1.0


def test_paper_swing_up_boundary_values_section_4():
    xs, ys, xi_s, eta_s = 0.75, 1.0, 0.3, -0.7
    P = flat.output([xs, ys, -np.pi / 2, 0, 0, 0, xi_s, eta_s], K, G0)
    np.testing.assert_allclose(P, [[xs, 0, 0, 0], [ys - K, 0, -xi_s, -eta_s]], atol=1e-12)
    xi_g, eta_g = -20.0, 0.4
    P = flat.output([xs, ys, np.pi / 2, 0, 0, 0, xi_g, eta_g], K, G0)
    np.testing.assert_allclose(P, [[xs, 0, 0, 0], [ys + K, 0, xi_g, eta_g]], atol=1e-12)


def test_horizontal_via_jerk_erratum():
    """At theta_m = 0 the CP jerk is y2''' = thetadot_m (xi_m - K thetadot_m^2) (text drops it)."""
    xm, ym, xdm, ydm, thdm, xim, etam = 0.75, 1.0, 0.2, -0.1, 1.3, -10.0, 0.5
    P = flat.output([xm, ym, 0.0, xdm, ydm, thdm, xim, etam], K, G0)
    expected = [
        [xm + K, xdm, xim - K * thdm**2, etam + 3 * G0 * thdm],
        [ym, ydm + K * thdm, -G0, thdm * (xim - K * thdm**2)],
    ]
    np.testing.assert_allclose(P, expected, atol=1e-12)
    assert abs(P[1, 3] - (xim - K * thdm**2)) > 1.0  # the printed value is wrong unless thdm = 1


def test_gamma_is_norm_of_cp_acceleration_plus_gravity():
    rng = np.random.default_rng(3)
    z = rng.normal(size=(50, 8))
    P = flat.output(z, K, G0)
    np.testing.assert_allclose(
        np.abs(flat.gamma(z, K, G0)), np.hypot(P[:, 0, 2], P[:, 1, 2] + G0), rtol=1e-12
    )
