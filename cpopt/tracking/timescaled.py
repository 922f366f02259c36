"""TVLQR with online time scaling: slow the reference when the motors cannot follow it.

Torque-limited path following by online time scaling (Dahl & Nielsen 1990, "Torque-limited
path following by online trajectory time scaling") on the sampled TVLQR loop. The controller's
state c = (s, s') is the plan's instant it tracks, s (in control periods, a fractional index
of the reference grid), and the rate s' at which it advances. At instant k it tracks the plan's
joint motion re-timed at that rate,

    x_ref = (q(s), s' qdot(s)),
    tau = tau_ff(s) + (s'^2 - 1) (tau(s) - g(q(s))) - K(s) (x - x_ref),

with TVLQR's gains K(s) and feed-forward tau_ff(s) (its period mean) interpolated at s; the
second term is the inverse dynamics of q(s(t)) at a constant rate on the actuated joints
(velocity terms scale with s'^2, gravity stays). Each period it tries :data:`CANDIDATES`
rates within :data:`RATE_STEP` x period of the last one, within [:data:`RATE_MIN`, the fastest
that keeps s at or behind the clock, :data:`RATE_MAX`], and keeps the one closest to its target
whose torque fits the motors' limits, else the one that exceeds them least (a joint on an arc
where the plan itself rides its limit, :data:`RIDING`, does not count). The target is 1
(the plan's pace) plus a catch-up of :data:`CATCH_UP` times the lag t - s, faded out over the
plan's last :data:`CATCH_UP_FADE` seconds so that the arm arrives at the plan's pace. A run is
judged when s reaches the end of the plan (a reference within half a period of it at T counts
as arriving at T), at most ``max_delay`` of the plan's duration after T.

A limit the plan's own feed-forward exceeds (a plan is limited at the optimizer's samples and
may pass a limit between them) does not count: the excess is measured beyond the larger of the
limit and the feed-forward. So on the model itself, and whenever the torque fits, the rate
stays exactly 1, s stays on the grid, and the law is TVLQR's
(:class:`~cpopt.tracking.tvlqr.TVLQRController`) to round-off.

**What limits it.** The arm's third joint is passive: a re-timing of the plan's joint motion
is not a motion of the arm, because gravity does not scale with the rate (the passive joint's
equation is left with (1 - s'^2) times its gravity torque), and the exact re-timing of the
flat CP curve y(s(t)) changes the third link's angle with the CP acceleration (slowing a
swing-up to 0.9 of its pace near its goal turns the link by 0.39 rad). Measured on the bundled
plans (20 Monte Carlo plants each, the benchmark plant of :mod:`cpopt.tracking.robustness`):

* this law (joint-space re-timing, RATE_STEP 2/s, CATCH_UP 1/s, RIDING 0.95), sweep (5
  steps) / Monte Carlo against TVLQR's: transfer_min_time_on_path 0.80/0.30 against
  0.72/0.25, transfer_straight_line 0.94/0.85 against 0.96/0.80, swing_up_torque_limited
  0.91/0.80 against 0.91/0.75, swing_up_min_time 0.79/0.15 against 0.77/0.30 (without RIDING
  0.17/0.15); on a plant with links 1 and 2 20 % heavier (500 Hz, motors at the problem's
  limits) it still swings the torque-limited swing-up up where TVLQR fails;
* faster rate changes (RATE_STEP 5 to 100/s) or a torque margin kept by slowing (10 or 20 % of
  the limit) lose 0.05 to 0.4: the slowed reference is not a motion of the arm, and on the
  model itself a 10 % margin leaves 2 to 8 cm of CP error;
* the exact flat re-timing (the chain rule on the CP derivatives, the inverse flat map and the
  linearising torques at zero error) with the same candidates: equal at RATE_STEP 0.5/s, worse
  beyond; with a rate driven by the excess torque, 0 to 0.2 (the reorientations saturate the
  motors more: 25 to 40 % of the periods);
* clipping by the LQR's own cost-to-go (the cheapest torque within the limits by
  (u - u*)^T (R h + Bd^T S Bd) (u - u*)) instead of per joint: no gain.

The plans that fail do so because a plant up to 10 % heavier needs more torque than motors at
the plan's own peak have (without limits the same plants succeed 0.75 to 1.0; without
measurement noise no better): the remedy is headroom in the plan.

The reference and the gains are interpolated linearly in s inside the law (a CasADi linear
interpolant over the control grid, a constant of the period function): the law's data r_k is
only the instant's index k, so a batch of runs stays one compiled, mapped call.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from ..model.dynamics import arm_dynamics
from ..model.mapping import mapped
from .reference import Reference
from .tvlqr import DEFAULT_Q, DEFAULT_QF, TVLQRController

RATE_MIN = 0.2
"""Slowest rate s' of the reference (a fifth of the plan's pace)."""
RATE_MAX = 1.5
"""Fastest rate s' while catching up."""
RATE_STEP = 2.0
"""Largest change of the rate per second [1/s] (the path acceleration s'')."""
CANDIDATES = 9
"""Rates tried per period, evenly spaced within +-RATE_STEP x period of the last one."""
CATCH_UP = 1.0
"""Target rate 1 + CATCH_UP x lag [1/s] (capped at RATE_MAX): 0.1 s behind, 1.1."""
CATCH_UP_FADE = 0.1
"""The catch-up fades out linearly over the plan's last this many seconds [s]."""
MAX_DELAY = 0.5
"""By default a run may last this fraction of the plan's duration longer than the plan."""
RIDING = 0.95
"""Where the plan's own feed-forward on a joint is within this fraction of its limit, that
joint's excess does not lower the rate: on the arcs where a plan rides its limits slowing is
no help (the re-timed reference is not a motion of the arm, see the module docstring), and
counting them made the minimum-time swing-up's sweep fall from 0.79 to 0.17."""


class TimeScaledTVLQR(TVLQRController):
    """TVLQR around the plan re-timed online to fit the motors' torque limits.

    Parameters
    ----------
    reference : Reference
        The plan on the control grid.
    torque_limit : sequence of (float or None), optional
        The motors' limits on tau1, tau2 [N m or N]; None (or a joint's None): no limit, and
        without any the controller is TVLQR.
    Q, R, Qf : sequence of float
        TVLQR's weights (:func:`~cpopt.tracking.tvlqr.riccati_gains`).
    max_delay : float
        How much longer than the plan a run may last, as a fraction of its duration.
    """

    name = "tvlqr_timescaled"

    def __init__(
        self,
        reference: Reference,
        torque_limit=None,
        Q=DEFAULT_Q,
        R=None,
        Qf=DEFAULT_QF,
        max_delay: float = MAX_DELAY,
    ) -> None:
        limits = [np.inf if v is None else float(v) for v in (torque_limit or (None, None))]
        if len(limits) != 2 or not all(v > 0 for v in limits):
            raise ValueError(f"torque_limit: give two limits > 0 or None, got {torque_limit}")
        if not max_delay >= 0:
            raise ValueError(f"max_delay must be >= 0, got {max_delay}")
        self.torque_limit = np.array(limits)
        self.extra = int(np.ceil(max_delay * reference.steps))
        super().__init__(reference, Q, R, Qf)

    @property
    def horizon(self) -> int:
        """The plan's periods and up to ``max_delay`` of its duration more."""
        return self.reference.steps + self.extra

    def initial_state(self) -> np.ndarray:
        """At the plan's first instant, at its pace: (s, s') = (0, 1)."""
        return np.array([0.0, 1.0])

    def progress(self, k: np.ndarray, c: np.ndarray) -> np.ndarray:
        """The controller's s (in periods), whatever the instant."""
        return np.asarray(c[0], float).copy()

    def schedule(self) -> np.ndarray:
        """The instant's index k, one row (the plan is a constant of the law)."""
        return np.arange(self.horizon + 1, dtype=float)[None, :]

    def table(self) -> np.ndarray:
        """The plan at every instant of its grid, one column per instant (22, n + 1): TVLQR's
        schedule (joint state, feed-forward, gains: 20 rows) and tau - g on the actuated
        joints (2) [N m or N]."""
        ref = self.reference
        gravity = np.asarray(mapped(arm_dynamics(ref.arm)["g"], ref.t.size)(ref.x[:, :3].T))
        return np.vstack([super().schedule(), ref.tau.T - gravity[:2]])

    def law(self) -> ca.Function:
        """``(k, q, qd, (s, s')) -> (tau, (s_next, s'_next))``: choose the rate, apply TVLQR
        around the plan re-timed at it."""
        ref = self.reference
        n, h = ref.steps, ref.period
        plan = ca.interpolant("plan", "linear", [np.arange(n + 1.0)], self.table().ravel(order="F"))
        k = ca.SX.sym("k")
        q = ca.SX.sym("q", 3)
        qd = ca.SX.sym("qd", 3)
        c = ca.SX.sym("c", 2)
        s, rate = c[0], c[1]
        row = plan(ca.fmin(ca.fmax(s, 0), n))
        x_plan, ff, gain, dynamic = row[0:6], row[6:8], ca.reshape(row[8:20], 2, 6), row[20:22]
        x = ca.vertcat(q, qd)
        limited = np.isfinite(self.torque_limit)
        if not limited.any():  # nothing to fit: TVLQR at the plan's pace
            tau = ff - gain @ (x - x_plan)
            return ca.Function(self.name, [k, q, qd, c], [tau, ca.vertcat(ca.fmin(s + 1, n), 1.0)])
        limit = ca.DM(np.where(limited, self.torque_limit, 1.0))
        room = ca.fmax(limit, ca.fabs(ff))  # the plan's own excess does not count
        # a joint counts where it is limited and the plan leaves it room (see RIDING)
        counted = ca.DM(limited.astype(float)) * (ca.fabs(ff) < RIDING * limit)
        lag, left = (k - s) * h, (n - s) * h
        target = 1 + ca.fmin(RATE_MAX - 1, CATCH_UP * ca.fmax(lag, 0)) * ca.fmin(
            1, left / CATCH_UP_FADE
        )
        fastest = ca.fmin(RATE_MAX, 1 + ca.fmax(k - s, 0))  # s_next never ahead of k + 1
        best = None
        for j in np.linspace(-1.0, 1.0, CANDIDATES):
            v = ca.fmin(ca.fmax(rate + j * RATE_STEP * h, RATE_MIN), fastest)
            x_ref = ca.vertcat(x_plan[0:3], v * x_plan[3:6])
            tau = ff + (v**2 - 1) * dynamic - gain @ (x - x_ref)
            excess = ca.fmax(ca.fabs(tau) - room, 0) / limit * counted
            score = 1e6 * ca.mmax(excess) + ca.fabs(v - target)
            if best is None:
                best = (tau, v, score)
            else:
                better = score < best[2]
                best = tuple(
                    ca.if_else(better, new, old)
                    for new, old in zip((tau, v, score), best, strict=True)
                )
        tau, v = best[0], best[1]
        # at T a reference within half a period of the goal has arrived: a smaller lag would
        # otherwise postpone the judgement by a whole period, on a goal the arm may pass through
        # fast (measured: 0.1 less Monte Carlo success on paper_swing_up)
        on_time = ca.logic_and(ca.fabs(k + 1 - n) < 0.5, n - (s + v) < 0.5)  # k + 1 == n
        s_next = ca.if_else(on_time, n, ca.fmin(s + v, n))
        return ca.Function(self.name, [k, q, qd, c], [tau, ca.vertcat(s_next, v)])
