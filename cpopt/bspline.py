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
        pieces = np.zeros((mids.size, d + 1, 2))
        derivs = [self.matrix(mids, r) @ coeffs for r in range(d + 1)]  # each (pieces, 2)
        for k in range(mids.size):
            # Taylor at the middle: sum_j D_j (w (lam - 1/2))^j / j!, expanded in powers of lam
            for j in range(d + 1):
                term = derivs[j][k] * w[k] ** j / factorial(j)
                for i in range(j + 1):
                    pieces[k, i] += term * comb(j, i) * (-0.5) ** (j - i)
        return PiecewisePolynomial(t0 + h * b, pieces)


def _knots(degree: int, count: int) -> np.ndarray:
    inner = np.linspace(0.0, 1.0, count - degree + 1)[1:-1]
    return np.r_[np.zeros(degree + 1), inner, np.ones(degree + 1)]


@lru_cache(maxsize=256)
def _matrix(degree: int, count: int, s: tuple, order: int) -> np.ndarray:
    if order > degree:  # a low-degree path's higher derivatives (SciPy refuses to form them)
        return np.zeros((len(s), count))
    from scipy.interpolate import BSpline  # imported here: 0.7 s of start-up otherwise

    spline = BSpline(_knots(degree, count), np.eye(count), degree)
    if order:
        spline = spline.derivative(order)
    return np.asarray(spline(np.asarray(s, float)))


def fit(basis: SplineBasis, curve: PiecewisePolynomial, samples: int = 200) -> np.ndarray:
    """Least-squares projection of a curve onto the basis (coefficients (count, 2))."""
    s = np.linspace(0.0, 1.0, samples)
    values = curve.derivatives(curve.t0 + s * (curve.t1 - curve.t0), 0)[:, :, 0]
    coeffs, *_ = np.linalg.lstsq(basis.matrix(s, 0), values, rcond=None)
    return coeffs
