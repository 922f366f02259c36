"""Checks of ``optimizer.path`` (``curve: path_timing``): shapes, bounds, and ends that meet
the nodes' centres of percussion and their derivatives."""

from __future__ import annotations

import numpy as np

from ..closedform.nodes import freed_fields, node_names
from ..closedform.paths import PathShape, node_mismatch, order_fields
from ..closedform.plan import Node
from ..model import flat
from ..model.robot import Arm
from .messages import interval
from .schema import FreePointSpec, PathSpec, ProblemError, ProblemSpec


def check_paths(spec: ProblemSpec, arm: Arm, nodes, free: dict, source: str) -> None:
    """``optimizer.path``: one per phase with ``curve: path_timing`` (and only then), shapes
    that make the CP smooth enough, ends at the nodes' CPs, and paths that can meet the nodes'
    CP derivatives wherever these are fixed."""
    o = spec.optimizer
    if o.path is None:
        if o.curve == "path_timing":
            raise ProblemError(
                source, "optimizer.path", "curve: path_timing needs a path per phase (degree, "
                "control_points, timing)",
            )  # fmt: skip
        return
    if o.curve != "path_timing":
        raise ProblemError(
            source, "optimizer.path", f"a path is used with curve: path_timing, not {o.curve}"
        )
    if len(o.path) != len(nodes) - 1:
        raise ProblemError(
            source,
            "optimizer.path",
            f"give one path per phase ({len(nodes) - 1}), got {len(o.path)}",
        )
    names = node_names(len(nodes))
    for k, path in enumerate(o.path):
        key = f"optimizer.path[{k}]"
        _check_path_shape(path, key, 5 if o.smooth_torque else 4, source)
        _check_point_bounds(path, key, source)
        points = _tied_points(arm, nodes, names, path, k, free, source)
        for i, at_end in ((k, False), (k + 1, True)):
            _check_path_end(arm, nodes[i], names[i], path, points, key, at_end, free, source)


def _check_point_bounds(path: PathSpec, key: str, source: str) -> None:
    """Each free control point: bounds in order, and its guess (x, y) within them."""
    for i, point in enumerate(path.control_points):
        if not isinstance(point, FreePointSpec):
            continue
        where = f"{key}.control_points[{i}]"
        for axis, guess, (lo, hi) in zip("xy", (point.x, point.y), point.bounds, strict=True):
            if lo is not None and hi is not None and lo > hi:
                raise ProblemError(
                    source,
                    f"{where}.bounds[{'xy'.index(axis)}]",
                    f"lower bound {lo:g} exceeds upper bound {hi:g} (bounds are [[x_lo, x_hi], "
                    "[y_lo, y_hi]] [m])",
                )
            if (lo is not None and guess < lo) or (hi is not None and guess > hi):
                raise ProblemError(
                    source,
                    f"{where}.{axis}",
                    f"the initial guess {axis} = {guess:g} m lies outside the bounds "
                    f"{interval(lo, hi)}",
                )


def _tied_points(arm: Arm, nodes, names, path: PathSpec, k: int, free, source) -> np.ndarray:
    """Phase k's control points (free ones at their guess) with the ends at the nodes' CPs,
    having checked the file's ends against the nodes whose position is fixed."""
    points = np.array([p if isinstance(p, list) else [p.x, p.y] for p in path.control_points])
    for i, end, at_end in ((k, 0, False), (k + 1, len(points) - 1, True)):
        cp = flat.output(nodes[i].state(after=not at_end), arm.K, arm.gravity)[:, 0]
        fixed = not {"x", "y", "theta_deg"} & freed_fields(names[i], free, nodes[i], not at_end)
        if fixed and np.hypot(*(points[end] - cp)) > 1e-4:
            raise ProblemError(
                source, f"optimizer.path[{k}].control_points[{end}]", f"the path's ends are "
                f"the nodes' CPs: {names[i]}'s CP is at ({cp[0]:.7g}, {cp[1]:.7g}) m, got "
                f"[{points[end][0]:g}, {points[end][1]:g}]",
            )  # fmt: skip
        points[end] = cp
    return points


def _check_path_shape(path: PathSpec, key: str, ends: int, source: str) -> None:
    n, d = len(path.control_points), path.degree
    if n < d + 1:
        raise ProblemError(
            source, f"{key}.control_points", f"a degree-{d} path needs at least {d + 1} control "
            f"points, got {n}",
        )  # fmt: skip
    if n > d + 1 and d < 4:
        raise ProblemError(
            source, f"{key}.degree", f"a B-spline path (more than degree + 1 control points) must "
            "be three times differentiable where the CP crosses its knots (the arm's state "
            f"depends on the CP's jerk): degree >= 4, got {d}; or give {d + 1} control points "
            "(a Bezier curve)",
        )  # fmt: skip
    need = max(2 * ends, path.timing.degree + 1)
    if path.timing.coefficients < need:
        raise ProblemError(
            source, f"{key}.timing.coefficients", f"{path.timing.coefficients} coefficients "
            f"cannot hold {ends} conditions at each end of a degree-{path.timing.degree} timing "
            f"law (need >= {need})",
        )  # fmt: skip
    for i in (0, n - 1):
        if not isinstance(path.control_points[i], list):
            raise ProblemError(
                source, f"{key}.control_points[{i}]", "the path's ends are tied to the nodes' "
                "CPs: write them as [x, y] (free the node's x, y or theta_deg to move them)",
            )  # fmt: skip


def _check_path_end(
    arm: Arm, node: Node, name: str, path: PathSpec, points: np.ndarray, key: str,
    at_end: bool, free: dict, source: str,
) -> None:  # fmt: skip
    """Can the path meet the node's CP derivatives of the orders whose values are fixed (and
    whose control points are fixed)? ``points`` holds the control points (free ones at their
    guess), the ends at the nodes' CPs."""
    n = len(points)
    P = flat.output(node.state(after=not at_end), arm.K, arm.gravity)
    freed = freed_fields(name, free, node, after=not at_end)
    fields = order_fields(arm.K, arm.gravity)
    fixed = 0  # highest order whose node values and control points are all fixed
    order = [n - 1 - j for j in range(n)] if at_end else list(range(n))
    for r in range(4):
        if fields[r] & freed or (r < n and not isinstance(path.control_points[order[r]], list)):
            break
        fixed = r
    shape = PathShape(path.degree, n)
    Y = (shape.end_matrix(at_end) @ np.asarray(points, float)).T
    problem = node_mismatch(Y, P, fixed, at_end) if fixed else None
    if problem:
        raise ProblemError(source, f"{key}.control_points[{order[1]}]", f"{name}: {problem}")
