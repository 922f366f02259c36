"""Nodes by name: which nodes a motion has, the fields of a node, file <-> SI units, and the
names by which a value can be freed for the optimizer.

A motion passes through ``start``, ``via[0]``, ``via[1]``, ... and ``goal``. A value is named
``<node>.<field>`` with the field as the problem file spells it (``start.theta_deg``,
``via[0].eta_after``, ``via[0].t``) or ``duration``. Files give angles in degrees; in code every
value is SI and in radians, whatever its name says: ``values["start.theta_deg"]`` is radians.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

from .plan import Node

NODE_FIELDS = ("x", "y", "theta_deg", "xdot", "ydot", "thetadot_deg", "xi", "eta")
"""Fields of every node, as the problem file names them."""
VIA_FIELDS = (*NODE_FIELDS, "eta_after", "t")
"""Fields of a via state: a node's, the eta reset and the time [s]."""
ANGLE_FIELDS = frozenset({"theta_deg", "thetadot_deg"})
"""Fields given in degrees (deg, deg/s) in files and held in radians in code."""
GAMMA_FIELDS = ("xi", "theta_deg", "thetadot_deg")
"""The fields gamma = xi - K thetadot^2 + g0 sin(theta) depends on."""
MIN_PHASE = 0.05
"""Shortest phase [s] a planner may choose when node times are free."""

_NODE_ATTRIBUTE = {"theta_deg": "theta", "thetadot_deg": "thetadot"}


def node_names(count: int) -> list[str]:
    """Names of ``count`` nodes: ``start``, ``via[0]``, ..., ``goal``."""
    return ["start", *(f"via[{i}]" for i in range(count - 2)), "goal"]


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

    A via state without an eta reset has ``eta_after`` equal to its ``eta``.
    """
    out = {"duration": nodes[-1].t - nodes[0].t}
    for name, node in zip(node_names(len(nodes)), nodes, strict=True):
        for f in NODE_FIELDS:
            out[f"{name}.{f}"] = float(getattr(node, _NODE_ATTRIBUTE.get(f, f)))
        if name.startswith("via"):
            out[f"{name}.t"] = float(node.t)
            after = node.eta if node.eta_after is None else node.eta_after
            out[f"{name}.eta_after"] = float(after)
    return out


def nodes_from_values(
    values: Mapping[str, float], count: int, xi: Mapping[str, float] | None = None
) -> list[Node]:
    """The nodes a set of values by name (SI units) describes; ``xi`` overrides xi by node."""
    names = node_names(count)
    times = [0.0, *(values[f"{v}.t"] for v in names[1:-1]), values["duration"]]
    nodes = []
    for t, name in zip(times, names, strict=True):
        fields = {_NODE_ATTRIBUTE.get(f, f): values[f"{name}.{f}"] for f in NODE_FIELDS}
        if xi and name in xi:
            fields["xi"] = xi[name]
        after = values.get(f"{name}.eta_after")
        reset = None if after is None or after == fields["eta"] else after
        nodes.append(Node(t=t, eta_after=reset, **fields))
    return nodes


def gamma_is_free(node: str, free: Mapping) -> bool:
    """True when gamma at a node (``start``, ``via[i]``, ``goal``) depends on a freed value."""
    return any(f"{node}.{f}" in free for f in GAMMA_FIELDS)


def freed_fields(node: str, free: Mapping, after: bool = False) -> set[str]:
    """The fields (:data:`NODE_FIELDS`) of a node whose values are freed; ``after`` a via
    state's eta reset, ``eta`` stands for ``eta_after``."""
    out = {f for f in NODE_FIELDS if f"{node}.{f}" in free}
    if after and node.startswith("via"):
        out.discard("eta")
        if f"{node}.eta_after" in free:
            out.add("eta")
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
    "node_names",
    "node_values",
    "nodes_from_values",
    "si_bounds",
    "to_file",
    "to_si",
]
