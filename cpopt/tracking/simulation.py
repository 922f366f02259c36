"""The sampled-data closed loop: a controller at a fixed rate, a plant, noise; many at once.

One CasADi function does a whole control period: add the measurement noise, evaluate the
controller's law, saturate and hold the torque, integrate the plant by RK4 substeps. It is
accumulated over a chunk of periods (``mapaccum``) and mapped over runs that differ in their
plant parameters and noise, so a batch of runs is one call per chunk. Between chunks, runs
that diverged are stopped and dropped from the batch, and so are runs that arrived: a run is
judged at the first instant its controller's progress (:meth:`Controller.progress`) reaches the
end of the plan, at T for a controller at the plan's pace, later for one that slowed its
reference (at most :attr:`Controller.horizon` periods; a run that has not arrived by then is
judged there and fails).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import casadi as ca
import numpy as np

from ..model.kinematics import kinematic_functions
from ..runtime import compiled
from .controller import Controller
from .outcome import cp_points
from .plant import PARAMETER_NAMES, plant_period

CHUNK = 100
"""Control periods per call of the simulation function (between divergence checks)."""
DIVERGED_CP = 1.0
"""A run whose CP is farther than this from the plan's [m] is stopped as diverged."""
DIVERGED_VELOCITY = 100.0
"""... and so is one with a joint faster than this [rad/s or m/s] or a non-finite state."""


NOISE_ROWS = 8
"""Rows of a period's noise: the six measured joint states', the two applied torques'."""


@dataclass(frozen=True)
class Noise:
    """Measurement and torque noise: standard deviations, and a seed.

    Attributes
    ----------
    position : tuple of float
        Of measured q1, q2, q3 [rad or m].
    velocity : tuple of float
        Of measured q1dot, q2dot, q3dot [rad/s or m/s].
    seed : int
        Seed of the noise; run i of a batch draws its measurement noise from
        ``numpy.random.default_rng([seed, i])``, its torque noise from
        ``default_rng([seed, i, 1])`` (so adding torque noise leaves the measurement noise).
    torque : tuple of float
        Of the torques applied by motors 1, 2, drawn once per control period [N m or N].
    """

    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    seed: int = 0
    torque: tuple[float, float] = (0.0, 0.0)

    @property
    def std(self) -> np.ndarray:
        """The six standard deviations of the measured joint states."""
        return np.array([*self.position, *self.velocity], float)

    def generators(self, run: int) -> tuple[np.random.Generator, np.random.Generator]:
        """Run ``run``'s generators of measurement and torque noise."""
        rng = np.random.default_rng
        return rng([self.seed, run]), rng([self.seed, run, 1])

    def draw(self, generators, length: int) -> np.ndarray:
        """``length`` periods of noise (NOISE_ROWS, length) from a run's generators."""
        out = np.zeros((NOISE_ROWS, length))
        std, torque = self.std, np.asarray(self.torque, float)
        if std.any():
            out[:6] = (generators[0].standard_normal((length, 6)) * std).T
        if torque.any():
            out[6:] = (generators[1].standard_normal((length, 2)) * torque).T
        return out


@lru_cache(maxsize=64)
def step_function(controller: Controller, jit: bool = False, delay: int = 0) -> ca.Function:
    """``(X, c, r, noise, p) -> (X_next, c_next, tau, qdd, cp, saturated)`` for one period.

    X (6,) is the plant's joint state, c the controller's (2,) followed by the ``delay``
    commands still on their way to the motors (2 delay,), r the controller's data of the
    instant, noise (NOISE_ROWS,) the measurement errors and the torque noise, p the plant's
    parameters; tau (2,) is the torque applied over the period (saturated, times the gains,
    plus the noise), qdd (3,) the plant's accelerations at the instant, cp (2,) its CP through
    the model's kinematics, saturated 1 when a torque was clipped. With ``jit`` the function
    is compiled to C once and cached on disk (:func:`compiled_step`); without a compiler it
    runs interpreted.
    """
    ref = controller.reference
    model = ref.arm
    law = controller.law()
    X = ca.SX.sym("X", 6)
    c = ca.SX.sym("c", 2 + 2 * delay)
    r = ca.SX.sym("r", law.size1_in(0))
    noise = ca.SX.sym("noise", NOISE_ROWS)
    p = ca.SX.sym("p", len(PARAMETER_NAMES))
    measured = X + noise[:6]
    tau_cmd, c_next = law(r, measured[0:3], measured[3:6], c[:2])
    c_next = ca.vertcat(c_next, c[4:], tau_cmd) if delay else c_next
    sent = c[2:4] if delay else tau_cmd  # the command that reaches the motors now
    period = plant_period(model.kind, model.base, model.gravity, ref.period)
    X_next, qdd, tau = period(X, sent, p, noise[6:])
    s = kinematic_functions(model)["pose"](X[0:3])
    cp = s[0:2] + model.K * ca.vertcat(ca.cos(s[2]), ca.sin(s[2]))
    clipped = ca.fmin(ca.fmax(sent, -p[18:20]), p[18:20])
    saturated = ca.sum1(ca.fabs(sent - clipped)) > 0
    ins, outs = [X, c, r, noise, p], [X_next, c_next, tau, qdd, cp, saturated]
    names = (["X", "c", "r", "noise", "p"], ["X_next", "c_next", "tau", "qdd", "cp", "saturated"])
    step = ca.Function("step", ins, outs, *names)
    return compiled_step(step) if jit else step


SOURCES = (Path(compiled.__file__),)
"""The files besides the function itself that determine a compiled step's code."""


def compiled_step(step: ca.Function) -> ca.Function:
    """A period function compiled to C through :func:`cpopt.compiled.load_library`'s cache.

    The step holds the plan's model, controller gains and period as constants, so a library is
    one step: it is named by a hash of the function's serialization, which is computed without
    generating code. The first process that tracks a plan compiles it (about a second); every
    later one loads the cached library. The arithmetic is the function's, compiled with
    :data:`cpopt.compiled.FLAGS`.
    """
    library = compiled.load_library(library_name(step), SOURCES, lambda: [step])
    return library.functions[step.name()]


def library_name(step: ca.Function) -> str:
    """The cache name of a compiled period function: ``tracking-step-<hash>``, the hash of the
    function's serialization (its whole expression graph, constants included)."""
    return "tracking-step-" + hashlib.sha256(step.serialize().encode()).hexdigest()[:20]


@lru_cache(maxsize=64)
def _batch_function(step: ca.Function, length: int, runs: int) -> ca.Function:
    """``length`` periods accumulated over (X, c), mapped over ``runs`` runs."""
    return step.mapaccum("chunk", length, [0, 1], [0, 1]).map(runs)


def call_buffered(f: ca.Function, *args: np.ndarray) -> list[np.ndarray]:
    """``f(*args)`` with dense numeric inputs and outputs through CasADi's zero-copy buffer:
    the outputs as arrays of the function's shapes. An input with a fraction of the columns a
    mapped function takes is repeated, as CasADi's own call repeats it for every instance.
    Converting the batches' large inputs and outputs to and from DM took more than the
    simulation itself (a robustness run of two plans: 23.0 s through DM, 11.0 s buffered)."""
    buffer, trigger = f.buffer()
    inputs = [_full_input(f, i, np.asarray(a, float)) for i, a in enumerate(args)]
    outputs = [np.zeros(f.nnz_out(i)) for i in range(f.n_out())]
    for i, a in enumerate(inputs):
        buffer.set_arg(i, memoryview(a))
    for i, o in enumerate(outputs):
        buffer.set_res(i, memoryview(o))
    trigger()
    return [o.reshape(f.size_out(i), order="F") for i, o in enumerate(outputs)]


def _full_input(f: ca.Function, i: int, a: np.ndarray) -> np.ndarray:
    """Input i as f's buffer takes it: column-major, its columns repeated to f's count."""
    rows, cols = f.size_in(i)
    a = a.reshape(rows, -1, order="F") if a.ndim < 2 else a
    if a.shape[0] != rows or cols % a.shape[1]:
        raise ValueError(f"input {i} of {f.name()} is {a.shape}, not a part of {(rows, cols)}")
    return np.ravel(np.tile(a, (1, cols // a.shape[1])), order="F")


@dataclass(frozen=True)
class Batch:
    """Runs of one controller on many plants (one entry per run).

    Attributes
    ----------
    t : numpy.ndarray
        Control instants (n + 1,) [s].
    x_final : numpy.ndarray
        Plant joint state at the last instant reached (N, 6).
    max_cp_error : numpy.ndarray
        Largest CP error over the instants reached (N,) [m].
    diverged_at : numpy.ndarray
        When a run was stopped as diverged, NaN for the others (N,) [s].
    peak_torque : numpy.ndarray
        Largest |torque| applied (N, 2) [N m or N].
    saturated_fraction : numpy.ndarray
        Fraction of the periods in which a torque was clipped (N,).
    arrival : numpy.ndarray
        When the run's progress reached the end of the plan (N,) [s]: T for a controller at the
        plan's pace; NaN for a run that diverged or had not arrived at the end of the horizon.
    max_lag : numpy.ndarray
        Largest lag of the tracked plan instant behind the clock, t_k - s_k (N,) [s].
    log : dict or None
        For a single run: ``x`` (m + 1, 6), ``qdd`` (m, 3), ``tau`` (m, 2), ``saturated``
        (m,), ``cp`` (m + 1, 2), ``progress`` (m + 1,) (the plan's instant tracked [s]), up to
        the last instant reached.
    """

    t: np.ndarray
    x_final: np.ndarray
    max_cp_error: np.ndarray
    diverged_at: np.ndarray
    peak_torque: np.ndarray
    saturated_fraction: np.ndarray
    arrival: np.ndarray
    max_lag: np.ndarray
    log: dict | None = None

    @property
    def diverged(self) -> np.ndarray:
        """True for runs stopped as diverged (N,)."""
        return ~np.isnan(self.diverged_at)

    @property
    def arrived(self) -> np.ndarray:
        """True for runs whose progress reached the end of the plan (N,)."""
        return ~np.isnan(self.arrival)


def _first_bad(X_next: np.ndarray, cp_err: np.ndarray) -> np.ndarray:
    """Index of the first diverged period of each run in a chunk, -1 for none (A, L)."""
    with np.errstate(invalid="ignore"):
        bad = (
            ~np.isfinite(X_next).all(axis=0)
            | (np.abs(X_next[3:6]) > DIVERGED_VELOCITY).any(axis=0)
            | ~(cp_err <= DIVERGED_CP)
        )
    return np.where(bad.any(axis=1), bad.argmax(axis=1), -1)


def _noise_block(noise: Noise, runs: np.ndarray, rngs: list, length: int) -> np.ndarray:
    """Measurement and torque noise (NOISE_ROWS, length * len(runs)), run after run."""
    return np.hstack([noise.draw(rngs[i], length) for i in runs])


def initial_controller_state(controller: Controller, delay: int) -> np.ndarray:
    """The controller's initial state (2 + 2 delay,): its own, then the commands on their
    way to the motors, the plan's initial torque (the arm held at its start before t0)."""
    held = np.tile(np.asarray(controller.reference.tau[0], float), delay)
    return np.r_[np.asarray(controller.initial_state(), float).ravel(), held]


class _Totals:
    """Per-run figures accumulated chunk by chunk (N runs)."""

    def __init__(self, runs: int) -> None:
        self.max_err = np.zeros(runs)
        self.diverged_at = np.full(runs, np.nan)
        self.arrival = np.full(runs, np.nan)
        self.max_lag = np.zeros(runs)
        self.peak = np.zeros((runs, 2))
        self.saturated = np.zeros(runs)
        self.steps = np.zeros(runs, int)

    def add(self, active, upto, bad, done, chunk: dict, t_after) -> None:
        """Fold in one chunk: ``upto[a]`` periods of active run a count, ``bad[a]`` and
        ``done[a]`` are the periods after which it diverged or arrived (-1: not); t_after
        (length,) are the instants that end the chunk's periods."""
        for a, i in enumerate(active):
            m = upto[a]
            self.max_err[i] = max(self.max_err[i], chunk["cp_err"][a, :m].max())
            self.max_lag[i] = max(self.max_lag[i], chunk["lag"][a, :m].max())
            self.peak[i] = np.maximum(self.peak[i], np.abs(chunk["tau"][:, a, :m]).max(axis=1))
            self.saturated[i] += chunk["sat"][0, a, :m].sum()
            self.steps[i] += m
            if bad[a] >= 0:
                self.diverged_at[i] = t_after[bad[a]]
            elif done[a] >= 0:
                self.arrival[i] = t_after[done[a]]


def _first(mask: np.ndarray) -> np.ndarray:
    """Index of the first True of each row (A, L), -1 for none."""
    return np.where(mask.any(axis=1), mask.argmax(axis=1), -1)


def simulate_batch(
    controller: Controller,
    parameters: np.ndarray,
    noise: Noise | None = None,
    jit: bool = False,
    log: bool = False,
    delay: int = 0,
) -> Batch:
    """Run a controller on plants with the given parameters, from the plan's start state.

    Each run lasts until its controller's progress reaches the end of the plan (see the module
    docstring), until it diverges, or to the end of the controller's horizon.

    Parameters
    ----------
    controller : Controller
        The controller (its reference fixes the grid and the model).
    parameters : numpy.ndarray
        Plant parameters (N, 20), one row per run (:data:`~cpopt.tracking.plant.PARAMETER_NAMES`).
    noise : Noise, optional
        Measurement noise (none by default); run i draws from ``default_rng([seed, i])``.
    jit : bool
        Compile the period function to C, cached on disk (worth it for batches of hundreds of
        runs, and for a plan tracked again in a later process).
    log : bool
        Keep every period of a single run (N = 1) in ``Batch.log``.
    delay : int
        Actuation delay in control periods (:meth:`cpopt.tracking.plant.Plant.delay_steps`).
    """
    ref = controller.reference
    noise = noise or Noise()
    P = np.atleast_2d(np.asarray(parameters, float)).T
    N, horizon, t = P.shape[1], controller.horizon, controller.times
    step = step_function(controller, jit, delay)
    schedule = controller.schedule()
    rngs = [noise.generators(i) for i in range(N)]
    X = np.tile(ref.x[0][:, None], (1, N))
    c = np.tile(initial_controller_state(controller, delay)[:, None], (1, N))
    active = np.arange(N)
    totals = _Totals(N)
    logs: dict[str, list] = {k: [] for k in ("x", "qdd", "tau", "saturated", "cp", "progress")}
    for k0 in range(0, horizon, CHUNK):
        length, A = min(CHUNK, horizon - k0), active.size
        f = _batch_function(step, length, A)
        # per-period inputs run after run: each run's parameters repeated over its periods
        params = np.repeat(P[:, active], length, axis=1)
        out = call_buffered(f, X[:, active], c[:, active], schedule[:, k0 : k0 + length],
                            _noise_block(noise, active, rngs, length), params)  # fmt: skip
        chunk = _Chunk.judged(controller, k0, c[:, active], out)
        totals.add(active, chunk.upto, chunk.bad, chunk.done, chunk.figures,
                   t[k0 + 1 : k0 + length + 1])  # fmt: skip
        if log:
            outputs = (chunk.qdd, chunk.figures["tau"], chunk.figures["sat"], chunk.cp)
            _log_chunk(logs, X[:, active[0]], chunk.X_next[:, 0], outputs, chunk.upto[0])
            logs["progress"].append(ref.t[0] + chunk.s[0, : chunk.upto[0] + 1] * ref.period)
        last = chunk.upto - 1
        X[:, active] = chunk.X_next[:, np.arange(A), last]
        c[:, active] = chunk.c_next[:, np.arange(A), last]
        active = active[chunk.stop < 0]
        if active.size == 0:
            break
    return _batch(ref, t, X, totals, _join_log(logs, ref.arm) if log else None)


@dataclass(frozen=True)
class _Chunk:
    """One chunk of periods of the active runs, judged: where each run stops (diverged, or its
    progress reached the plan's end) and the figures the totals take."""

    X_next: np.ndarray  # (6, A, length)
    c_next: np.ndarray  # (2 + 2 delay, A, length)
    qdd: np.ndarray
    cp: np.ndarray
    s: np.ndarray  # the plan's instant tracked, in periods (A, length + 1)
    bad: np.ndarray
    done: np.ndarray
    stop: np.ndarray
    upto: np.ndarray
    figures: dict

    @classmethod
    def judged(cls, controller: Controller, k0: int, c: np.ndarray, out) -> _Chunk:
        """The chunk from the mapped period function's outputs ``out`` (from instant k0, the
        runs' controller states c at k0)."""
        ref = controller.reference
        A = c.shape[1]
        length = out[0].shape[1] // A
        X_next, c_next, tau, qdd, cp, sat = (
            np.asarray(o).reshape(o.shape[0], A, length) for o in out
        )
        k = np.arange(k0, k0 + length + 1)
        c_all = np.concatenate([c[:, :, None], c_next], axis=2)  # (2 + 2 delay, A, length + 1)
        s = controller.progress(k, c_all[:2])
        cp_err = np.linalg.norm(cp - plan_cp_at(ref, s[:, :-1]), axis=0)
        bad = _first_bad(X_next, cp_err)
        done = _first(s[:, 1:] >= ref.steps - 1e-9)
        stop = np.where(bad >= 0, bad, done)
        upto = np.where(stop >= 0, stop + 1, length)
        figures = {"cp_err": cp_err, "lag": (k[:-1] - s[:, :-1]) * ref.period, "tau": tau,
                   "sat": sat}  # fmt: skip
        return cls(X_next, c_next, qdd, cp, s, bad, done, stop, upto, figures)


def _batch(ref, t: np.ndarray, X: np.ndarray, totals: _Totals, log) -> Batch:
    """The batch's result from the runs' final states X (6, N) and their totals; a run that
    did not diverge also counts its CP error at its final state."""
    ok = np.isnan(totals.diverged_at)
    end_err = np.linalg.norm(cp_points(ref.arm, X.T[:, :3]) - ref.cp[-1, :, 0], axis=1)
    totals.max_err[ok] = np.maximum(totals.max_err[ok], end_err[ok])
    return Batch(
        t=t,
        x_final=X.T.copy(),
        max_cp_error=totals.max_err,
        diverged_at=totals.diverged_at,
        peak_torque=totals.peak,
        saturated_fraction=totals.saturated / np.maximum(totals.steps, 1),
        arrival=totals.arrival,
        max_lag=totals.max_lag,
        log=log,
    )


def plan_cp_at(ref, s: np.ndarray) -> np.ndarray:
    """The plan's CP (2, ...) at fractional instants s (...) of its grid, interpolated linearly
    (exact at whole instants)."""
    s = np.clip(s, 0, ref.steps)
    i = np.minimum(np.floor(s).astype(int), ref.steps - 1)
    w = s - i
    cp = ref.cp[:, :, 0]
    return ((1 - w)[..., None] * cp[i] + w[..., None] * cp[i + 1]).transpose(-1, *range(s.ndim))


def _log_chunk(logs: dict, x_first, x_next, outputs, m: int) -> None:
    """Keep the first m periods of a single run's chunk (its state before each period)."""
    logs["x"].append(np.column_stack([x_first, x_next[:, : m - 1]]).T)
    for key, value in zip(("qdd", "tau", "saturated", "cp"), outputs, strict=True):
        logs[key].append(value[:, 0, :m].T)
    logs["x_last"] = [x_next[:, m - 1]]


def _join_log(logs: dict, model) -> dict:
    """The chunks of a single run joined, with the state and CP of the last instant reached."""
    progress = logs.pop("progress")
    out = {k: np.concatenate(v) for k, v in logs.items() if k != "x_last"}
    # each chunk's progress starts at its first instant: keep one per instant
    out["progress"] = np.concatenate([p[:-1] for p in progress] + [progress[-1][-1:]])
    out["x"] = np.vstack([out["x"], logs["x_last"][0]])
    out["cp"] = np.vstack([out["cp"], cp_points(model, out["x"][-1:, :3])])
    out["saturated"] = out["saturated"][:, 0] > 0
    return out
