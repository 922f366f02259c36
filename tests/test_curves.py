"""Curves: Hermite segments and the exact |gamma| certificate."""

import numpy as np
import pytest

from cpopt.closedform.curves import PiecewisePolynomial, hermite


@pytest.mark.parametrize("n", [4, 5])
def test_hermite_matches_end_derivatives(n):
    rng = np.random.default_rng(n)
    start, end = rng.normal(size=(2, n)), rng.normal(size=(2, n))
    curve = hermite(0.2, 1.7, start, end)
    assert curve.coeffs.shape == (1, 2 * n, 2)
    np.testing.assert_allclose(curve.derivatives([0.2], n - 1)[0], start, atol=1e-12)
    np.testing.assert_allclose(curve.derivatives([1.7], n - 1)[0], end, atol=1e-10)


def test_derivatives_agree_with_finite_differences():
    rng = np.random.default_rng(0)
    curve = PiecewisePolynomial([0.0, 0.5, 1.3], rng.normal(size=(2, 8, 2)))
    t = np.linspace(0.01, 0.49, 50)
    d = curve.derivatives(t, 4)
    h = 1e-5
    for k in range(4):
        fd = (curve.derivatives(t + h, 4)[:, :, k] - curve.derivatives(t - h, 4)[:, :, k]) / (2 * h)
        np.testing.assert_allclose(fd, d[:, :, k + 1], rtol=1e-6, atol=1e-5)


def test_min_gamma_certificate_is_exact():
    rng = np.random.default_rng(2)
    for _ in range(20):
        curve = hermite(0.0, 1.0, rng.normal(size=(2, 4)) * 3, rng.normal(size=(2, 4)) * 3)
        value, _t = curve.min_norm_of_acceleration_plus((0.0, 9.81))
        tt = np.linspace(0, 1, 200001)
        acc = curve.derivatives(tt, 2)[:, :, 2]
        dense = np.hypot(acc[:, 0], acc[:, 1] + 9.81)
        assert value <= dense.min() + 1e-10
        assert value == pytest.approx(dense.min(), abs=1e-6)


def test_every_pieces_minimum_is_exact_batched_or_not():
    """Seven-piece curves, the roots of all pieces' slopes found together; a piece of lower
    degree (its top coefficients zero) goes by the per-piece roots: each piece's certified
    minimum is at or below the densest sampling's and within 1e-6 m/s^2 (or 1e-8 of it, the
    sampling's own resolution on a large one) of it."""
    rng = np.random.default_rng(5)
    for trial in range(10):
        coeffs = rng.normal(size=(7, 8, 2)) * 3.0
        if trial % 2:
            coeffs[3, 5:, :] = 0.0  # a cubic among septics
        curve = PiecewisePolynomial(np.cumsum(np.r_[0.0, rng.uniform(0.1, 0.4, 7)]), coeffs)
        for k, (value, at) in enumerate(curve.piece_minima((0.0, 9.81))):
            tt = np.linspace(curve.breaks[k], curve.breaks[k + 1], 100001)
            acc = curve.derivatives(tt, 2)[:, :, 2]
            dense = np.hypot(acc[:, 0], acc[:, 1] + 9.81)
            assert value <= dense.min() + 1e-10
            assert value == pytest.approx(dense.min(), rel=1e-8, abs=1e-6)
            assert curve.breaks[k] <= at <= curve.breaks[k + 1]


def test_bspline_pieces_match_the_basis_and_end_conditions_are_local():
    from cpopt.closedform.bspline import SplineBasis, fit

    basis = SplineBasis(8, 14)
    coeffs = np.random.default_rng(4).normal(size=(14, 2))
    pieces = basis.to_pieces(coeffs, 0.5, 2.0)
    s = np.linspace(0, 1, 97)
    for r in range(5):  # the r-th time derivative is h^-r times the basis derivative
        expected = basis.matrix(s, r) @ coeffs / 2.0**r
        got = pieces.derivatives(0.5 + 2.0 * s, 4)[:, :, r]
        np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-9 * np.abs(expected).max())
    start, end = basis.end_matrices(5)
    assert np.allclose(np.triu(start, 1), 0) and abs(np.linalg.det(start)) > 0
    # the r-th derivative at s = 1 uses the last r + 1 coefficients only
    assert np.allclose(np.triu(end[:, ::-1], 1), 0) and abs(np.linalg.det(end)) > 0
    # derivatives at s = 0 use only the first five coefficients
    assert np.allclose(basis.matrix([0.0], 4)[0, 5:], 0)
    # projecting a degree-7 Hermite curve onto a degree-8 spline reproduces it
    curve = hermite(0.0, 1.3, np.ones((2, 4)), np.zeros((2, 4)))
    t = np.linspace(0, 1.3, 50)
    back = basis.to_pieces(fit(basis, curve), 0.0, 1.3)
    np.testing.assert_allclose(back.derivatives(t, 3), curve.derivatives(t, 3), atol=1e-8)


def _break_jumps(curve: PiecewisePolynomial, order: int) -> np.ndarray:
    """Largest jump of each derivative 0..order across the curve's inner breaks."""
    b = curve.breaks[1:-1]
    jumps = np.zeros(order + 1)
    for k, t in enumerate(b):
        one = PiecewisePolynomial(curve.breaks[k : k + 2], curve.coeffs[k : k + 1])
        two = PiecewisePolynomial(curve.breaks[k + 1 : k + 3], curve.coeffs[k + 1 : k + 2])
        diff = one.derivatives([t], order)[0] - two.derivatives([t], order)[0]
        jumps = np.maximum(jumps, np.abs(diff).max(axis=0))
    return jumps


def test_bspline_pieces_of_a_short_far_phase_keep_their_derivatives():
    """A 0.1 s phase 1.5 m from the origin (like the benchmark transfer's first phase): its
    pieces agree across their breaks in the third derivative to 1e-7 m/s^3 (measured 1.9e-8;
    taking the derivatives of the coefficients themselves, not of their offset from their
    mean, left 4.2e-7 here, and 7e-7 on the transfer, which an open-loop replay grew to 3e-6
    rad/s), and their derivatives are those of the same motion near the origin."""
    from cpopt.closedform.bspline import SplineBasis

    basis = SplineBasis(8, 26)
    g = np.linspace(0.0, 1.0, 26)
    motion = 0.05 * np.column_stack([np.sin(3 * g), np.cos(2 * g)])  # 5 cm in 0.1 s
    far = basis.to_pieces(motion + np.array([1.5, -1.2]), 0.3, 0.1)
    near = basis.to_pieces(motion, 0.3, 0.1)
    assert _break_jumps(far, 3)[3] < 1e-7
    t = np.linspace(0.3, 0.4, 41)
    moving, still = far.derivatives(t, 4)[:, :, 1:], near.derivatives(t, 4)[:, :, 1:]
    scale = np.abs(still).max(axis=(0, 1))  # of each derivative
    assert np.all(np.abs(moving - still).max(axis=(0, 1)) < 1e-12 * scale)


def test_end_jets_are_set_exactly_and_the_inner_breaks_stay_smooth():
    """with_end_jets moves a curve's derivatives 0..3 at its ends to the given jets and leaves
    the inner pieces and the breaks' continuity in derivatives 0..3 as they were."""
    from cpopt.closedform.bspline import SplineBasis
    from cpopt.closedform.curves import with_end_jets

    basis = SplineBasis(8, 14)
    coeffs = np.random.default_rng(5).normal(size=(14, 2))
    curve = basis.to_pieces(coeffs, 0.0, 1.0)
    jets = curve.derivatives(np.array([0.0, 1.0]), 3)
    start, end = jets[0] + 1e-6, jets[1] - 2e-6
    fixed = with_end_jets(curve, start, end)
    np.testing.assert_allclose(fixed.derivatives(np.array([0.0]), 3)[0], start, atol=1e-13)
    np.testing.assert_allclose(fixed.derivatives(np.array([1.0]), 3)[0], end, atol=1e-12)
    np.testing.assert_array_equal(fixed.coeffs[1:-1], curve.coeffs[1:-1])
    scale = np.abs(curve.derivatives(np.linspace(0, 1, 101), 3)).max(axis=(0, 1))
    assert np.all(_break_jumps(fixed, 3) <= _break_jumps(curve, 3) + 1e-13 * scale)
    one_piece = with_end_jets(hermite(0.0, 1.0, np.zeros((2, 4)), np.ones((2, 4))), start, end)
    np.testing.assert_allclose(one_piece.derivatives(np.array([0.0, 1.0]), 3), [start, end])
    kept = with_end_jets(curve, None, end)
    np.testing.assert_array_equal(kept.coeffs[0], curve.coeffs[0])


@pytest.mark.parametrize("degree", [1, 3, 5, 8, 11])
def test_basis_matrices_equal_scipys_bspline(degree):
    """cpopt's own Cox-de Boor evaluation (no scipy.interpolate import at start-up) gives
    SciPy's BSpline values and derivatives, ends and a little outside [0, 1] included."""
    from scipy.interpolate import BSpline

    from cpopt.closedform.bspline import SplineBasis

    s = np.r_[0.0, 1.0, np.linspace(0.0, 1.0, 23), np.random.default_rng(degree).random(9), -1e-3]
    for count in (degree + 1, degree + 4, degree + 17):
        basis = SplineBasis(degree, count)
        for order in range(degree + 1):
            reference = BSpline(basis.knots, np.eye(count), degree)
            reference = reference.derivative(order) if order else reference
            expected = reference(s)
            scale = max(1.0, np.abs(expected).max())
            np.testing.assert_allclose(basis.matrix(s, order), expected, rtol=0, atol=1e-13 * scale)
        assert not basis.matrix(s, degree + 1).any()


def test_the_minimum_of_gamma_of_a_curve_with_a_non_finite_coefficient_is_nan():
    """A failed solve's iterate may hold NaN coefficients: certifying it gives NaN (and where),
    not numpy's LinAlgError from the roots of a NaN polynomial (a traceback a user saw)."""
    curve = hermite(0.0, 1.0, np.zeros((2, 4)), np.ones((2, 4)))
    coeffs = np.concatenate([curve.coeffs, curve.coeffs])
    coeffs[1, 3, 0] = np.nan
    broken = PiecewisePolynomial(np.array([0.0, 1.0, 2.0]), coeffs)
    value, where = broken.min_norm_of_acceleration_plus((0.0, 9.81))
    assert np.isnan(value) and where == 1.0
    assert np.isfinite(curve.min_norm_of_acceleration_plus((0.0, 9.81))[0])
