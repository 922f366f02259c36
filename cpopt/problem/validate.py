"""The checks across keys of a problem (physics, limits, free values, optimizer settings), each
raising :class:`ProblemError` with the key path at fault; the arm and nodes they yield."""

from __future__ import annotations

import importlib.util
import math

import numpy as np

from ..closedform.nodes import free_value_names
from ..closedform.plan import GAMMA_ZERO, Node
from ..io.keypath import leaves
from ..io.safe_yaml import echo, key_path
from ..model.dynamics import holding_torque
from ..model.kinematics import ReachError, inverse_derivatives, inverse_position
from ..model.limits import torque_headroom
from ..model.objectives import COLLOCATION_OBJECTIVES, LEAST_SQUARES, LINEAR, weights
from ..model.robot import BRANCHES, Arm, Link
from .gamma import check_gamma, check_signs
from .messages import interval, suggestion
from .path_checks import check_paths
from .schema import ArmSpec, ProblemError, ProblemSpec, StateSpec


def _node(state: StateSpec, t: float) -> Node:
    return Node(
        t=t,
        x=state.x,
        y=state.y,
        theta=math.radians(state.theta_deg),
        xdot=state.xdot,
        ydot=state.ydot,
        thetadot=math.radians(state.thetadot_deg),
        xi=state.xi,
        eta=state.eta,
        eta_after=getattr(state, "eta_after", None),
        xi_after=getattr(state, "xi_after", None),
    )


def check_physics(spec: ProblemSpec, source: str) -> tuple[Arm, tuple[Node, ...]]:
    """Every check across keys, in the order the user should fix them; the arm and its nodes.

    Raises
    ------
    ProblemError
        Naming the source, the key path and what was expected.
    """
    _check_ranges(spec, source)
    arm = _arm(spec.arm, source)
    m = spec.motion
    T = m.duration
    prev = 0.0
    for i, via in enumerate(m.via):
        if not prev < via.t < T:
            raise ProblemError(
                source,
                f"motion.via[{i}].t",
                f"via times must increase strictly inside (0, {T:g}) s, got "
                f"{via.t:g} s after {prev:g} s",
            )
        prev = via.t
    nodes = (_node(m.start, 0.0), *(_node(v, v.t) for v in m.via), _node(m.goal, T))
    paths = ["motion.start", *(f"motion.via[{i}]" for i in range(len(m.via))), "motion.goal"]
    joints = [_joint_position(arm, n, p, source) for n, p in zip(nodes, paths, strict=True)]
    _check_limits(spec, arm, nodes, joints, source)
    free = spec.optimizer.free if spec.planner != "closed_form" else {}
    _check_free(spec, free, source)
    flat_plan = spec.planner != "collocation" or spec.collocation.warm_start == "flat"
    _check_switches(spec, source)
    if flat_plan:
        sides = check_gamma(spec, arm, nodes, paths, free, source)
    if spec.planner != "closed_form" and flat_plan:
        _check_optimizer(spec, len(nodes) - 1, source)
        check_signs(spec.optimizer, sides, source)
        check_paths(spec, arm, nodes, free, source)
    if spec.planner == "collocation":
        _check_collocation(spec, source)
    if spec.tracking is not None:
        check_tracking(spec, source)
    return arm, nodes


def _arm(a: ArmSpec, source: str) -> Arm:
    """The arm of the file, with ``branch: none`` read as the single branch of RPR and PPR."""
    allowed = BRANCHES[a.kind]
    branch = None if a.branch is None or a.branch.lower() == "none" else a.branch
    if a.branch is not None and branch not in allowed:
        choices = ", ".join("none" if b is None else b for b in allowed)
        raise ProblemError(
            source, "arm.branch", f"a {a.kind} arm has branches {choices}, got {echo(a.branch)}"
        )
    arm = Arm(
        kind=a.kind,
        links=tuple(Link(l.length, l.mass, l.com, l.inertia) for l in a.links),  # noqa: E741
        base=a.base,
        gravity=a.gravity,
        branch=branch,
    )
    l3 = a.links[2].length
    if arm.K / l3 > 100:  # (I3 + m3 d3^2) / (m3 d3) grows without bound as d3 -> 0
        raise ProblemError(
            source,
            "arm.links[2].com" if a.links[2].com is not None else "arm.links[2].inertia",
            f"the centre of percussion lies K = {arm.K:.4g} m from the third joint, more than "
            f"100 link lengths ({100 * l3:g} m): the centre of mass is too close to the joint "
            "for its inertia",
        )
    return arm


def _joint_position(arm: Arm, node: Node, path: str, source: str) -> np.ndarray:
    """The joint position (3,) of a node's state, or a ProblemError when it is out of reach."""
    try:
        q = inverse_position(arm, node.x, node.y, node.theta)
        inverse_derivatives(
            arm, q, np.array([[node.xdot, node.ydot, node.thetadot]]), np.zeros((1, 3))
        )
    except ReachError as err:
        raise ProblemError(source, path, f"state not reachable: {err}") from None
    return np.asarray(q, float).ravel()


PHYSICAL_RANGES = {
    "arm.base[]": (-1e3, 1e3, "m"),
    "arm.gravity": (0.1, 100.0, "m/s^2"),
    "arm.links[].length": (1e-3, 100.0, "m"),
    "arm.links[].mass": (1e-3, 1e4, "kg"),
    "motion.duration": (0.01, 1e4, "s"),
    "motion.<node>.theta_deg": (-3600.0, 3600.0, "deg"),
    "motion.<node>.xdot": (-1e3, 1e3, "m/s"),
    "motion.<node>.ydot": (-1e3, 1e3, "m/s"),
    "motion.<node>.thetadot_deg": (-1e5, 1e5, "deg/s"),
    "motion.<node>.xi": (-1e4, 1e4, "m/s^2"),
    "motion.<node>.eta": (-1e6, 1e6, "m/s^3"),
    "motion.<node>.eta_after": (-1e6, 1e6, "m/s^3"),
    "optimizer.gamma_min": (GAMMA_ZERO, 1e3, "m/s^2"),
    "optimizer.limits.torque[]": (0.0, 1e7, "N m or N"),
    "optimizer.limits.joint_position[][]": (-3600.0, 3600.0, "deg or m"),
    "optimizer.limits.joint_velocity[]": (0.0, 1e5, "deg/s or m/s"),
    "optimizer.solver.tol": (1e-12, 1.0, ""),
    "optimizer.solver.max_time": (0.0, 1e6, "s"),
    "verification.poles[]": (-100.0, -1e-2, "1/s"),
}
"""Values cpopt accepts, by key (``[]`` any index, ``<node>`` start, via[i] or goal): outside
them the dynamics are so ill-conditioned that a solve or a simulation would only crawl."""


def _range_key(parts) -> str:
    pattern = key_path(["[]" if isinstance(p, int) else p for p in parts]).replace(".[]", "[]")
    for node in ("motion.start.", "motion.goal.", "motion.via[]."):
        pattern = pattern.replace(node, "motion.<node>.")
    return pattern


def _check_ranges(spec: ProblemSpec, source: str) -> None:
    """Every number within :data:`PHYSICAL_RANGES`; gamma_min > 0; com and inertia vs length."""
    gamma_min = spec.optimizer.gamma_min
    if gamma_min <= 0:
        raise ProblemError(
            source,
            "optimizer.gamma_min",
            f"must be > 0, got {gamma_min:g}: the flat map is singular at gamma = 0 (theta and "
            "the torques are undetermined there), so a plan keeps |gamma| >= gamma_min > 0",
        )
    for parts, value in leaves(spec.model_dump(exclude={"optimizer": {"free"}})):
        if not isinstance(value, int | float) or isinstance(value, bool):
            continue
        value = float(value)
        bounds = PHYSICAL_RANGES.get(_range_key(parts))
        if bounds is not None and not bounds[0] <= value <= bounds[1]:
            lo, hi, unit = bounds
            raise ProblemError(
                source,
                key_path(parts),
                f"{value:g} {unit} lies outside the physical range cpopt accepts, "
                f"[{lo:g}, {hi:g}] {unit} (see 'Physical ranges' in docs/problems.md)",
            )
    for i, link in enumerate(spec.arm.links):
        reach = 10 * link.length
        if link.com is not None and not (0 if i == 2 else -reach) < link.com <= reach:
            where = "beyond its joint, " if i == 2 else ""
            raise ProblemError(
                source,
                f"arm.links[{i}].com",
                f"the centre of mass must lie {where}within 10 link lengths of the joint "
                f"({'0' if i == 2 else f'{-reach:g}'} < com <= {reach:g} m), got {link.com:g} m",
            )
        if link.inertia is not None and link.inertia > link.mass * reach**2:
            raise ProblemError(
                source,
                f"arm.links[{i}].inertia",
                f"{link.inertia:g} kg m^2 exceeds mass * (10 length)^2 = "
                f"{link.mass * reach**2:g} kg m^2, more than any link of this size can have",
            )


def _check_limits(spec, arm: Arm, nodes, joints, source: str) -> None:
    """Joint position bounds in order; torque limits able to hold the arm at its rest ends."""
    lim = spec.optimizer.limits
    for i, pair in enumerate(lim.joint_position or ()):
        if pair is not None and pair[0] > pair[1]:
            raise ProblemError(
                source,
                f"optimizer.limits.joint_position[{i}]",
                f"lower bound {pair[0]:g} exceeds upper bound {pair[1]:g} (give [lower, upper])",
            )
    headroom = _check_headroom(lim, source)
    if all(t is None for t in lim.torque):
        return
    units = ["N m" if r else "N" for r in arm.revolute]
    free = spec.optimizer.free if spec.planner != "closed_form" else {}
    for index, name in ((0, "start"), (len(nodes) - 1, "goal")):
        node = nodes[index]
        # the arm rests at the start before the motion (and at a goal with xi = 0 after it)
        fields = ["x", "y", "theta_deg", "xdot", "ydot", "thetadot_deg"] + ["xi"] * (name == "goal")
        holds = node.at_rest and (name == "start" or node.xi == 0)
        if not holds or any(f"{name}.{f}" in free for f in fields):
            continue
        tau = holding_torque(arm, joints[index])
        for i, tmax in enumerate(lim.torque):
            if tmax is None or abs(tau[i]) <= tmax * (1 - headroom[i]):
                continue
            bound = f"|tau{i + 1}| <= {tmax:g} {units[i]}"
            if abs(tau[i]) <= tmax:  # only the headroom is in the way
                bound = f"{bound} less {100 * headroom[i]:g} % headroom"
            raise ProblemError(
                source,
                f"optimizer.limits.torque{'_headroom' if abs(tau[i]) <= tmax else ''}[{i}]",
                f"{bound} cannot even hold the arm at rest at motion.{name}: the static "
                f"holding torque there is {tau[i]:.4g} {units[i]}",
            )


def _check_headroom(lim, source: str) -> tuple[float, float]:
    """0 <= h < 1 for each joint, and a headroom only where there is a torque limit to take
    it from; the headroom per joint."""
    pair = isinstance(lim.torque_headroom, list)
    for i, h in enumerate(lim.torque_headroom if pair else [lim.torque_headroom]):
        key = f"optimizer.limits.torque_headroom{f'[{i}]' if pair else ''}"
        if not 0 <= h < 1:
            raise ProblemError(
                source,
                key,
                f"{h:g} is not a fraction in [0, 1): give the share of each torque limit the "
                "plan leaves to feedback (0.2 keeps |tau_i| <= 0.8 torque_i)",
            )
        if h > 0 and (lim.torque[i] is None if pair else all(t is None for t in lim.torque)):
            which = f"optimizer.limits.torque[{i}] is" if pair else "no torque limit is"
            raise ProblemError(
                source,
                key,
                f"a headroom of {h:g} is a fraction of a torque limit, but {which} given: "
                "set the limit (the motor's torque) or a headroom of 0",
            )
    return torque_headroom(lim)


def _file_value(spec: ProblemSpec, name: str) -> float:
    """The file's value of a free value's name (its initial guess), in the file's units."""
    if name == "duration":
        return spec.motion.duration
    node, field = name.split(".", 1)
    m = spec.motion
    state = {"start": m.start, "goal": m.goal}.get(node) or m.via[int(node[4:-1])]
    if field.endswith("_after") and getattr(state, field) is None:  # no reset in the file
        return getattr(state, field.removesuffix("_after"))
    return getattr(state, field)


def _check_free(spec: ProblemSpec, free: dict, source: str) -> None:
    """Known names, bounds in order and each guess (the file's value) within its bounds."""
    names = free_value_names(len(spec.motion.via))
    for name, (lo, hi) in free.items():
        key = f"optimizer.free.{key_path([name])}"
        if name not in names:
            raise ProblemError(
                source,
                key,
                f"not a value of this problem{suggestion(name, names)} (names: {', '.join(names)})",
            )
        if lo is not None and hi is not None and lo > hi:
            raise ProblemError(source, key, f"lower bound {lo:g} exceeds upper bound {hi:g}")
        guess = _file_value(spec, name)
        if (lo is not None and guess < lo) or (hi is not None and guess > hi):
            raise ProblemError(
                source,
                key,
                f"the initial guess motion.{name} = {guess:g} lies outside the bounds "
                f"{interval(lo, hi)}; "
                "the file's value is where the optimizer starts",
            )


def _check_switches(spec: ProblemSpec, source: str) -> None:
    """``optimizer.gamma_switches`` only where the flat optimizer's B-spline or polynomial
    curves can take the switches (a path_timing path is drawn through the file's nodes)."""
    o = spec.optimizer
    if o.gamma_switches == 0:
        return
    if spec.planner != "optimize":
        raise ProblemError(
            source,
            "optimizer.gamma_switches",
            f"switches of the sign of gamma are added by planner: optimize, not {spec.planner}",
        )
    if o.curve == "path_timing":
        raise ProblemError(
            source,
            "optimizer.gamma_switches",
            "curve: path_timing draws one path per phase of the file, so the optimizer cannot "
            "add a switch inside one; place the switch by hand (a via state with xi_after) or "
            "use curve: bspline",
        )


def _check_optimizer(spec: ProblemSpec, phases: int, source: str) -> None:
    o = spec.optimizer
    ends = 5 if o.smooth_torque else 4
    why = f"{ends} boundary conditions at each end{' (smooth_torque)' if o.smooth_torque else ''}"
    if o.curve == "path_timing":  # the path block has its own checks (check_paths)
        pass
    elif o.curve == "bspline" and o.coefficients < o.degree + 1:
        # blame the value the file changed: a high degree, unless only coefficients was set
        only_coefficients = {"coefficients"} <= o.model_fields_set and "degree" not in (
            o.model_fields_set
        )
        raise ProblemError(
            source,
            "optimizer.coefficients" if only_coefficients else "optimizer.degree",
            f"a B-spline of degree {o.degree} needs at least {o.degree + 1} coefficients per "
            f"phase, and optimizer.coefficients is {o.coefficients}: lower the degree or raise "
            "the coefficients",
        )
    if o.refine_basis is True and o.curve != "bspline":
        raise ProblemError(
            source,
            "optimizer.refine_basis",
            f"refine_basis halves a B-spline's knot intervals, and optimizer.curve is "
            f"{o.curve}: use curve: bspline, or refine_basis auto or false",
        )
    count = o.coefficients if o.curve == "bspline" else o.degree + 1
    if o.curve != "path_timing" and count < 2 * ends:
        key = "optimizer.coefficients" if o.curve == "bspline" else "optimizer.degree"
        raise ProblemError(
            source,
            key,
            f"{count} coefficients per phase cannot hold {why} (need >= {2 * ends})",
        )
    if o.gamma_sign is not None and len(o.gamma_sign) != phases:
        raise ProblemError(
            source,
            "optimizer.gamma_sign",
            f"give one sign per phase ({phases}), got {len(o.gamma_sign)}",
        )
    if weights(o.objective).get("duration") and "duration" not in o.free:
        raise ProblemError(
            source, "optimizer.objective", "a duration objective needs 'duration' in optimizer.free"
        )
    not_squares = sorted(set(weights(o.objective)) - LEAST_SQUARES - LINEAR)
    if o.solver.hessian == "gauss_newton" and not_squares:
        raise ProblemError(
            source,
            "optimizer.solver.hessian",
            f"gauss_newton needs a least-squares objective ({', '.join(sorted(LEAST_SQUARES))}, "
            f"plus {', '.join(sorted(LINEAR))}); {', '.join(not_squares)} is not one: use exact",
        )


def _check_collocation(spec: ProblemSpec, source: str) -> None:
    o = spec.optimizer
    terms = weights(o.objective)
    unsupported = sorted(k for k in terms if k not in COLLOCATION_OBJECTIVES)
    if unsupported:
        raise ProblemError(
            source,
            "optimizer.objective",
            f"the collocation planner minimizes {', '.join(COLLOCATION_OBJECTIVES)}; "
            f"{', '.join(unsupported)} belongs to the flat optimizer (v is the CP's fourth "
            "derivative; |power| under piecewise-constant torques has no smooth transcription)",
        )
    if terms.get("duration") and "duration" not in o.free:
        raise ProblemError(
            source, "optimizer.objective", "a duration objective needs 'duration' in optimizer.free"
        )
    if spec.collocation.solver == "fatrop":
        _check_fatrop(spec, source)


def _check_fatrop(spec: ProblemSpec, source: str) -> None:
    """Fatrop needs the single-stage, fixed-time structure it detects (see docs/problems.md)."""
    why = None
    if spec.motion.via:
        why = (
            f"fatrop solves single-phase problems only (this one has {len(spec.motion.via) + 1} "
            "phases: rockit's multi-stage transcription defeats Fatrop's structure detection)"
        )
    elif spec.collocation.method != "multiple_shooting":
        why = "fatrop needs collocation.method: multiple_shooting (rockit's direct collocation "
        why += "does not give Fatrop its stage structure)"
    elif {"duration"} & set(spec.optimizer.free) or "gamma_margin" in weights(
        spec.optimizer.objective
    ):
        why = "fatrop needs a fixed duration and no gamma_margin objective (a free time or a "
        why += "margin variable is shared by all stages, which Fatrop's structure cannot hold)"
    if why:
        raise ProblemError(source, "collocation.solver", why + "; use solver: ipopt")


def plant_links(spec: ProblemSpec) -> list[Link]:
    """The plant's links: each key of ``tracking.plant.links[i]`` overrides the arm's value;
    a key given nowhere takes the usual default (uniform rod), so a link given only a new
    mass stays a uniform rod."""
    overrides = (spec.tracking.plant.links if spec.tracking else None) or [None] * 3
    links = []
    for model, new in zip(spec.arm.links, overrides, strict=True):
        values = model.model_dump()
        if new is not None:
            values.update({k: v for k, v in new.model_dump().items() if v is not None})
        links.append(Link(values["length"], values["mass"], values["com"], values["inertia"]))
    return links


def _check_mujoco_actuators(spec: ProblemSpec, source: str) -> None:
    """The MuJoCo plant has no actuation delay or torque noise (it has the gains)."""
    plant = spec.tracking.plant
    if plant.engine != "mujoco":
        return
    for key, value, none in (
        ("delay", plant.delay, 0.0),
        ("torque_noise", plant.torque_noise, [0.0, 0.0]),
    ):
        if value != none:
            raise ProblemError(
                source,
                f"tracking.plant.{key}",
                f"the mujoco plant has no {key.replace('_', ' ')}: got {value}; "
                "use the built-in plant (engine: cpopt)",
            )


def check_tracking(spec: ProblemSpec, source: str) -> None:
    """The ``tracking`` block's physics: a valid plant third link, a controller for the plan,
    MuJoCo installed for ``plant.engine: mujoco``."""
    if spec.tracking.plant.engine == "mujoco" and importlib.util.find_spec("mujoco") is None:
        raise ProblemError(
            source,
            "tracking.plant.engine",
            "mujoco needs MuJoCo, which is not installed: pip install 'cpopt[mujoco]', or use "
            "the built-in plant (engine: cpopt)",
        )
    _check_mujoco_actuators(spec, source)
    com3 = plant_links(spec)[2].d
    if not com3 > 0:
        raise ProblemError(
            source,
            "tracking.plant.links[2].com",
            "the plant's third link needs its centre of mass beyond its joint (> 0 m), "
            f"got {com3!r}",
        )
    if spec.tracking.controller == "flat_mpc" and (
        spec.planner != "optimize" or spec.optimizer.curve == "path_timing"
    ):
        raise ProblemError(
            source,
            "tracking.controller",
            "flat_mpc re-plans with the flat optimizer: it needs planner: optimize with "
            f"B-spline curves (got planner: {spec.planner}, optimizer.curve: "
            f"{spec.optimizer.curve}); use tvlqr",
        )
    if (
        spec.tracking.controller == "dfl"
        and spec.planner == "collocation"
        and not spec.collocation.gamma_constraint
    ):
        raise ProblemError(
            source,
            "tracking.controller",
            "dfl needs gamma away from zero along the plan, which a collocation plan without "
            "collocation.gamma_constraint does not guarantee; use tvlqr or set "
            "collocation.gamma_constraint: true",
        )
