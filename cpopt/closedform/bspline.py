"""Clamped uniform B-splines on normalised time s in [0, 1], as constant basis matrices.

A CP coordinate on a phase of duration h is ``p(t0 + s h) = sum_i c_i N_i(s)``; its r-th time
derivative is ``h^-r sum_i c_i N_i^(r)(s)``. The basis matrices at fixed s are numbers, so the
curve and its derivatives are linear in the coefficients: the optimizer's graph stays small. A
polynomial of degree d is the B-spline with d + 1 coefficients (Bernstein basis).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from math import comb, factorial

import numpy as np

from .curves import PiecewisePolynomial


@dataclass(frozen=True)
class SplineBasis:
    """A clamped uniform B-spline basis of a given degree and number of coefficients."""

    degree: int
    count: int

    def __post_init__(self) -> None:
        if self.count < self.degree + 1:
            raise ValueError(
                f"a degree-{self.degree} B-spline needs at least "
                f"{self.degree + 1} coefficients, got {self.count}"
            )

    @property
    def knots(self) -> np.ndarray:
        """The knot vector (count + degree + 1,)."""
        return _knots(self.degree, self.count)

    @property
    def breaks(self) -> np.ndarray:
        """The distinct knots: ends of the polynomial pieces in s."""
        return np.linspace(0.0, 1.0, self.count - self.degree + 1)

    def matrix(self, s: np.ndarray, order: int) -> np.ndarray:
        """Basis derivative values ``N_i^(order)(s_j)``, shape (len(s), count)."""
        return _matrix(self.degree, self.count, tuple(np.atleast_1d(s).tolist()), order)

    def end_matrices(self, orders: int) -> tuple[np.ndarray, np.ndarray]:
        """Square (orders x orders) maps from the first / last ``orders`` coefficients to the
        derivatives 0..orders-1 at s = 0 / s = 1 (the other coefficients do not enter)."""
        start = np.array([self.matrix([0.0], r)[0, :orders] for r in range(orders)])
        end = np.array([self.matrix([1.0], r)[0, -orders:] for r in range(orders)])
        return start, end

    def to_pieces(self, coeffs: np.ndarray, t0: float, h: float) -> PiecewisePolynomial:
        """The spline with coefficients (count, 2) on [t0, t0 + h] as polynomial pieces."""
        b = self.breaks
        mids = 0.5 * (b[:-1] + b[1:])
        w = np.diff(b)
        d = self.degree
        # The derivatives are differences of the coefficients: taken of the coefficients less
        # their mean (B-splines sum to one, so only the value moves), they lose the digits of
        # the curve's offset, not of its motion.
        ref = coeffs.mean(axis=0)
        derivs = np.stack([self.matrix(mids, r) @ (coeffs - ref) for r in range(d + 1)])
        derivs[0] = derivs[0] + ref  # (orders, pieces, 2)
        # Taylor at the middle: sum_j D_j (w (lam - 1/2))^j / j!, expanded in powers of lam;
        # one product over every piece (a loop over pieces and orders took most of a
        # re-plan's unpacking)
        terms = derivs * (w[None, :] ** np.arange(d + 1)[:, None])[:, :, None]
        pieces = np.einsum("jkc,ji->kic", terms, _taylor_shift(d))
        return PiecewisePolynomial(t0 + h * b, pieces)


@lru_cache(maxsize=16)
def _taylor_shift(degree: int) -> np.ndarray:
    """M[j, i] = comb(j, i) (-1/2)^(j - i) / j!: the j-th Taylor term about a piece's middle
    as powers lam^i of its own coordinate (zero for i > j)."""
    M = np.zeros((degree + 1, degree + 1))
    for j in range(degree + 1):
        for i in range(j + 1):
            M[j, i] = comb(j, i) * (-0.5) ** (j - i) / factorial(j)
    return M


def _knots(degree: int, count: int) -> np.ndarray:
    inner = np.linspace(0.0, 1.0, count - degree + 1)[1:-1]
    return np.r_[np.zeros(degree + 1), inner, np.ones(degree + 1)]


@lru_cache(maxsize=256)
def _matrix(degree: int, count: int, s: tuple, order: int) -> np.ndarray:
    if order > degree:  # a low-degree path's higher derivatives vanish
        return np.zeros((len(s), count))
    knots = _knots(degree, count)
    # the r-th derivative of sum_i c_i N_i is a spline of degree p - r on the inner knots
    # whose coefficients are differences of the c_i (the classic derivative formula); with
    # c = identity, the rows of D map the original coefficients onto the derivative's
    D = np.eye(count)
    for r in range(order):
        p = degree - r
        width = knots[r + p + 1 : p + count] - knots[r + 1 : count]  # u_{i+p+1} - u_{i+1}
        D = p * (D[1:] - D[:-1]) / width[:, None]
    inner = knots[order : len(knots) - order]
    return cox_de_boor(inner, degree - order, np.asarray(s, float)) @ D


def cox_de_boor(knots: np.ndarray, degree: int, s: np.ndarray) -> np.ndarray:
    """Values of the B-spline basis functions of ``degree`` on ``knots`` at s (len(s), count).

    Each s is placed in its knot span (the last non-empty one at the right end, as a limit
    from the left; outside the knots, the end spans' polynomials, as scipy's BSpline
    extrapolates), and the Cox-de Boor recursion raises the degree from the span's indicator.
    SciPy's ``BSpline`` computes the same; it is not imported for it because importing
    ``scipy.interpolate`` took 0.4-0.9 s of a fresh ``cpopt solve``.
    """
    spans = len(knots) - 1
    k = np.clip(np.searchsorted(knots, s, side="right") - 1, degree, spans - degree - 1)
    N = np.zeros((s.size, spans))
    N[np.arange(s.size), k] = 1.0
    for q in range(1, degree + 1):
        left = knots[: spans - q]
        right = knots[q + 1 : spans + 1]
        rise = _safe_ratio(s[:, None] - left, knots[q:spans] - left)
        fall = _safe_ratio(right - s[:, None], right - knots[1 : spans - q + 1])
        N = rise * N[:, :-1] + fall * N[:, 1:]
    return N


def _safe_ratio(numerator: np.ndarray, denominator: np.ndarray) -> np.ndarray:
    """numerator / denominator, 0 where the denominator is 0 (a repeated knot: 0/0 := 0)."""
    out = np.zeros(np.broadcast_shapes(numerator.shape, denominator.shape))
    np.divide(numerator, denominator, out=out, where=np.broadcast_to(denominator != 0, out.shape))
    return out


def fit(basis: SplineBasis, curve: PiecewisePolynomial, samples: int = 200) -> np.ndarray:
    """Least-squares projection of a curve onto the basis (coefficients (count, 2))."""
    s = np.linspace(0.0, 1.0, samples)
    values = curve.derivatives(curve.t0 + s * (curve.t1 - curve.t0), 0)[:, :, 0]
    coeffs, *_ = np.linalg.lstsq(basis.matrix(s, 0), values, rcond=None)
    return coeffs
