"""gamma at the nodes: its sides (arrival, departure after a xi reset), its segments between
resets, and the checks of its value and sign against the optimizer's settings."""

from __future__ import annotations

import itertools
from dataclasses import dataclass

from ..closedform.nodes import gamma_is_free, has_reset
from ..closedform.plan import GAMMA_ZERO
from ..model import flat
from ..model.robot import G0, Arm
from .schema import OptimizerSpec, ProblemError


@dataclass(frozen=True)
class GammaSide:
    """gamma on one side of a node: on arrival, or on departure after a xi reset.

    Attributes
    ----------
    gamma : float
        Its value at the file's values [m/s^2].
    fixed : bool
        True when no freed value moves it.
    path : str
        The key path of the xi that sets it (``motion.via[0].xi_after``).
    index : int
        The node's index in the motion.
    after : bool
        True on departure from a via state that resets xi.
    """

    gamma: float
    fixed: bool
    path: str
    index: int = 0
    after: bool = False


def gamma_sides(arm: Arm, nodes, paths, free) -> tuple[list[GammaSide], list[GammaSide]]:
    """gamma on arrival at each node and on departure (after a via state's xi reset; the same
    object as on arrival where xi is not reset)."""
    arrive, leave = [], []
    for i, (node, path) in enumerate(zip(nodes, paths, strict=True)):
        name = path.removeprefix("motion.")
        gam = float(flat.gamma(node.state(), arm.K, arm.gravity))
        arrive.append(GammaSide(gam, not gamma_is_free(name, free), f"{path}.xi", i))
        if 0 < i < len(nodes) - 1 and has_reset(node, name, "xi", free):
            after = float(flat.gamma(node.state(after=True), arm.K, arm.gravity))
            fixed = not gamma_is_free(name, free, "xi_after")
            leave.append(GammaSide(after, fixed, f"{path}.xi_after", i, True))
        else:
            leave.append(arrive[-1])
    return arrive, leave


def gamma_segments(arrive: list[GammaSide], leave: list[GammaSide]) -> list[list[GammaSide]]:
    """The fixed sides of gamma in order, split where xi is reset: within one segment gamma is
    continuous, so it keeps one sign unless the optimizer adds switches."""
    segments = [[arrive[0]]]
    for i in range(1, len(arrive)):
        segments[-1].append(arrive[i])
        if leave[i] is not arrive[i]:
            segments.append([leave[i]])
    return [[s for s in seg if s.fixed] for seg in segments]


def check_gamma(spec, arm, nodes, paths, free, source) -> tuple[list, list]:
    """gamma != 0 where it is fixed, and one sign between xi resets unless the optimizer may
    add switches (as many as the sign changes); returns the sides of :func:`gamma_sides`."""
    switches = 0 if spec.planner == "closed_form" else spec.optimizer.gamma_switches
    arrive, leave = gamma_sides(arm, nodes, paths, free)
    for side in (*arrive, *leave):
        if side.fixed and abs(side.gamma) < GAMMA_ZERO:
            raise ProblemError(
                source,
                side.path,
                f"gamma = xi - K thetadot^2 + g0 sin(theta) = {side.gamma:.3g} m/s^2 at "
                "this node: the flat map is singular there; choose xi so that gamma != 0",
            )
    needed = 0
    for segment in gamma_segments(arrive, leave):
        changes = sum(a.gamma * b.gamma < 0 for a, b in itertools.pairwise(segment))
        if changes and switches == 0:
            _refuse_sign_change(spec, arm, nodes, segment, source)
        needed += changes
    if switches != "auto" and needed > switches:
        raise ProblemError(
            source,
            "optimizer.gamma_switches",
            f"the fixed values of gamma change sign {needed} times where xi is not reset and "
            f"need a switch each, got {switches}",
        )
    return arrive, leave


def _refuse_sign_change(spec, arm: Arm, nodes, segment: list[GammaSide], source: str) -> None:
    """Refuse fixed values of gamma of both signs between two xi resets, blaming the odd
    side (or ``arm.gravity``) and saying which xi gives it the others' sign."""
    values = ", ".join(
        f"{s.gamma:+.3g} {'after' if s.after else 'at'} {s.path.rsplit('.', 1)[0]}" for s in segment
    )
    where = "over the motion" if len(segment) == len(nodes) else "between xi resets"
    intro = (
        f"gamma = xi - K thetadot^2 + g0 sin(theta) changes sign {where} ({values} "
        "m/s^2), so it vanishes in between; it keeps one sign where xi is not reset (it is "
        "continuous at via states)"
    )
    hint = "; or reset xi at a via state (xi_after), or let the optimizer add switches "
    hint += "(optimizer.gamma_switches)"
    if _gravity_at_fault(spec, arm, nodes, segment):
        raise ProblemError(
            source,
            "arm.gravity",
            f"{intro}. With the standard {G0} m/s^2 the signs agree: the node values look chosen "
            f"for it; choose xi for gravity {arm.gravity:g} m/s^2 or change arm.gravity{hint}",
        )
    odd = _odd_one_out(nodes, segment)
    sign = -1.0 if odd.gamma > 0 else 1.0
    margin = max(spec.optimizer.gamma_min, 1.0)
    xi = nodes[odd.index].state(odd.after)[6] - odd.gamma + sign * margin
    raise ProblemError(
        source,
        odd.path,
        f"{intro}. Here it has the sign of the fewer nodes: {odd.path.rsplit('.', 1)[1]} "
        f"{'>=' if sign > 0 else '<='} "
        f"{xi:.4g} m/s^2 gives it the others' sign with |gamma| >= {margin:g}{hint}",
    )


def _gravity_at_fault(spec, arm: Arm, nodes, segment: list[GammaSide]) -> bool:
    """True when the file changed gravity and the standard one gives every fixed side one sign."""
    if "gravity" not in spec.arm.model_fields_set or arm.gravity == G0:
        return False
    gam = [float(flat.gamma(nodes[s.index].state(s.after), arm.K, G0)) for s in segment]
    return min(abs(g) for g in gam) >= GAMMA_ZERO and len({g > 0 for g in gam}) == 1


def _odd_one_out(nodes, segment: list[GammaSide]) -> GammaSide:
    """The side to blame for a sign change: the first of the smaller group of signs.

    On a tie, the group whose xi the file set away from 0 (chosen by hand; xi = 0 at a rest
    state is a physical fact), else the group holding the later node.
    """
    pos = [s for s in segment if s.gamma > 0]
    neg = [s for s in segment if s.gamma < 0]
    if len(pos) != len(neg):
        return min(pos, neg, key=len)[0]
    pos_set, neg_set = (any(nodes[s.index].state(s.after)[6] != 0 for s in g) for g in (pos, neg))
    if pos_set != neg_set:
        return (pos if pos_set else neg)[0]
    return (pos if segment.index(pos[-1]) > segment.index(neg[-1]) else neg)[0]


def check_signs(o: OptimizerSpec, sides: tuple[list, list], source: str) -> None:
    """``gamma_sign`` (the sign at each phase's start) against the fixed values of gamma, and,
    without switches, against the phase's end and the via states that do not reset xi."""
    if o.gamma_sign is None:
        return
    arrive, leave = sides
    wanted = [{"positive": 1, "negative": -1}.get(s, 0) for s in o.gamma_sign]
    for k, sign in enumerate(wanted):
        ends = [leave[k]] if o.gamma_switches else [leave[k], arrive[k + 1]]
        for side in ends:
            if sign and side.fixed and sign * side.gamma < 0:
                raise ProblemError(
                    source,
                    f"optimizer.gamma_sign[{k}]",
                    f"phase {k + 1} is asked to keep gamma {o.gamma_sign[k]}, but "
                    f"{side.path} fixes gamma = {side.gamma:.3g} m/s^2 at its "
                    f"{'start' if side is leave[k] else 'end'}",
                )
        joined = k and leave[k] is arrive[k]  # no xi reset between phases k and k + 1
        if sign and joined and not o.gamma_switches and wanted[k - 1] == -sign:
            raise ProblemError(
                source,
                f"optimizer.gamma_sign[{k}]",
                f"phases {k} and {k + 1} meet at {arrive[k].path.rsplit('.', 1)[0]} where xi "
                "is not reset, so gamma keeps its sign there; give the same sign, a xi reset "
                "(xi_after) or optimizer.gamma_switches",
            )
