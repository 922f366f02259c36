"""Rest ends held at the holding torque: where the flat optimizer pins a motion's end at rest
to xi = 0 with the base still (``smooth_torque``), by the sign of gamma of its phase."""

from __future__ import annotations

import numpy as np

from ..closedform.nodes import node_names
from .build import Problem


def rest_ends(problem: Problem) -> list[bool]:
    """Per node: a start or goal at rest whose velocities are not freed."""
    names = node_names(len(problem.nodes))
    out = []
    for i, (name, node) in enumerate(zip(names, problem.nodes, strict=True)):
        end = i in (0, len(problem.nodes) - 1)
        fixed_still = all(
            f"{name}.{f}" not in problem.free for f in ("xdot", "ydot", "thetadot_deg")
        )
        out.append(end and fixed_still and node.at_rest)
    return out


def holding_possible(problem: Problem, sign: int, index: int) -> bool:
    """Can the rest end ``index`` sit at the holding torque (xi = 0, base still) with this sign?"""
    name = node_names(len(problem.nodes))[index]
    node = problem.nodes[index]
    if f"{name}.theta_deg" in problem.free:
        return False
    if f"{name}.xi" not in problem.free and node.xi != 0:
        return False
    gamma_min = problem.spec.optimizer.gamma_min
    return sign * problem.arm.gravity * np.sin(node.theta) >= max(gamma_min, 1e-3)


def holding_pattern(problem: Problem, signs: tuple[int, ...]) -> tuple[bool, ...]:
    """Per node: held at the holding torque (a rest end, ``smooth_torque``, and possible with
    the sign of gamma of the phase it starts or ends: ``signs[0]`` or ``signs[-1]``)."""
    smooth = problem.spec.optimizer.smooth_torque
    # a rest end is the start or the goal: the first phase's sign or the last's (``signs`` may
    # also be a pattern's, with more phases than the problem's nodes make)
    return tuple(
        rest and smooth and holding_possible(problem, signs[0] if i == 0 else signs[-1], i)
        for i, rest in enumerate(rest_ends(problem))
    )


__all__ = ["holding_pattern", "holding_possible", "rest_ends"]
