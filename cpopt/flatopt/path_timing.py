"""The ``path_timing`` curve family of the flat optimizer: in each phase y(t) = Y(s(t)).

A new curve family, not a new optimizer: a phase yields its CP derivatives 0..4 at any
normalised times (:meth:`PathTimingCurve.derivatives`), and those feed the same per-sample
function, limits, objective terms and gamma constraints as the free B-spline curves.

Decision variables of a phase: the path's free control points (block kind ``control_points``,
bounded as the file says) and the timing law's inner coefficients (kind ``timing``). The ends are
tied to the nodes, as the free B-spline's boundary coefficients are:

* the first and last control points are the nodes' CPs;
* the timing law's first and last coefficients hold s = 0 and s = 1 and the timing derivatives
  s', s'', ... that the node's CP derivatives ask for (their tangential components,
  :func:`cpopt.paths.end_conditions`); these coefficients are eliminated;
* the normal components, the path's geometric conditions, are equality constraints where they
  depend on the optimizer's choices (where they do not, the problem's validation has checked
  them and names the node that a path cannot meet).

s' >= 0 is imposed through non-decreasing timing coefficients (a sufficient condition: s' is
a B-spline whose coefficients are the scaled differences of s's, and it lies in their convex
hull).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from ..closedform.bspline import SplineBasis
from ..closedform.curves import hermite
from ..closedform.nodes import freed_fields, node_names
from ..closedform.paths import (
    ORDERS,
    ZERO,
    PathShape,
    chain_rule,
    compose,
    end_conditions,
    order_fields,
    path_jet,
)
from ..model import flat
from .constraints import Constraints
from .layout import Layout

if TYPE_CHECKING:
    from ..problem import PathSpec, Problem

TANGENT_MIN = 1e-3
"""Smallest length [m] of a path's end tangent Y'(0) or Y'(1) that free control points may take
(the timing derivatives at a node are projections on it)."""
TANGENT_RATIO = 0.1
"""... and at least this fraction of the chord |Y(1) - Y(0)|: a control point next to an end
would otherwise collapse onto it, and a path with a vanishing end tangent meets a node's
directional conditions trivially (every normal residual is a cross product with Y')."""


def timing_basis(path: PathSpec) -> SplineBasis:
    """The basis of a phase's timing law s(t) on the phase's normalised time."""
    return SplineBasis(path.timing.degree, path.timing.coefficients)


@dataclass(frozen=True)
class PathTimingCurve:
    """One phase's CP curve y(t) = Y(s(t)) as CasADi expressions of the decision variables.

    Attributes
    ----------
    shape : PathShape
        The path's degree and number of control points.
    timing : SplineBasis
        The timing law's basis on the phase's normalised time.
    points : casadi.MX
        Control points (count x 2) [m]: the nodes' CPs at the ends, constants or decisions.
    coefficients : casadi.MX
        Timing coefficients (count,), from 0 to 1.
    h : casadi.MX
        The phase's duration [s].
    """

    shape: PathShape
    timing: SplineBasis
    points: ca.MX
    coefficients: ca.MX
    h: ca.MX

    def derivatives(self, lam: np.ndarray, orders: int = ORDERS) -> list:
        """CP derivatives 0..orders-1 at normalised times, each (len(lam), 2) [m/s^r]."""
        lam = np.atleast_1d(np.asarray(lam, float))
        n = lam.size
        s = [
            ca.mtimes(self.timing.matrix(lam, r), self.coefficients) / self.h**r
            for r in range(orders)
        ]
        Y = path_jet(self.shape, orders).map(n, "serial")(self.points, s[0].T)  # 2 x orders n
        y = chain_rule(orders).map(n, "serial")(Y, ca.horzcat(*s).T)  # 2 x orders n
        return [y[:, r::orders].T for r in range(orders)]

    @property
    def packed(self) -> ca.MX:
        """The phase's control points (column-major) and timing coefficients, as one column."""
        return ca.vertcat(ca.vec(self.points), self.coefficients)


def unpack(path: PathSpec, packed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Control points (count x 2) [m] and timing coefficients of a phase from :attr:`packed`."""
    packed = np.asarray(packed, float).ravel()
    n = len(path.control_points)
    return packed[: 2 * n].reshape(2, n).T, packed[2 * n :]


def chosen_points(paths: list, packed: list) -> dict[str, float]:
    """The free control points the optimizer chose, by name (``path[k].control_points[i].x``
    and ``.y``) [m], for ``free_values``."""
    out = {}
    for k, (path, column) in enumerate(zip(paths, packed, strict=True)):
        points, _ = unpack(path, column)
        for i, point in enumerate(path.control_points):
            if not isinstance(point, list):
                out[f"path[{k}].control_points[{i}].x"] = float(points[i, 0])
                out[f"path[{k}].control_points[{i}].y"] = float(points[i, 1])
    return out


def to_pieces(path: PathSpec, packed: np.ndarray, t0: float, h: float):
    """A solved phase as exact polynomial pieces (a :class:`cpopt.paths.TimedPath`)."""
    points, coefficients = unpack(path, packed)
    shape = PathShape(path.degree, len(path.control_points))
    timing = timing_basis(path)
    return compose(shape, points, timing, coefficients, t0, h)


def zero_orders(problem: Problem, index: int, after: bool) -> tuple[int, ...]:
    """Orders r in 1..3 of node ``index``'s CP derivatives that are zero whatever the optimizer
    chooses (they depend on no freed value); the path meets them with s^(r) = 0 exactly."""
    arm = problem.arm
    name = node_names(len(problem.nodes))[index]
    freed = freed_fields(name, problem.free, problem.nodes[index], after)
    P = flat.output(problem.nodes[index].state(after), arm.K, arm.gravity)
    fields = order_fields(arm.K, arm.gravity)
    return tuple(r for r in range(1, 4) if np.linalg.norm(P[:, r]) < ZERO and not fields[r] & freed)


def structure(problem: Problem) -> tuple:
    """What of a problem's values shapes a path-timing NLP (a key of the NLP cache): the
    paths, and the orders that are zero at each phase's ends."""
    o = problem.spec.optimizer
    n = len(problem.nodes)
    zeros = tuple(
        (zero_orders(problem, k, True), zero_orders(problem, k + 1, False)) for k in range(n - 1)
    )
    return tuple(p.model_dump_json() for p in o.path), zeros


def _points(path: PathSpec, k: int, head, tail, layout: Layout) -> ca.MX:
    """Control points (count x 2): the nodes' CPs at the ends, the file's fixed points, and
    decision variables for the free ones (bounded as the file says)."""
    rows = [head.T]
    for i, point in enumerate(path.control_points[1:-1], start=1):
        if isinstance(point, list):
            rows.append(ca.DM(point).T)
            continue
        lo, hi = zip(
            *[(-np.inf if a is None else a, np.inf if b is None else b) for a, b in point.bounds],
            strict=True,
        )
        rows.append(
            layout.add(
                f"phase[{k}].control_points[{i}]",
                "control_points",
                ca.MX.sym(f"Y{k}_{i}", 1, 2),
                phase=k,
                rows=(i, i + 1),
                bounds=(np.array(lo), np.array(hi)),
            )
        )
    rows.append(tail.T)
    return ca.vertcat(*rows)


def _end_timing(jet, zeros: tuple, Y, start: bool, h):
    """The timing law's value and normalised derivatives at one end (pinned orders), and the
    normal residuals (order, expression) to constrain."""
    count = int(jet.shape[1])
    y = ca.horzcat(jet, ca.MX.zeros(2, ORDERS - count))
    s, normal = end_conditions()(Y, y)
    first = next((r for r in range(1, count) if r not in zeros), count)
    values = [ca.MX(1, 1) if start else ca.MX(1.0)]  # s = 0 (structurally zero) or s = 1
    residuals = []
    for r in range(1, count):
        if r < first:
            values.append(ca.MX(1, 1))  # structurally zero: no constraint, no dependence
            continue
        values.append(h**r * s[r - 1])
        residuals.append((r, normal[r - 1]))
    return ca.vertcat(*values), residuals


def lower_inverse(L: np.ndarray) -> np.ndarray:
    """The inverse of a small lower-triangular matrix by forward substitution: exact zeros
    above the diagonal (its structure), and no ``scipy.linalg`` import (0.2-0.4 s of a fresh
    process, for matrices of at most five rows)."""
    n = L.shape[0]
    X = np.zeros((n, n))
    for j in range(n):
        for i in range(j, n):
            X[i, j] = ((i == j) - L[i, j:i] @ X[j:i, j]) / L[i, i]
    return X


def _timing(path: PathSpec, k: int, ends: list, h, layout: Layout) -> ca.MX:
    """Timing coefficients: the ends eliminated (triangular solves keep the structural zeros
    of a node where the CP's first derivatives vanish), the inner ones decisions."""
    basis = timing_basis(path)
    (head, _), (tail, _) = ends
    r0, r1 = int(head.numel()), int(tail.numel())
    E0 = basis.end_matrices(r0)[0]
    E1 = basis.end_matrices(r1)[1]
    c_head = ca.mtimes(ca.sparsify(ca.DM(lower_inverse(E0))), head)
    # at s = 1 derivative r involves the last r + 1 coefficients: reversed, E1 is triangular
    c_tail = ca.mtimes(ca.sparsify(ca.DM(lower_inverse(E1[:, ::-1])[::-1])), tail)
    m = basis.count
    parts = [c_head]
    if m > r0 + r1:
        parts.append(
            layout.add(
                f"phase[{k}].timing[{r0}:{m - r1}]",
                "timing",
                ca.MX.sym(f"s{k}", m - r0 - r1),
                phase=k,
                rows=(r0, m - r1),
            )
        )
    parts.append(c_tail)
    return ca.vertcat(*parts)


def phase_curve(
    path: PathSpec,
    k: int,
    h,
    jets: tuple,
    zeros: tuple,
    layout: Layout,
    g: Constraints,
    names: tuple[str, str],
) -> PathTimingCurve:
    """Phase k's curve, decision blocks and boundary constraints.

    Parameters
    ----------
    path : PathSpec
        The phase's ``optimizer.path`` entry.
    k : int
        Phase index.
    h : casadi.MX
        The phase's duration [s].
    jets : tuple of casadi.MX
        The CP derivatives 0..R-1 at the phase's start and end nodes (2 x R each, R = 4, or 5
        where the fourth is pinned) [m/s^r].
    zeros : tuple of tuple of int
        Orders that are zero at the start and end node whatever the optimizer chooses.
    layout, g
        The NLP's decision blocks and constraints, appended to.
    names : tuple of str
        The two nodes' names, for constraint labels.
    """
    shape = PathShape(path.degree, len(path.control_points))
    points = _points(path, k, jets[0][:, 0], jets[1][:, 0], layout)
    ends = []
    for jet, zero, at_end in ((jets[0], zeros[0], False), (jets[1], zeros[1], True)):
        Y = ca.mtimes(ca.DM(shape.end_matrix(at_end)), points).T
        ends.append(_end_timing(jet, zero, Y, not at_end, h))
        _tangent_constraint(g, Y[:, 1], points, layout, k, names[at_end], float(at_end))
    c = _timing(path, k, ends, h, layout)
    decisions = layout.vector()
    for (_, residuals), name, where in zip(ends, names, (0.0, 1.0), strict=True):
        for r, expr in residuals:
            if ca.depends_on(expr, decisions):
                g.add(expr, 0, 0, f"path meets {name}: order {r} (phase {k + 1})", [(k, where)])
    steps = c[1:] - c[:-1]
    m = int(c.numel())
    where = [(k, (i + 0.5) / (m - 1)) for i in range(m - 1)]
    # steps between coefficients that are numbers (0 or 1, where a node's first derivatives
    # vanish) hold by construction; the rest are constraints
    keep = [i for i in range(m - 1) if ca.symvar(steps[i])]
    if keep:
        g.add(steps[keep], 0, ca.inf, f"timing s' >= 0 (phase {k + 1})", [where[i] for i in keep])
    return PathTimingCurve(shape, timing_basis(path), points, c, h)


def _tangent_constraint(g, tangent, points, layout: Layout, k: int, name: str, where) -> None:
    """|Y'|^2 >= TANGENT_MIN^2 + (TANGENT_RATIO |chord|)^2 at an end whose tangent the
    optimizer chooses."""
    if ca.depends_on(tangent, layout.vector()):
        chord = points[-1, :] - points[0, :]
        g.add(
            ca.sumsqr(tangent) - TANGENT_RATIO**2 * ca.sumsqr(chord),
            TANGENT_MIN**2,
            ca.inf,
            f"path tangent at {name} (phase {k + 1})",
            [(k, where)],
        )


def initial_blocks(problem: Problem) -> dict[str, np.ndarray]:
    """First initial values of the path-timing blocks by name: free control points at the
    file's values; timing coefficients on the smoothstep of degree 9 (zero derivatives 1..4 at
    both ends) at the Greville abscissae, non-decreasing from 0 to 1 (:func:`timing_guess`
    then bends them to the ends the nodes fix)."""
    out = {}
    for k, path in enumerate(problem.spec.optimizer.path):
        for i, point in enumerate(path.control_points):
            if not isinstance(point, list):
                out[f"phase[{k}].control_points[{i}]"] = np.array([point.x, point.y])
        basis = timing_basis(path)
        knots, e = basis.knots, basis.degree
        greville = np.array([knots[i + 1 : i + 1 + e].mean() for i in range(basis.count)])
        smooth = np.polynomial.Polynomial([0, 0, 0, 0, 0, 126, -420, 540, -315, 70])(greville)
        out[f"phase[{k}].timing"] = smooth
    return out


def timing_guess(path: PathSpec, coefficients: np.ndarray, rows: tuple[int, int]) -> np.ndarray:
    """Inner timing coefficients that join the ends the nodes fixed smoothly: the least-squares
    fit of the Hermite polynomial matching the timing law's derivatives at both ends.

    Parameters
    ----------
    path : PathSpec
        The phase's path (its timing basis).
    coefficients : numpy.ndarray
        All timing coefficients, the eliminated ends as the nodes fix them.
    rows : tuple of int
        The inner coefficients [lo, hi).
    """
    basis = timing_basis(path)
    c = np.asarray(coefficients, float).ravel()
    lo, hi = rows
    head = [basis.matrix([0.0], r)[0] @ c for r in range(lo)]
    tail = [basis.matrix([1.0], r)[0] @ c for r in range(basis.count - hi)]
    n = max(len(head), len(tail))
    ends = [np.pad(v, (0, n - len(v))) for v in (head, tail)]
    target = hermite(0.0, 1.0, np.vstack([ends[0]] * 2), np.vstack([ends[1]] * 2))
    lam = np.linspace(0.0, 1.0, 200)
    B = basis.matrix(lam, 0)
    rhs = target.derivatives(lam, 0)[:, 0, 0] - B[:, :lo] @ c[:lo] - B[:, hi:] @ c[hi:]
    inner, *_ = np.linalg.lstsq(B[:, lo:hi], rhs, rcond=None)
    return inner


__all__ = [
    "TANGENT_MIN",
    "TANGENT_RATIO",
    "PathTimingCurve",
    "chosen_points",
    "initial_blocks",
    "lower_inverse",
    "phase_curve",
    "structure",
    "timing_basis",
    "timing_guess",
    "to_pieces",
    "unpack",
    "zero_orders",
]
