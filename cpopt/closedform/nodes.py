"""Nodes by name: which nodes a motion has, the fields of a node, file <-> SI units, and the
names by which a value can be freed for the optimizer.

A motion passes through ``start``, ``via[0]``, ``via[1]``, ... and ``goal``. A value is named
``<node>.<field>`` with the field as the problem file spells it (``start.theta_deg``,
``via[0].eta_after``, ``via[0].t``) or ``duration``. Files give angles in degrees; in code every
value is SI and in radians, whatever its name says: ``values["start.theta_deg"]`` is radians.
Via states a planner adds to switch the sign of gamma are named ``switch[0]``, ``switch[1]``,
... in its results.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

from .plan import Node

NODE_FIELDS = ("x", "y", "theta_deg", "xdot", "ydot", "thetadot_deg", "xi", "eta")
"""Fields of every node, as the problem file names them."""
VIA_FIELDS = (*NODE_FIELDS, "xi_after", "eta_after", "t")
"""Fields of a via state: a node's, the xi and eta resets and the time [s]."""
ANGLE_FIELDS = frozenset({"theta_deg", "thetadot_deg"})
"""Fields given in degrees (deg, deg/s) in files and held in radians in code."""
GAMMA_FIELDS = ("xi", "theta_deg", "thetadot_deg")
"""The fields gamma = xi - K thetadot^2 + g0 sin(theta) depends on (on arrival; after a via
state's xi reset, ``xi_after`` takes the place of ``xi``)."""
MIN_PHASE = 0.05
"""Shortest phase [s] a planner may choose when node times are free."""

_NODE_ATTRIBUTE = {"theta_deg": "theta", "thetadot_deg": "thetadot"}


def node_names(count: int, switches: Sequence[int] = ()) -> list[str]:
    """Names of ``count`` nodes: ``start``, ``via[0]``, ..., ``goal``.

    ``switches`` are the indices of via states a planner added (``switch[0]``, ...); the other
    via states keep the numbers the problem file gives them.
    """
    names, vias, added = ["start"], 0, 0
    for i in range(1, count - 1):
        if i in switches:
            names.append(f"switch[{added}]")
            added += 1
        else:
            names.append(f"via[{vias}]")
            vias += 1
    return [*names, "goal"]


def to_si(name: str, value: float) -> float:
    """A value of the named field from file units (degrees) to SI (radians)."""
    return math.radians(value) if name.split(".")[-1] in ANGLE_FIELDS else float(value)


def to_file(name: str, value: float) -> float:
    """A value of the named field from SI (radians) to file units (degrees)."""
    return math.degrees(value) if name.split(".")[-1] in ANGLE_FIELDS else float(value)


def free_value_names(via_count: int) -> list[str]:
    """Every name a value can be freed by in ``optimizer.free``, for a motion with
    ``via_count`` via states."""
    names = ["duration", *(f"start.{f}" for f in NODE_FIELDS)]
    for i in range(via_count):
        names += [f"via[{i}].{f}" for f in VIA_FIELDS]
    return names + [f"goal.{f}" for f in NODE_FIELDS]


def node_values(nodes: Sequence[Node]) -> dict[str, float]:
    """Every value of a motion by name, SI units (see the module docstring).

    A via state without a reset has ``xi_after`` (``eta_after``) equal to its ``xi`` (``eta``).
    """
    out = {"duration": nodes[-1].t - nodes[0].t}
    for name, node in zip(node_names(len(nodes)), nodes, strict=True):
        for f in NODE_FIELDS:
            out[f"{name}.{f}"] = float(getattr(node, _NODE_ATTRIBUTE.get(f, f)))
        if name.startswith("via"):
            out[f"{name}.t"] = float(node.t)
            after = node.state(after=True)
            out[f"{name}.xi_after"] = float(after[6])
            out[f"{name}.eta_after"] = float(after[7])
    return out


def nodes_from_values(
    values: Mapping[str, float], count: int, xi: Mapping[str, float] | None = None
) -> list[Node]:
    """The nodes a set of values by name (SI units) describes.

    ``xi`` overrides xi by node name (``start``, ``via[0]``) and xi after a via state's reset
    by ``via[i].xi_after``.
    """
    names = node_names(count)
    times = [0.0, *(values[f"{v}.t"] for v in names[1:-1]), values["duration"]]
    nodes = []
    for t, name in zip(times, names, strict=True):
        fields = {_NODE_ATTRIBUTE.get(f, f): values[f"{name}.{f}"] for f in NODE_FIELDS}
        if xi and name in xi:
            fields["xi"] = xi[name]
        resets = {}
        for f in ("xi", "eta"):
            after = values.get(f"{name}.{f}_after")
            if f == "xi" and xi and f"{name}.xi_after" in xi:
                after = xi[f"{name}.xi_after"]
            resets[f"{f}_after"] = None if after is None or after == fields[f] else after
        nodes.append(Node(t=t, **resets, **fields))
    return nodes


def has_reset(node: Node, name: str, field: str, free: Mapping) -> bool:
    """True when a via state may reset ``field`` (``xi`` or ``eta``): the file gives
    ``<field>_after`` or frees it. Otherwise the value after the node is the value on arrival,
    whether that is fixed or free."""
    return getattr(node, f"{field}_after") is not None or f"{name}.{field}_after" in free


def gamma_is_free(node: str, free: Mapping, xi: str = "xi") -> bool:
    """True when gamma at a node (``start``, ``via[i]``, ``goal``) depends on a freed value;
    ``xi="xi_after"`` asks about gamma after a via state's xi reset."""
    return any(f"{node}.{f}" in free for f in (xi, *GAMMA_FIELDS[1:]))


def freed_fields(name: str, free: Mapping, node: Node, after: bool = False) -> set[str]:
    """The fields (:data:`NODE_FIELDS`) of node ``name`` whose values are freed. ``after`` a
    via state that resets xi or eta (:func:`has_reset`), ``xi`` and ``eta`` stand for
    ``xi_after`` and ``eta_after``; without a reset they are the values on arrival."""
    out = {f for f in NODE_FIELDS if f"{name}.{f}" in free}
    if after and name.startswith("via"):
        for field in ("xi", "eta"):
            if has_reset(node, name, field, free):
                out.discard(field)
                if f"{name}.{field}_after" in free:
                    out.add(field)
    return out


def si_bounds(free: Mapping[str, Sequence[float | None]]) -> dict[str, tuple[float, float]]:
    """Bounds of freed values from file units (``None`` for none) to SI, +-inf for none."""
    return {
        name: (
            -math.inf if lo is None else to_si(name, lo),
            math.inf if hi is None else to_si(name, hi),
        )
        for name, (lo, hi) in free.items()
    }


__all__ = [
    "ANGLE_FIELDS",
    "GAMMA_FIELDS",
    "MIN_PHASE",
    "NODE_FIELDS",
    "VIA_FIELDS",
    "free_value_names",
    "freed_fields",
    "gamma_is_free",
    "has_reset",
    "node_names",
    "node_values",
    "nodes_from_values",
    "si_bounds",
    "to_file",
    "to_si",
]
