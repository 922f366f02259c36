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
    headroom : float
        For a torque limit planned with ``optimizer.limits.torque_headroom``: the fraction h of
        the motor's limit left to feedback; ``lower`` and ``upper`` are then (1 - h) times it.
    motor : float or None
        That motor's full limit [N m or N] (None: ``upper``).
    """

    quantity: str
    joint: int
    lower: float
    upper: float
    label: str
    magnitude: bool
    headroom: float = 0.0
    motor: float | None = None

    @property
    def rated(self) -> float:
        """The full limit: the motor's torque of a limit planned with headroom, the upper bound
        itself otherwise."""
        return self.upper if self.motor is None else self.motor

    def bounds(self, safety: float = 0.0) -> tuple[float, float]:
        """The bounds; a magnitude limit is tightened by the relative ``safety`` margin (a
        planner keeps a little away from it so that the plan between samples holds too)."""
        if not self.magnitude:
            return self.lower, self.upper
        return self.lower * (1 - safety), self.upper * (1 - safety)

    def excess(self, values: np.ndarray) -> np.ndarray:
        """How far values lie outside the bounds (negative inside)."""
        return np.maximum(self.lower - values, values - self.upper)


def torque_headroom(spec) -> tuple[float, float]:
    """The headroom h of each actuated joint from an ``optimizer.limits`` block: a single
    value applies to every joint with a torque limit (0 on the others), a pair per joint."""
    h = spec.torque_headroom
    if isinstance(h, list | tuple):
        return float(h[0]), float(h[1])
    return tuple(float(h) if tmax is not None else 0.0 for tmax in spec.torque)


def arm_limits(spec, arm: Arm) -> tuple[Limit, ...]:
    """The limits of an ``optimizer.limits`` block (a ``LimitsSpec``) in SI units; a torque
    limit with headroom h is the plan's, (1 - h) times the motor's.

    Order: torques, joint positions, joint velocities (the order of the NLP's constraints).
    """
    revolute = arm.revolute
    out = []
    for i, (tmax, h) in enumerate(zip(spec.torque, torque_headroom(spec), strict=True)):
        if tmax is not None:
            bound = float(tmax) * (1 - h)
            label = f"|tau{i + 1}| <= {tmax:g}"
            if h:
                label = f"|tau{i + 1}| <= {bound:g} ({tmax:g} less {100 * h:g} % headroom)"
            out.append(Limit("tau", i, -bound, bound, label, True, h, float(tmax)))
    for i, pair in enumerate(spec.joint_position or ()):
        if pair is not None:
            lo, hi = np.radians(pair) if revolute[i] else pair
            out.append(Limit("q", i, float(lo), float(hi), f"q{i + 1} within limits", False))
    for i, vmax in enumerate(spec.joint_velocity or ()):
        if vmax is not None:
            vm = float(np.radians(vmax) if revolute[i] else vmax)
            out.append(Limit("qd", i, -vm, vm, f"|q{i + 1}dot| within limits", True))
    return tuple(out)


def rated_torques(limits: tuple[Limit, ...]) -> tuple[tuple, tuple[float, float]]:
    """The motors' full torque limits (None where there is none) [N m or N] and the headroom
    of each actuated joint, from a problem's limits."""
    rated, headroom = [None, None], [0.0, 0.0]
    for limit in limits:
        if limit.quantity == "tau":
            rated[limit.joint], headroom[limit.joint] = limit.rated, limit.headroom
    return tuple(rated), tuple(headroom)


def sampled(limit: Limit, traj) -> np.ndarray:
    """The limited quantity along a trajectory's samples (N,)."""
    return {"tau": traj.tau, "q": traj.q, "qd": traj.qd}[limit.quantity][:, limit.joint]


@dataclass(frozen=True)
class Violation:
    """The worst place where a sampled plan leaves one limit.

    Attributes
    ----------
    limit : Limit
        The limit.
    t : float
        Where [s].
    value : float
        The quantity there (SI units).
    """

    limit: Limit
    t: float
    value: float

    def message(self) -> str:
        """One line naming the limit, the time and the value."""
        return (
            f"{self.limit.label} violated at t = {self.t:.4g} s (value {self.value:.4g}, "
            f"bounds [{self.limit.lower:.4g}, {self.limit.upper:.4g}] in SI units)"
        )


VIOLATION_RTOL = 1e-4
"""Relative excess over a bound that counts as a violation of a sampled plan (the flat
optimizer itself keeps 2e-3 inside on its samples and checks 1e-6 on a fine grid; the
trajectory's own grid may fall between those points)."""


def violations(limits: tuple[Limit, ...], traj, rtol: float = VIOLATION_RTOL) -> list[Violation]:
    """The limits a sampled plan violates, each at its worst sample."""
    out = []
    for limit in limits:
        values = sampled(limit, traj)
        excess = limit.excess(values)
        j = int(np.argmax(excess))
        if excess[j] > rtol * max(abs(limit.lower), abs(limit.upper), 1e-9):
            out.append(Violation(limit, float(traj.t[j]), float(values[j])))
    return out


__all__ = [
    "VIOLATION_RTOL",
    "Limit",
    "Violation",
    "arm_limits",
    "rated_torques",
    "sampled",
    "torque_headroom",
    "violations",
]
