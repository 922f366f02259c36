"""The limits of a real arm, each defined once in SI units: torque, joint position and joint
velocity. Both planners transcribe them, the flat optimizer checks them between its samples, and
a sampled plan is checked against them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .robot import Arm


@dataclass(frozen=True)
class Limit:
    """One limit ``lower <= quantity[joint] <= upper`` on a sampled quantity.

    Attributes
    ----------
    quantity : str
        ``tau`` (actuated torques [N m or N]), ``q`` (joint positions [rad or m]) or ``qd``
        (joint velocities [rad/s or m/s]).
    joint : int
        Joint index from 0.
    lower, upper : float
        Bounds in SI units.
    label : str
        How messages name it, e.g. ``|tau1| <= 120``.
    magnitude : bool
        True for a limit on |value| (torques, velocities), False for a range (positions).
    """

    quantity: str
    joint: int
    lower: float
    upper: float
    label: str
    magnitude: bool

    def bounds(self, safety: float = 0.0) -> tuple[float, float]:
        """The bounds; a magnitude limit is tightened by the relative ``safety`` margin (a
        planner keeps a little away from it so that the plan between samples holds too)."""
        if not self.magnitude:
            return self.lower, self.upper
        return self.lower * (1 - safety), self.upper * (1 - safety)

    def excess(self, values: np.ndarray) -> np.ndarray:
        """How far values lie outside the bounds (negative inside)."""
        return np.maximum(self.lower - values, values - self.upper)


def arm_limits(spec, arm: Arm) -> tuple[Limit, ...]:
    """The limits of an ``optimizer.limits`` block (a ``LimitsSpec``) in SI units.

    Order: torques, joint positions, joint velocities (the order of the NLP's constraints).
    """
    revolute = arm.revolute
    out = []
    for i, tmax in enumerate(spec.torque):
        if tmax is not None:
            out.append(
                Limit("tau", i, -float(tmax), float(tmax), f"|tau{i + 1}| <= {tmax:g}", True)
            )
    for i, pair in enumerate(spec.joint_position or ()):
        if pair is not None:
            lo, hi = np.radians(pair) if revolute[i] else pair
            out.append(Limit("q", i, float(lo), float(hi), f"q{i + 1} within limits", False))
    for i, vmax in enumerate(spec.joint_velocity or ()):
        if vmax is not None:
            vm = float(np.radians(vmax) if revolute[i] else vmax)
            out.append(Limit("qd", i, -vm, vm, f"|q{i + 1}dot| within limits", True))
    return tuple(out)


def sampled(limit: Limit, traj) -> np.ndarray:
    """The limited quantity along a trajectory's samples (N,)."""
    return {"tau": traj.tau, "q": traj.q, "qd": traj.qd}[limit.quantity][:, limit.joint]


__all__ = ["Limit", "arm_limits", "sampled"]
