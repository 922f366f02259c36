"""CP curve families, evaluated with their derivatives 0..4.

Every curve is held as a :class:`PiecewisePolynomial` in the plane: pieces on breakpoints, each
a polynomial in the local normalised time ``lam = (t - t_k) / (t_{k+1} - t_k)`` with ascending
coefficients. The closed-form seventh-degree Hermite segment (:func:`hermite`) is one piece;
B-splines (see :mod:`cpopt.closedform.bspline`) convert to pieces. The exact minimum of
``|p'' + g0 e_y|`` (= |gamma|) over a curve comes from the roots of a polynomial, which
certifies the regularity margin between samples.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from math import factorial

import numpy as np


@dataclass(frozen=True)
class PiecewisePolynomial:
    """A planar curve made of polynomial pieces.

    Parameters
    ----------
    breaks : numpy.ndarray
        Increasing breakpoints t_0 < ... < t_m [s], shape (m + 1,).
    coeffs : numpy.ndarray
        Shape (m, d + 1, 2): piece k is ``sum_j coeffs[k, j] lam^j`` with
        ``lam = (t - t_k) / (t_{k+1} - t_k)`` [m].
    """

    breaks: np.ndarray
    coeffs: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "breaks", np.asarray(self.breaks, float))
        object.__setattr__(self, "coeffs", np.asarray(self.coeffs, float))
        if self.coeffs.shape[0] != self.breaks.size - 1 or np.any(np.diff(self.breaks) <= 0):
            raise ValueError("breakpoints must increase and match the number of pieces")

    @property
    def t0(self) -> float:
        """Start time [s]."""
        return float(self.breaks[0])

    @property
    def t1(self) -> float:
        """End time [s]."""
        return float(self.breaks[-1])

    def derivatives(self, t: np.ndarray, order: int = 4) -> np.ndarray:
        """Value and time derivatives 0..order at times t.

        Parameters
        ----------
        t : array_like
            Times [s] within [t0, t1] (clipped to it), shape (N,).
        order : int
            Highest derivative.

        Returns
        -------
        numpy.ndarray
            (N, 2, order + 1): [..., k] is the k-th derivative [m/s^k].
        """
        t = np.clip(np.atleast_1d(np.asarray(t, float)), self.t0, self.t1)
        k = np.clip(np.searchsorted(self.breaks, t, side="right") - 1, 0, self.coeffs.shape[0] - 1)
        h = np.diff(self.breaks)[k]
        lam = (t - self.breaks[k]) / h
        deg = self.coeffs.shape[1] - 1
        out = np.zeros((t.size, 2, order + 1))
        c = self.coeffs[k]  # (N, d+1, 2)
        for r in range(order + 1):
            if r > deg:
                break
            # d^r/dlam^r of lam^j is j!/(j-r)! lam^(j-r)
            acc = np.zeros((t.size, 2))
            for j in range(deg, r - 1, -1):
                acc = acc * lam[:, None] + c[:, j, :] * (factorial(j) / factorial(j - r))
            out[:, :, r] = acc / h[:, None] ** r
        return out

    def min_norm_of_acceleration_plus(self, offset: tuple[float, float]) -> tuple[float, float]:
        """Exact minimum over the curve of ``|p''(t) + offset|`` and where it occurs.

        With ``offset = (0, g0)`` this is the minimum of |gamma| along the plan: the squared
        norm is a polynomial on each piece, minimised at an end or at a real root of its
        derivative. A curve with a non-finite coefficient (a failed solve's iterate) has NaN
        as its minimum, at the start of the first such piece.

        Returns
        -------
        value : float
            The minimum [m/s^2].
        t : float
            A time where it is attained [s].
        """
        minima = self.piece_minima(offset)
        return next((m for m in minima if math.isnan(m[0])), None) or min(minima)

    def piece_minima(self, offset: tuple[float, float]) -> list[tuple[float, float]]:
        """Exact minimum of ``|p''(t) + offset|`` on each piece, as (value [m/s^2], time [s])."""
        h = np.diff(self.breaks)
        finite = np.all(np.isfinite(self.coeffs), axis=(1, 2))
        # Candidates of every piece evaluated in one call: per call, numpy's overhead is most
        # of the cost on a re-plan's few pieces (the Polynomial class took 6 ms a plan).
        cands = self._stationary_all(h, offset, finite)
        owner = np.repeat(np.arange(h.size), [len(c) for c in cands])
        times = self.breaks[owner] + np.concatenate([[], *cands]) * h[owner]
        # Evaluate the candidates on the curve itself: the squared polynomial loses digits.
        acc = self.derivatives(times, 2)[:, :, 2] + np.asarray(offset)
        norms = np.hypot(acc[:, 0], acc[:, 1])
        # each piece's smallest candidate: the first of its group sorted by norm
        order = np.lexsort((norms, owner))
        first = order[np.r_[True, owner[order][1:] != owner[order][:-1]]] if owner.size else []
        best = dict(zip(owner[first].tolist(), first.tolist(), strict=True))
        out = []
        for k in range(h.size):
            if not finite[k]:  # a failed solve's iterate: no minimum
                out.append((math.nan, float(self.breaks[k])))
                continue
            i = best[k]
            out.append((float(norms[i]), float(times[i])))
        return out

    def _stationary_all(
        self, h: np.ndarray, offset: tuple[float, float], finite: np.ndarray
    ) -> list:
        """Every piece's candidates (:meth:`_stationary`; none for a non-finite piece), the
        roots of all pieces' slopes from one batched eigenvalue call (one call a piece was
        most of a re-plan's certificate); a piece whose slope's leading coefficient is
        negligible (a lower degree than its neighbours') goes by :meth:`_stationary`."""
        d = self.coeffs.shape[1] - 1
        if d < 3:
            return [[0.0, 1.0] if finite[k] else [] for k in range(h.size)]
        m = d - 2  # the degree of p''
        j = np.arange(2, d + 1)
        with np.errstate(invalid="ignore", over="ignore"):
            acc = self.coeffs[:, 2:, :] * (j * (j - 1))[None, :, None] / (h**2)[:, None, None]
            acc[:, 0, :] += np.asarray(offset, float)
            outer = np.einsum("kac,kbc->kab", acc, acc)
        square = np.zeros((h.size, 2 * m + 1))
        for a in range(m + 1):
            square[:, a : a + m + 1] += outer[:, a, :]
        slope = square[:, 1:] * np.arange(1, 2 * m + 1)
        curv = slope[:, 1:] * np.arange(1, 2 * m)
        lead = np.abs(slope[:, -1])
        with np.errstate(invalid="ignore"):
            batched = finite & (lead > 1e-12 * np.abs(slope).max(axis=1, initial=0.0))
        out = [[] for _ in range(h.size)]
        for k in np.flatnonzero(finite & ~batched):
            out[k] = self._stationary(int(k), float(h[k]), offset)
        rows = np.flatnonzero(batched)
        if not rows.size:
            return out
        n = slope.shape[1] - 1
        companion = np.zeros((rows.size, n, n))
        companion[:, np.arange(1, n), np.arange(n - 1)] = 1.0
        companion[:, :, -1] = -slope[rows, :-1] / slope[rows, -1:]
        roots = np.linalg.eigvals(companion)
        keep = (np.abs(roots.imag) <= 1e-4) & (roots.real > -1e-6) & (roots.real < 1 + 1e-6)
        owner, lam = np.nonzero(keep)[0], roots.real[keep]
        active = np.ones(lam.size, bool)
        for _ in range(4):  # Newton polishing: companion-matrix roots lose digits
            c = _horner(curv[rows[owner]], lam)
            active &= c != 0
            step = np.divide(
                _horner(slope[rows[owner]], lam), c, where=active, out=np.zeros_like(c)
            )
            lam = lam - step
        lam = np.clip(lam, 0.0, 1.0)
        for i, k in enumerate(rows):
            out[k] = [0.0, 1.0, *lam[owner == i].tolist()]
        return out

    def _stationary(self, k: int, h: float, offset: tuple[float, float]) -> list[float]:
        """Piece k's candidates for the minimum of ``|p'' + offset|^2``: its ends and the
        roots of the derivative in [0, 1], in local time lam (h: the piece's length [s])."""
        P = np.polynomial.polynomial
        cands = [0.0, 1.0]
        if self.coeffs.shape[1] - 1 < 3:
            return cands
        acc = [P.polyadd(P.polyder(self.coeffs[k, :, i], 2) / h**2, [offset[i]]) for i in (0, 1)]
        slope = P.polyder(P.polyadd(P.polymul(acc[0], acc[0]), P.polymul(acc[1], acc[1])))
        curv = P.polyder(slope)
        for r in P.polyroots(slope):
            if abs(r.imag) > 1e-4 or not -1e-6 < r.real < 1 + 1e-6:
                continue
            lam = r.real
            for _ in range(4):  # Newton polishing: companion-matrix roots lose digits
                c = P.polyval(lam, curv)
                if c == 0:
                    break
                lam -= P.polyval(lam, slope) / c
            cands.append(min(max(lam, 0.0), 1.0))
        return cands


def hermite(t0: float, t1: float, start: np.ndarray, end: np.ndarray) -> PiecewisePolynomial:
    """The polynomial of degree 2n - 1 matching derivatives 0..n-1 at both ends.

    ``start`` and ``end`` are (2, n) arrays; n = 4 gives the paper's seventh degree and
    n = 5 (pinning the fourth derivative too, for torque continuity) the ninth.
    """
    start, end = np.asarray(start, float), np.asarray(end, float)
    n = start.shape[1]
    h = t1 - t0
    deg = 2 * n - 1
    rows = []
    rhs = []
    for at, vals in ((0.0, start), (1.0, end)):
        for r in range(n):
            row = np.zeros(deg + 1)
            for j in range(r, deg + 1):
                row[j] = factorial(j) / factorial(j - r) * at ** (j - r)
            rows.append(row)
            rhs.append(vals[:, r] * h**r)
    coeffs = np.linalg.solve(np.array(rows), np.array(rhs))
    return PiecewisePolynomial(np.array([t0, t1]), coeffs[None])


def with_end_jets(
    curve: PiecewisePolynomial, start: np.ndarray | None, end: np.ndarray | None
) -> PiecewisePolynomial:
    """``curve`` with its derivatives 0..3 at t0 set to ``start`` and at t1 to ``end`` exactly.

    A phase of the flat optimizer ends at its nodes' states, but evaluating its B-spline there
    loses digits: a short phase's third derivative weighs its end coefficients by up to 1e5
    over h^3 (the benchmark transfer's 0.097 s phase missed its switch state by 9e-8 rad/s in
    thetadot), and an open-loop replay grows that to 4e-6. The first and last pieces get a
    seventh-degree correction (:func:`hermite`) that vanishes with derivatives 0..3 at their
    other end.

    Parameters
    ----------
    curve : PiecewisePolynomial
        A curve of degree 7 or more.
    start, end : numpy.ndarray or None
        (2, 4): derivatives 0..3 [m/s^k] wanted at t0 and t1; None keeps that end.
    """
    coeffs = curve.coeffs.copy()
    if coeffs.shape[1] < 8:
        coeffs = np.concatenate([coeffs, np.zeros((coeffs.shape[0], 8 - coeffs.shape[1], 2))], 1)
    jets = curve.derivatives(np.array([curve.t0, curve.t1]), 3)
    zero = np.zeros((2, 4))
    d0 = zero if start is None else np.asarray(start, float) - jets[0]
    d1 = zero if end is None else np.asarray(end, float) - jets[1]
    b, last = curve.breaks, coeffs.shape[0] - 1
    fixes = [(0, d0, d1)] if last == 0 else [(0, d0, zero), (last, zero, d1)]
    for k, at_start, at_end in fixes:
        coeffs[k, :8] += hermite(b[k], b[k + 1], at_start, at_end).coeffs[0]
    return PiecewisePolynomial(b, coeffs)


def _horner(coeffs: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Row i's polynomial (ascending coefficients, ``coeffs[i]``) at ``x[i]``."""
    out = np.zeros_like(x)
    for j in range(coeffs.shape[1] - 1, -1, -1):
        out = out * x + coeffs[:, j]
    return out
