"""CP paths and timing laws, separated (the paper's first suggested extension, section 6).

In a phase the CP follows a path Y(s), s in [0, 1] (a Bezier curve or a clamped uniform
B-spline of low degree, :class:`PathShape`), at the pace of a timing law s(t), a B-spline in the
phase's normalised time with s' >= 0. Everything the rest of cpopt needs follows from two
derivations, made here with CasADi rather than copied:

* :func:`chain_rule`: the CP derivatives 0..4 of y(t) = Y(s(t)) (Faa di Bruno) from the path's
  derivatives at s(t) and the timing law's derivatives at t;
* :func:`end_conditions`: at a node, where the CP's derivatives y', y'', ... are given, the
  timing derivatives s', s'', ... as tangential projections, and the normal residuals that the
  path's geometry must cancel (its tangent, curvature, ...; see docs/problems.md).

:func:`compose` writes y(t) = Y(s(t)) exactly as polynomial pieces (a path piece of degree d
composed with a timing piece of degree e is a polynomial of degree d e; a B-spline path is cut
where s(t) crosses its knots), so sampling, verification and the exact gamma certificate work
on it unchanged; :func:`node_mismatch` explains a path that cannot meet a node.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from functools import lru_cache
from math import factorial

import casadi as ca
import numpy as np

from ..model import flat
from .bspline import SplineBasis
from .curves import PiecewisePolynomial
from .nodes import NODE_FIELDS

ORDERS = 5
"""CP derivatives 0..4 travel together (the torque depends on the fourth)."""
ZERO = 1e-9
"""A node's CP derivative smaller than this [m/s^r] counts as zero (round-off of cos(pi/2))."""


@lru_cache(maxsize=8)
def chain_rule(orders: int = ORDERS) -> ca.Function:
    """``(Y, s) -> y``: CP derivatives of y(t) = Y(s(t)), derived by differentiating along time.

    ``d/dt Y^(k)(s(t)) = Y^(k+1) s'`` and ``d/dt s^(k) = s^(k+1)``: applying this vector field
    four times to Y gives Faa di Bruno's formula, e.g.
    ``y'''' = Y'''' s'^4 + 6 Y''' s'^2 s'' + Y'' (3 s''^2 + 4 s' s''') + Y' s''''``.

    Parameters
    ----------
    orders : int
        How many orders (0..orders-1) to take in and give out; y^(r) needs Y, ..., Y^(r) and
        s, ..., s^(r) only.

    Returns
    -------
    casadi.Function
        Inputs: Y (2 x orders), the path and its derivatives with respect to s at s(t) [m];
        s (orders,), the timing law and its time derivatives [1/s^k]. Output: y (2 x orders),
        the CP and its time derivatives [m/s^k].
    """
    Y = ca.SX.sym("Y", 2, ORDERS)
    s = ca.SX.sym("s", ORDERS)
    x = ca.vertcat(ca.vec(Y), s)
    # the last column's derivative (Y^(5) s') enters y^(5) only: a zero placeholder is exact
    Ydot = ca.horzcat(Y[:, 1:] * s[1], ca.SX.zeros(2, 1))
    xdot = ca.vertcat(ca.vec(Ydot), s[1:], 0)
    y = [Y[:, 0]]
    for _ in range(orders - 1):
        y.append(ca.jtimes(y[-1], x, xdot))
    inputs = [Y[:, :orders], s[:orders]]
    return ca.Function("chain_rule", inputs, [ca.horzcat(*y)], ["Y", "s"], ["y"])


@lru_cache(maxsize=16)
def order_fields(K: float, g0: float) -> tuple[frozenset, ...]:
    """Per order r = 0..3, the node fields (``x``, ``theta_deg``, ...) the CP's r-th derivative
    depends on, read from the sparsity of the flat output map's Jacobian (not a table)."""
    pattern = np.array(ca.DM(flat.flat_functions(K, g0)["output"].sparsity_jac(0, 0), 1))
    return tuple(
        frozenset(NODE_FIELDS[j] for j in np.flatnonzero(pattern[2 * r : 2 * r + 2].any(0)))
        for r in range(4)
    )


def cross(a, b):
    """The planar cross product a x b (NumPy or CasADi)."""
    return a[0] * b[1] - a[1] * b[0]


@lru_cache(maxsize=1)
def end_conditions() -> ca.Function:
    """``(Y, y) -> (s, normal)``: what a node's CP derivatives ask of the path and the timing.

    The chain rule is linear in the highest timing derivative, ``y^(r) = Y' s^(r) + R_r`` with
    R_r made of Y, Y'', ... and s', ..., s^(r-1). Order by order, the component of
    ``y^(r) - R_r`` along the tangent Y' fixes ``s^(r) = Y' . (y^(r) - R_r) / |Y'|^2``; the
    component across it, ``n_r = Y' x (y^(r) - R_r)``, must vanish: that is the geometric
    (directional) condition of order r on the path.

    Returns
    -------
    casadi.Function
        Inputs: Y (2 x 5), the path's derivatives 0..4 at the node's end of the path [m];
        y (2 x 5), the node's CP derivatives 0..4 [m/s^k] (columns beyond those pinned are
        ignored by the caller). Outputs: s (4,), s' .. s'''' at the node [1/s^k]; normal (4,),
        n_1 .. n_4 [m^2/s^k].
    """
    Y = ca.SX.sym("Y", 2, ORDERS)
    y = ca.SX.sym("y", 2, ORDERS)
    s = ca.SX.sym("s", ORDERS)
    chained = chain_rule()(Y, s)
    tangent = Y[:, 1]
    found, normal = [], []
    for r in range(1, ORDERS):
        rest = ca.substitute(chained[:, r], s[r], 0)
        rest = ca.substitute(rest, s[1:r], ca.vertcat(*found)) if found else rest
        residual = y[:, r] - rest
        found.append(ca.dot(tangent, residual) / ca.dot(tangent, tangent))
        normal.append(cross(tangent, residual))
    return ca.Function(
        "end_conditions",
        [Y, y],
        [ca.vertcat(*found), ca.vertcat(*normal)],
        ["Y", "y"],
        ["s", "normal"],
    )


@dataclass(frozen=True)
class PathShape:
    """A path's shape: ``degree`` and ``count`` control points on s in [0, 1].

    ``count == degree + 1`` is a Bezier curve (one polynomial piece); more control points make
    a clamped uniform B-spline with ``count - degree`` pieces.
    """

    degree: int
    count: int

    @property
    def basis(self) -> SplineBasis:
        """The B-spline basis (Bernstein for a Bezier curve)."""
        return SplineBasis(self.degree, self.count)

    @property
    def breaks(self) -> np.ndarray:
        """Ends of the polynomial pieces in s."""
        return self.basis.breaks

    def end_matrix(self, at_end: bool) -> np.ndarray:
        """(ORDERS x count): control points -> path derivatives 0..4 at s = 0 or s = 1."""
        return np.vstack([self.basis.matrix([1.0 if at_end else 0.0], r) for r in range(ORDERS)])

    def piece_maps(self) -> np.ndarray:
        """(pieces, degree + 1, count): control points -> ascending coefficients of each piece
        in its local parameter u = (s - b_p) / (b_(p+1) - b_p)."""
        unit = np.eye(self.count)
        maps = [
            self.basis.to_pieces(np.column_stack([e, e]), 0.0, 1.0).coeffs[:, :, 0] for e in unit
        ]
        return np.stack(maps, axis=-1)


@lru_cache(maxsize=32)
def path_jet(shape: PathShape, orders: int = ORDERS) -> ca.Function:
    """``(points, s) -> Y``: a path's derivatives 0..orders-1 (2 x orders) [m] at a parameter s
    for control points (count x 2) [m]; on a B-spline the piece is chosen by s (a CasADi
    ``if_else``)."""
    points = ca.SX.sym("points", shape.count, 2)
    s = ca.SX.sym("s")
    b = shape.breaks
    maps = shape.piece_maps()
    jet = None
    for p in reversed(range(b.size - 1)):
        w = b[p + 1] - b[p]
        u = (s - b[p]) / w
        A = ca.mtimes(ca.DM(maps[p]), points)  # (degree + 1, 2)
        cols = []
        for r in range(orders):
            terms = [
                A[j, :].T * (factorial(j) / factorial(j - r)) * u ** (j - r)
                for j in range(r, shape.degree + 1)
            ]
            cols.append(sum(terms) / w**r if terms else ca.SX.zeros(2, 1))
        piece = ca.horzcat(*cols)
        jet = piece if jet is None else ca.if_else(s < b[p + 1], piece, jet)
    return ca.Function("path_jet", [points, s], [jet], ["points", "s"], ["Y"])


def timing_pieces(basis: SplineBasis, coefficients: np.ndarray, t0: float, h: float):
    """The timing law s(t) on [t0, t0 + h] as pieces: (breaks (m + 1,), coeffs (m, e + 1))."""
    c = np.asarray(coefficients, float).ravel()
    pp = basis.to_pieces(np.column_stack([c, c]), t0, h)
    return pp.breaks, pp.coeffs[:, :, 0]


def _cuts(q: np.polynomial.Polynomial, knots: np.ndarray) -> list[float]:
    """Local parameters in (0, 1) where a monotone timing piece crosses the path's knots."""
    out = [0.0, 1.0]
    for b in knots:
        for r in (q - b).roots():
            if abs(r.imag) < 1e-9 and 1e-9 < r.real < 1 - 1e-9:
                out.append(float(r.real))
    out = sorted(out)
    return [u for i, u in enumerate(out) if i == 0 or u - out[i - 1] > 1e-9]


def compose(
    shape: PathShape,
    points: np.ndarray,
    timing: SplineBasis,
    coefficients: np.ndarray,
    t0: float,
    h: float,
) -> TimedPath:
    """y(t) = Y(s(t)) on [t0, t0 + h] as exact polynomial pieces.

    Parameters
    ----------
    shape : PathShape
        The path's degree and number of control points.
    points : numpy.ndarray
        Control points (count x 2) [m].
    timing : SplineBasis
        The timing law's basis on the phase's normalised time.
    coefficients : numpy.ndarray
        Timing coefficients (non-decreasing, from 0 to 1).
    t0, h : float
        Start and duration of the phase [s].

    Returns
    -------
    TimedPath
        Pieces of degree ``shape.degree * timing.degree`` (exact: no fitting), with the path
        and the timing law kept for plots.
    """
    points = np.asarray(points, float)
    maps = shape.piece_maps()
    path_breaks = shape.breaks
    breaks, pieces = [], []
    t_breaks, s_coeffs = timing_pieces(timing, coefficients, t0, h)
    degree = shape.degree * timing.degree
    for j, q_j in enumerate(s_coeffs):
        q = np.polynomial.Polynomial(q_j)
        cuts = _cuts(q, path_breaks[1:-1])
        span = t_breaks[j + 1] - t_breaks[j]
        for a, b in itertools.pairwise(cuts):
            local = q(np.polynomial.Polynomial([a, b - a]))  # s on this cut, in nu in [0, 1]
            p = int(
                np.clip(
                    np.searchsorted(path_breaks, q((a + b) / 2), "right") - 1,
                    0,
                    path_breaks.size - 2,
                )
            )
            u = (local - path_breaks[p]) / (path_breaks[p + 1] - path_breaks[p])
            A = maps[p] @ points  # (shape.degree + 1, 2)
            piece = np.zeros((degree + 1, 2))
            for i in range(2):
                c = np.polynomial.Polynomial(A[:, i])(u).coef
                piece[: c.size, i] = c[: degree + 1]
            breaks.append(t_breaks[j] + a * span)
            pieces.append(piece)
    breaks.append(t_breaks[-1])
    return TimedPath(
        np.array(breaks),
        np.array(pieces),
        shape=shape,
        control_points=points,
        timing=timing,
        timing_coefficients=np.asarray(coefficients, float).ravel(),
        t_start=t0,
        h=h,
    )


@dataclass(frozen=True)
class TimedPath(PiecewisePolynomial):
    """A CP curve y(t) = Y(s(t)) as exact polynomial pieces, with its path and timing law.

    It is a :class:`~cpopt.closedform.curves.PiecewisePolynomial`: sampling, simulation and the
    gamma certificate use the pieces; :meth:`timing_law` and :meth:`path` serve plots and reports.
    """

    shape: PathShape | None = None
    control_points: np.ndarray | None = None
    timing: SplineBasis | None = None
    timing_coefficients: np.ndarray | None = None
    t_start: float = 0.0
    h: float = 1.0

    def timing_law(self, t: np.ndarray, order: int = 1) -> np.ndarray:
        """s(t) and its time derivatives up to ``order`` (N, order + 1) [1/s^k]."""
        lam = np.clip((np.atleast_1d(np.asarray(t, float)) - self.t_start) / self.h, 0, 1)
        return np.column_stack(
            [
                self.timing.matrix(lam, r) @ self.timing_coefficients / self.h**r
                for r in range(order + 1)
            ]
        )

    def path(self, s: np.ndarray) -> np.ndarray:
        """Points Y(s) of the path (N, 2) [m]."""
        s = np.clip(np.atleast_1d(np.asarray(s, float)), 0, 1)
        return self.shape.basis.matrix(s, 0) @ self.control_points


def node_mismatch(
    Y: np.ndarray, y: np.ndarray, orders: int, at_end: bool, tol: float = 1e-6
) -> str | None:
    """Why a path cannot meet a node's CP derivatives, or None when it can.

    Parameters
    ----------
    Y : numpy.ndarray
        The path's derivatives 0..4 at its end touching the node (2 x 5) [m].
    y : numpy.ndarray
        The node's CP derivatives (2 x k, k >= orders + 1) [m/s^r]; orders 1 .. ``orders``
        are checked.
    orders : int
        Highest order checked (3: the derivatives a node's state fixes).
    at_end : bool
        The node ends the phase (the path arrives) rather than starting it (it leaves).
    tol : float
        Relative tolerance.

    Returns
    -------
    str or None
        The first failing condition, with the direction needed and the one given.
    """
    Y = np.asarray(Y, float)
    y_node = np.zeros((2, ORDERS))
    y_node[:, : np.shape(y)[1]] = y
    tangent = Y[:, 1]
    length = float(np.linalg.norm(tangent))
    if length < 1e-9:
        return "the path's tangent there is zero (its first two control points coincide)"
    t_hat = tangent / length
    s, normal = (np.asarray(v).ravel() for v in end_conditions()(Y, y_node))
    size = np.linalg.norm(y_node, axis=0)
    first = next((r for r in range(1, orders + 1) if size[r] > ZERO), None)
    if first is None:
        return None
    # s' >= 0 along the phase: s^(first) > 0 where the path leaves a node, and
    # (-1)^(first - 1) s^(first) > 0 where it arrives
    sign = (-1) ** (first - 1) if at_end else 1
    if abs(normal[first - 1]) > tol * length * size[first] or sign * s[first - 1] <= 0:
        word = "arrive" if at_end else "leave"
        return (
            f"the CP's first nonzero derivative there is {NAMES[first]} = "
            f"{_vec(y_node[:, first])}, so the path must {word} along "
            f"{_vec(sign * y_node[:, first] / size[first])}; its tangent points along "
            f"{_vec(t_hat)}"
        )
    for r in range(first + 1, orders + 1):
        if abs(normal[r - 1]) <= tol * length * max(size[r], 1.0):
            continue
        if first == 1 and r == 2:
            return (
                f"the CP moves there, so the path's curvature must be the motion's, "
                f"{cross(y_node[:, 1], y_node[:, 2]) / size[1] ** 3:.4g} 1/m; it is "
                f"{cross(Y[:, 1], Y[:, 2]) / length**3:.4g} 1/m"
            )
        if r < 2 * first:
            return (
                f"at rest the CP's derivatives up to order {2 * first - 1} must all lie along "
                f"the path's tangent {_vec(t_hat)}; {NAMES[r]} = {_vec(y_node[:, r])} does not"
            )
        return (
            f"{NAMES[r]} = {_vec(y_node[:, r])} needs another path shape there: its "
            f"component across the tangent {_vec(t_hat)} is off by "
            f"{normal[r - 1] / length:.4g} m/s^{r}"
        )
    return None


NAMES = ("y", "its velocity y'", "its acceleration y''", "its jerk y'''", "its snap y''''")
"""How messages name the CP's derivatives 0..4."""


def wandering(points: np.ndarray) -> tuple[float, float]:
    """How far a CP path wanders (the paper's complaint about high-order time polynomials).

    Parameters
    ----------
    points : numpy.ndarray
        The CP along the motion (N, 2) [m], densely sampled.

    Returns
    -------
    length_ratio : float
        The path's length over the straight distance between its ends (1 for a straight path).
    excursion : float
        Its largest distance from the segment between its ends [m].
    """
    points = np.asarray(points, float)
    a, b = points[0], points[-1]
    length = np.linalg.norm(np.diff(points, axis=0), axis=1).sum()
    chord = b - a
    span = float(chord @ chord)
    u = np.clip((points - a) @ chord / span, 0.0, 1.0) if span > 0 else np.zeros(len(points))
    excursion = np.linalg.norm(points - (a + u[:, None] * chord), axis=1).max()
    return float(length / np.sqrt(span)), float(excursion)


def _vec(v: np.ndarray) -> str:
    v = np.asarray(v, float)
    v = np.where(np.abs(v) < 1e-9 * np.abs(v).max(), 0.0, v) + 0.0  # no "-0", no round-off
    return f"({v[0]:.4g}, {v[1]:.4g})"


__all__ = [
    "NAMES",
    "ORDERS",
    "ZERO",
    "PathShape",
    "TimedPath",
    "chain_rule",
    "compose",
    "cross",
    "end_conditions",
    "node_mismatch",
    "order_fields",
    "path_jet",
    "timing_pieces",
    "wandering",
]
