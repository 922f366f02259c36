"""``flat_mpc``: TVLQR around the newest plan, the plan re-solved from the measured state.

Every ``period`` [s] the loop measures (q, qd) (with the plant's measurement noise) and
re-plans the remaining motion to the goal at T (:func:`cpopt.flatopt.replan.replan`: the
flat NLP from the measured state, xi and eta the newest plan's unless
:attr:`MPCSettings.free_compensator`, torques within :attr:`MPCSettings.motor_fraction` of
the motors, warm started from the newest plan and its multipliers). The computation takes
time: the new plan takes effect ``delay`` [s] after the measurement (one period by default);
until then the previous plan's TVLQR runs on, so the re-plan starts at that later instant,
from the measured state carried over the delay on the model under that law
(:attr:`MPCSettings.predict`). A re-plan that does not solve, or
takes longer than its ``deadline`` of wall time (the delay by default: a real loop has no
more), keeps the previous plan. Between re-plans the law is TVLQR
(:class:`~cpopt.tracking.tvlqr.TVLQRController`) around the newest plan, its Riccati gains
designed on the new plan's remainder with the first plan's torque weights.

The simulation is the sampled-data loop of :mod:`cpopt.tracking.simulation` (the same period
function: noise, law, saturation, RK4 plant), run a stretch at a time between re-plans,
because each stretch's schedule depends on what the re-plans returned. One run at a time:
runs on different plants re-plan differently.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import lru_cache

import casadi as ca
import numpy as np

from ..closedform.trajectory import sample
from ..flatopt.replan import Replan, replan
from ..model.kinematics import ReachError
from .outcome import Tolerance, TrackingOutcome, cp_points, final_errors
from .plant import Plant
from .reference import reference
from .simulation import (
    DIVERGED_CP,
    DIVERGED_VELOCITY,
    NOISE_ROWS,
    Noise,
    call_buffered,
    initial_controller_state,
    step_function,
)
from .tvlqr import DEFAULT_Q, DEFAULT_QF, TVLQRController, relative_R

DEFAULT_PERIOD = 0.02
"""Re-plan period [s] (``tracking.replan_period``)."""
MOTOR_FRACTION = 0.9
"""The fraction of the motors' torque limits a re-plan may use: a re-plan from a state the
model error moved asks more torque near the end of a shrinking horizon, and one that rides
the motors' limits leaves the feedback nothing (without it, transfer_min_torque's re-plans on
a Monte Carlo plant asked more than the benchmark's motors near T and the arm ended 0.8 m
off; TVLQR alone: 0.7 mm)."""


@dataclass(frozen=True)
class MPCSettings:
    """When the loop re-plans and when a re-plan takes effect.

    Attributes
    ----------
    period : float
        Time between re-plans [s], rounded to whole control periods.
    delay : float or None
        Time from the measured state to the new plan taking effect [s] (None: one re-plan
        period), rounded to whole control periods (at least one).
    deadline : float or None
        Wall time a re-plan may take [s] (None: the delay); past it the previous plan stays.
    free_compensator : bool
        Re-plans choose xi and eta at their instant, or keep the newest plan's (the default:
        measured on transfer_min_torque on the model, re-planning every 0.1 s, 7 of 8
        re-plans solved with xi and eta kept and 2 of 8 with them free: a re-plan with them
        free starts with a jump of the CP's acceleration and jerk, and the next re-plan,
        warm started from that plan, mostly ran out of iterations).
    motor_fraction : float
        Re-plans keep their torques within this fraction of the motors' limits (the rest is
        the feedback's).
    predict : bool
        Re-plan from the state predicted at the instant the new plan takes effect (the
        measured state carried over the delay on the model under the law in effect), not
        from the measured one (see :meth:`_Loop._replan`).
    method : str
        The re-plans' solver (:data:`cpopt.flatopt.replan.METHODS`).
    """

    period: float = DEFAULT_PERIOD
    delay: float | None = None
    deadline: float | None = None
    free_compensator: bool = False
    motor_fraction: float = MOTOR_FRACTION
    predict: bool = True
    method: str = "ipopt"

    def steps(self, control_period: float) -> tuple[int, int]:
        """(re-plan period, delay) in control periods."""
        every = max(1, round(self.period / control_period))
        delay = self.period if self.delay is None else self.delay
        return every, max(1, round(delay / control_period))

    def wall_deadline(self) -> float:
        """The wall time a re-plan may take [s]."""
        if self.deadline is not None:
            return self.deadline
        return self.period if self.delay is None else self.delay


@dataclass
class Stretch:
    """The law in effect: a plan, its TVLQR controller, the global instant it starts at."""

    plan: object
    controller: TVLQRController
    k0: int

    def schedule(self, k: int, length: int) -> np.ndarray:
        """The law's data for global instants k .. k + length - 1."""
        cols = self.controller.schedule()
        i = np.clip(np.arange(k, k + length) - self.k0, 0, cols.shape[1] - 1)
        return cols[:, i]


@dataclass
class MPCRun:
    """One run of the loop: the plant's states and torques per control period, the re-plans.

    Attributes
    ----------
    t : numpy.ndarray
        Control instants reached (m + 1,) [s].
    x : numpy.ndarray
        Plant joint states at those instants (m + 1, 6).
    tau, qdd, cp, saturated : numpy.ndarray
        Per period: torque held (m, 2), accelerations (m, 3), CP at the period's start
        (m, 2), clipped or not (m,).
    replans : list of Replan
        Every re-plan, in order (their ``time_s`` is the wall time of the solve).
    applied : int
        Re-plans that took effect.
    diverged_at : float or None
        When the run was stopped as diverged [s].
    """

    t: np.ndarray
    x: np.ndarray
    tau: np.ndarray
    qdd: np.ndarray
    cp: np.ndarray
    saturated: np.ndarray
    replans: list = field(default_factory=list)
    applied: int = 0
    diverged_at: float | None = None

    @property
    def misses(self) -> int:
        """Re-plans over their deadline or without a plan to follow (neither solved nor
        ``feasible``; ``holding`` ones do not count)."""
        return sum(r.status not in ("solved", "feasible", "holding") for r in self.replans)


@lru_cache(maxsize=32)
def _stretch_function(step: ca.Function, length: int) -> ca.Function:
    """``length`` periods of the period function accumulated over (X, c)."""
    return step.mapaccum("stretch", length, [0, 1], [0, 1])


class FlatMPC:
    """The ``flat_mpc`` loop for one flat plan (see the module docstring).

    Parameters
    ----------
    problem : Problem
        The problem the plan solves (objective, limits, freed values).
    plan : CPPlan
        A flat plan of ``planner: optimize`` with B-spline curves.
    rate_hz : float
        Control rate [Hz].
    settings : MPCSettings
        Re-plan period, delay and deadline.
    Q, R, Qf : sequence of float
        TVLQR weights (R None: relative to the first plan's peak torques).
    torque_limit : sequence of (float or None), optional
        The motors' torque limits [N m or N] (re-plans keep within
        :attr:`MPCSettings.motor_fraction` of them).
    """

    name = "flat_mpc"

    def __init__(
        self, problem, plan, rate_hz, settings=None, Q=DEFAULT_Q, R=None, Qf=DEFAULT_QF,
        torque_limit=None,
    ):  # fmt: skip
        self.problem, self.plan = problem, plan
        self.torque_limit = torque_limit
        self.settings = settings or MPCSettings()
        first = reference(plan, rate_hz)
        self.reference = first
        self.R = relative_R(first) if R is None else tuple(R)
        self.Q, self.Qf = Q, Qf
        self.first = TVLQRController(first, Q, self.R, Qf)
        self.seed = sample(plan)
        self.model = Plant(plan.arm).parameters()

    def step(self, delay: int = 0) -> ca.Function:
        """The period function with an actuation delay of ``delay`` periods (one law for
        every plan: the plan's data are in the schedule)."""
        return step_function(self.first, False, delay)

    @property
    def period(self) -> float:
        """Control period [s]."""
        return self.reference.period

    def controller_for(self, plan, k: int) -> TVLQRController:
        """TVLQR on a re-plan's remainder from global instant k, on the first plan's grid."""
        ref0 = self.reference
        steps = ref0.steps - k
        rate = steps / (ref0.t[-1] - ref0.t[k])  # the rate that lands on the same instants
        return TVLQRController(reference(plan, rate), self.Q, self.R, self.Qf)

    def replan_at(self, k: int, measured: np.ndarray, newest, warm, samples=None) -> Replan:
        """The re-plan from the measured joint state (6,) at global instant k; ``samples``:
        ``newest`` sampled, when it is a re-plan (its :attr:`Replan.samples`)."""
        t = float(self.reference.t[k])
        return replan(
            self.problem,
            newest,
            t,
            measured[:3],
            measured[3:],
            deadline_s=self.settings.wall_deadline(),
            seed=self.seed if newest is self.plan else samples,
            warm=warm,
            free_compensator=self.settings.free_compensator,
            torque_limit=self.motors(),
            method=self.settings.method,
        )

    def motors(self) -> tuple | None:
        """The torque limits re-plans keep [N m or N] (None: the problem's)."""
        if self.torque_limit is None:
            return None
        f = self.settings.motor_fraction
        return tuple(None if v is None else f * float(v) for v in self.torque_limit)

    def run(
        self, parameters: np.ndarray, noise: Noise | None = None, index: int = 0, delay: int = 0
    ) -> MPCRun:
        """One run on a plant with these parameters (22,), noise drawn as run ``index`` of a
        batch draws it (:meth:`Noise.generators`), an actuation delay of ``delay`` periods."""
        noise = noise or Noise()
        return _Loop(self, np.asarray(parameters, float), noise, index, delay).run()


class _Loop:
    """The state of one run of :class:`FlatMPC` while it runs."""

    def __init__(
        self, mpc: FlatMPC, parameters: np.ndarray, noise: Noise, index: int, delay: int
    ) -> None:
        self.mpc, self.parameters, self.noise = mpc, parameters, noise
        self.generators = noise.generators(index)
        self.delay_steps = delay
        self.step = mpc.step(delay)
        self.stretches: dict[int, ca.Function] = {}
        self.every, self.delay = mpc.settings.steps(mpc.period)
        self.current = Stretch(mpc.plan, mpc.first, 0)
        self.newest, self.warm, self.samples = mpc.plan, None, None
        self.pending: list[tuple[int, Stretch]] = []
        self.replans: list[Replan] = []
        self.applied = 0
        self.logs: dict[str, list] = {k: [] for k in ("x", "tau", "qdd", "cp", "saturated")}

    def _noise(self, length: int) -> np.ndarray:
        return self.noise.draw(self.generators, length)

    def _replan(self, k: int, X: np.ndarray, c: np.ndarray, measurement: np.ndarray) -> None:
        """Re-plan from the state measured at k (X + measurement), the law's state c; the new
        plan takes effect at k + delay.

        With :attr:`MPCSettings.predict` the re-plan starts at k + delay from the measured
        state carried over the delay on the model, under the law in effect (the previous
        plan's TVLQR, which drives the arm until then): a plan solved from the state at k
        assumes its own torques from k on, and by k + delay the arm, driven by the previous
        law, is elsewhere. Measured on transfer_min_torque, a Monte Carlo plant, re-plans every
        20 ms taking effect 20 ms later: from the measured state, the passive joint's velocity
        was 0.2-1.6 rad/s off the new plan where it took effect (0.06-0.7 off the previous
        one), and the motors saturated 30 % of the first 0.2 s (TVLQR alone: 8 %)."""
        start, measured = k, X + measurement
        if self.mpc.settings.predict:
            start = k + self.delay
            if start >= self.mpc.reference.steps:
                return
            measured = self._predicted(k, measured, c)
        result = self.mpc.replan_at(start, measured, self.newest, self.warm, self.samples)
        if result.usable:
            try:
                controller = self.mpc.controller_for(result.plan, start)
            except ReachError:  # within reach on sample's points, not on the tracking grid
                result = replace(result, status="out_of_reach", plan=self.newest)
                result = replace(result, kept_previous=True)
        self.replans.append(result)
        if result.usable:
            self.warm = result.multipliers
            self.newest, self.samples = result.plan, result.samples
            self.pending.append((k + self.delay, Stretch(result.plan, controller, start)))

    def _stretch(self, length: int) -> ca.Function:
        """``length`` periods of the run's period function (:func:`_stretch_function`), built
        once a length for the whole run: the stretches between re-plans, and the prediction
        over the delay, have a few lengths only."""
        if length not in self.stretches:
            self.stretches[length] = _stretch_function(self.step, length)
        return self.stretches[length]

    def _predicted(self, k: int, measured: np.ndarray, c: np.ndarray) -> np.ndarray:
        """The measured state (6,) at k carried ``delay`` periods on the model (the nominal
        plant, no noise) under the law in effect."""
        f = self._stretch(self.delay)
        params = np.repeat(self.mpc.model[:, None], self.delay, axis=1)
        schedule = self.current.schedule(k, self.delay)
        quiet = np.zeros((NOISE_ROWS, self.delay))
        X_next = call_buffered(f, measured, c, schedule, quiet, params)[0]
        return X_next[:, -1]

    def _next_event(self, k: int, horizon: int) -> int:
        nxt = (k // self.every + 1) * self.every
        due = [at for at, _ in self.pending if at > k]
        return min([nxt, horizon, *due])

    def _apply_due(self, k: int) -> None:
        for at, stretch in [p for p in self.pending if p[0] <= k]:
            self.current, self.applied = stretch, self.applied + 1
            self.pending.remove((at, stretch))

    def run(self) -> MPCRun:
        mpc = self.mpc
        ref = mpc.reference
        horizon = ref.steps
        X, k = ref.x[0].copy(), 0
        c = initial_controller_state(mpc.first, self.delay_steps)
        diverged = None
        while k < horizon:
            self._apply_due(k)
            end = self._next_event(k, horizon)
            length = end - k
            measurement = self._noise(length)
            if k > 0 and k % self.every == 0:
                self._replan(k, X, c, measurement[:6, 0])
                self._apply_due(k)  # a delay of zero periods is refused: nothing due now
            f = self._stretch(length)
            params = np.repeat(self.parameters[:, None], length, axis=1)
            schedule = self.current.schedule(k, length)
            X_next, c_next, tau, qdd, cp, sat = call_buffered(
                f, X, c, schedule, measurement, params
            )
            self._log(X, X_next, tau, qdd, cp, sat)
            bad = self._first_bad(X_next, k, cp)
            if bad is not None:
                diverged = float(ref.t[k + bad + 1])
                X, k = X_next[:, bad], k + bad + 1
                break
            X, c, k = X_next[:, -1], c_next[:, -1], end
        return self._result(k, X, diverged)

    def _first_bad(self, X_next: np.ndarray, k: int, cp: np.ndarray) -> int | None:
        """The first period after which the run diverged (as the batch simulation judges)."""
        ref = self.mpc.reference
        length = X_next.shape[1]
        cp_ref = ref.cp[k : k + length, :, 0].T
        with np.errstate(invalid="ignore"):
            bad = (
                ~np.isfinite(X_next).all(axis=0)
                | (np.abs(X_next[3:6]) > DIVERGED_VELOCITY).any(axis=0)
                | ~(np.linalg.norm(cp - cp_ref, axis=0) <= DIVERGED_CP)
            )
        return int(np.argmax(bad)) if bad.any() else None

    def _log(self, X, X_next, tau, qdd, cp, sat) -> None:
        self.logs["x"].append(np.column_stack([X, X_next[:, :-1]]).T)
        self.logs["tau"].append(tau.T)
        self.logs["qdd"].append(qdd.T)
        self.logs["cp"].append(cp.T)
        self.logs["saturated"].append(np.asarray(sat).ravel() > 0)

    def _result(self, k: int, X: np.ndarray, diverged) -> MPCRun:
        ref = self.mpc.reference
        out = {key: np.concatenate(v)[:k] for key, v in self.logs.items()}
        x = np.vstack([out["x"], X[None, :]])
        cp = np.vstack([out["cp"], cp_points(ref.arm, X[None, :3])])
        return MPCRun(
            t=ref.t[: k + 1],
            x=x,
            tau=out["tau"],
            qdd=out["qdd"],
            cp=cp,
            saturated=out["saturated"],
            replans=self.replans,
            applied=self.applied,
            diverged_at=diverged,
        )


def replan_figures(runs: list[MPCRun]) -> dict:
    """Median and 99th percentile of the re-plans' wall times [ms], the fraction missed (over
    their deadline or without a plan to follow) and the fraction followed as the SQP's
    ``feasible`` iterates (not solved to optimality) over every re-plan of the runs
    (``holding`` ones left out)."""
    kept = [r for run in runs for r in run.replans if r.status != "holding"]
    times = [r.time_s for r in kept]
    missed = sum(run.misses for run in runs)
    if not times:
        nan = math.nan
        return {"median_ms": nan, "p99_ms": nan, "misses": nan, "feasible": nan, "count": 0}
    return {
        "median_ms": 1e3 * float(np.median(times)),
        "p99_ms": 1e3 * float(np.percentile(times, 99)),
        "misses": missed / len(times),
        "feasible": sum(r.status == "feasible" for r in kept) / len(times),
        "count": len(times),
    }


def track_flat_mpc(
    problem,
    plan,
    plant: Plant | None = None,
    noise: Noise | None = None,
    rate_hz: float = 1000.0,
    tolerance: Tolerance | None = None,
    settings: MPCSettings | None = None,
    **gains,
) -> TrackingOutcome:
    """Track a flat plan with ``flat_mpc`` on a plant (see the module docstring).

    Parameters
    ----------
    problem : Problem
        The problem the plan solves (``planner: optimize``, B-spline curves).
    plan : CPPlan
        Its plan.
    plant : Plant, optional
        The simulated arm (default: the model); its torque limits are the motors' the
        re-plans keep within.
    noise : Noise, optional
        Measurement and torque noise (default: none).
    rate_hz : float
        Control rate [Hz].
    tolerance : Tolerance, optional
        Success criterion.
    settings : MPCSettings, optional
        Re-plan period, delay and deadline.
    **gains
        ``Q``, ``R``, ``Qf`` of the TVLQR between re-plans.

    Returns
    -------
    TrackingOutcome
        As for the other controllers, with ``replans``: their count, median and 99th
        percentile wall time [ms], misses and how many took effect.
    """
    plant = plant or Plant(plan.arm)
    gains = {k: v for k, v in gains.items() if k in ("Q", "R", "Qf") and v is not None}
    mpc = FlatMPC(problem, plan, rate_hz, settings, torque_limit=plant.torque_limit, **gains)
    run = mpc.run(plant.parameters(), noise, 0, plant.delay_steps(mpc.period))
    ref = mpc.reference
    m = run.tau.shape[0]
    figures = {**replan_figures([run]), "applied": run.applied}
    return TrackingOutcome(
        controller=FlatMPC.name,
        rate_hz=1.0 / ref.period,
        t=run.t,
        x=run.x,
        qdd=run.qdd,
        tau=run.tau,
        saturated=run.saturated,
        cp=run.cp,
        cp_ref=ref.cp[: m + 1, :, 0],
        diverged_at=run.diverged_at,
        final=final_errors(ref.arm, ref.goal, run.x[-1:]),
        tolerance=tolerance or Tolerance(),
        arrived=run.diverged_at is None,
        replans=figures,
    )


__all__ = [
    "DEFAULT_PERIOD",
    "FlatMPC",
    "MPCRun",
    "MPCSettings",
    "replan_figures",
    "track_flat_mpc",
]
