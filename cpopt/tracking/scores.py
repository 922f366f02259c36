"""Robustness figures of ``flat_mpc`` and RealAIGym-style scores of any controller.

``flat_mpc`` re-plans differently on every plant, so its runs go one at a time
(:func:`mpc_trials`), on the same plant parameters and noise seeds as a batch of the other
controllers (:func:`cpopt.tracking.robustness.run_trials`), judged by the same tolerance.

A score, after the RealAIGym double-pendulum leaderboard, is the fraction of successful runs
in each category of :data:`SCORE_VALUES` values, on the model (no friction, no noise, the
motors of the benchmark plant) perturbed in one way at a time:

* ``model``: each of the 12 link parameters (length, mass, centre of mass, inertia of each
  link) scaled by 0.75 .. 1.25, one at a time (the category's fraction over all 12 x 21);
* ``velocity_noise``: measurement noise on the joint velocities, standard deviation
  0 .. :data:`VELOCITY_NOISE_MAX`;
* ``torque_noise``: noise on the applied torques, standard deviation 0 ..
  :data:`TORQUE_NOISE_MAX` of each motor's limit;
* ``gain``: both actuator gains 1 -+ :data:`GAIN_SPAN`;
* ``delay``: actuation delay 0 .. :data:`DELAY_MAX` (whole control periods);

``overall`` is the mean of the categories measured.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from .mpc import FlatMPC, MPCRun
from .outcome import Tolerance, final_errors
from .robustness import Trials, run_trials
from .simulation import Noise

SCORE_VALUES = 21
"""Values per score category."""
MODEL_SPAN = 0.25
"""The link parameters are scaled by 1 +- this."""
LINK_PARAMETERS = 12
"""The first 12 plant parameters: length, mass, centre of mass and inertia of each link."""
VELOCITY_NOISE_MAX = 0.2
"""Largest standard deviation of the velocity noise of the ``velocity_noise`` category
[rad/s or m/s] (twenty times the benchmark plant's)."""
TORQUE_NOISE_MAX = 0.1
"""Largest standard deviation of the ``torque_noise`` category, a fraction of each motor's
torque limit (the benchmark's motors: the problem's limits, or 1.5 x the plan's peak)."""
GAIN_SPAN = 0.5
"""The actuator gains are scaled by 1 +- this (RealAIGym's 0.5 .. 1.5)."""
DELAY_MAX = 0.04
"""Largest actuation delay of the ``delay`` category [s] (RealAIGym's 40 ms)."""
GAINS = slice(20, 22)
"""The actuator gains in the plant's parameter vector."""
TORQUE_LIMITS = slice(18, 20)
"""The motors' torque limits in the plant's parameter vector [N m or N]."""
CATEGORIES = ("model", "velocity_noise", "torque_noise", "gain", "delay")


def mpc_trials(
    mpc: FlatMPC,
    parameters: np.ndarray,
    noise: Noise,
    tolerance: Tolerance | None = None,
    delay: int = 0,
) -> tuple[Trials, list[MPCRun]]:
    """``flat_mpc`` on plants with the given parameter rows (N, 22), run i's noise drawn as
    in a batch, an actuation delay of ``delay`` control periods; the judged trials and the
    runs."""
    rows = np.atleast_2d(parameters)
    runs = [mpc.run(row, noise, i, delay) for i, row in enumerate(rows)]
    ref = mpc.reference
    x_final = np.array([run.x[-1] for run in runs])
    diverged = np.array([run.diverged_at is not None for run in runs])
    final = final_errors(ref.arm, ref.goal, x_final)
    max_cp = np.array(
        [np.linalg.norm(r.cp - ref.cp[: len(r.cp), :, 0], axis=1).max() for r in runs]
    )
    trials = Trials(
        success=final.success(tolerance or Tolerance(), diverged),
        max_cp_error=max_cp,
        final_cp_error=final.cp,
        diverged=diverged,
        delay=np.where(diverged, np.nan, 0.0),
    )
    return trials, runs


Judge = Callable[[np.ndarray, Noise, int], np.ndarray]
"""``judge(parameter rows (N, 22), noise, delay) -> success (N,)``: one controller's runs
with an actuation delay of ``delay`` control periods."""


def batch_judge(controller, tolerance: Tolerance | None = None) -> Judge:
    """A judge running a tracking controller's batch (:func:`run_trials`)."""
    # a delayed step is another function: compiled, each one-run batch of the delay category
    # would wait seconds for the compiler
    return lambda rows, noise, delay=0: (
        run_trials(controller, rows, noise, tolerance, jit=delay == 0, delay=delay).success
    )


def mpc_judge(mpc: FlatMPC, tolerance: Tolerance | None = None) -> Judge:
    """A judge running ``flat_mpc`` one plant at a time (:func:`mpc_trials`)."""
    return lambda rows, noise, delay=0: mpc_trials(mpc, rows, noise, tolerance, delay)[0].success


def model_rows(nominal: np.ndarray, values: int = SCORE_VALUES) -> np.ndarray:
    """Parameter rows (12 * values, 22): each link parameter scaled by 1 -+ MODEL_SPAN."""
    factors = np.linspace(1 - MODEL_SPAN, 1 + MODEL_SPAN, values)
    rows = np.tile(nominal, (LINK_PARAMETERS * values, 1))
    for i in range(LINK_PARAMETERS):
        rows[i * values : (i + 1) * values, i] *= factors
    return rows


def gain_rows(nominal: np.ndarray, values: int = SCORE_VALUES) -> np.ndarray:
    """Parameter rows (values, 22): both actuator gains scaled by 1 -+ GAIN_SPAN."""
    rows = np.tile(nominal, (values, 1))
    rows[:, GAINS] *= np.linspace(1 - GAIN_SPAN, 1 + GAIN_SPAN, values)[:, None]
    return rows


def scores(
    judge: Judge, nominal: np.ndarray, period: float, values: int = SCORE_VALUES
) -> dict[str, float]:
    """The score of each category and ``overall`` (see the module docstring) of a controller
    on a plant with parameters ``nominal`` (22,) (the model with the benchmark's motors),
    controlled every ``period`` [s]."""
    out = dict.fromkeys(CATEGORIES, math.nan)
    one, fractions = nominal[None, :], np.linspace(0.0, 1.0, values)
    out["model"] = float(judge(model_rows(nominal, values), Noise(), 0).mean())
    velocity = [
        judge(one, Noise(velocity=(f * VELOCITY_NOISE_MAX,) * 3, seed=k), 0)[0]
        for k, f in enumerate(fractions)
    ]
    out["velocity_noise"] = float(np.mean(velocity))
    scale = TORQUE_NOISE_MAX * nominal[TORQUE_LIMITS]
    torque = [
        judge(one, Noise(torque=tuple(f * scale), seed=k), 0)[0] for k, f in enumerate(fractions)
    ]
    out["torque_noise"] = float(np.mean(torque))
    out["gain"] = float(judge(gain_rows(nominal, values), Noise(), 0).mean())
    delays = np.rint(fractions * DELAY_MAX / period).astype(int)
    out["delay"] = float(np.mean([judge(one, Noise(), int(d))[0] for d in delays]))
    out["overall"] = float(np.mean([out[k] for k in CATEGORIES]))
    return out


def score_line(plan: str, controller: str, figures: dict) -> str:
    """``SCORE <plan> <controller> model=... velocity_noise=... torque_noise=... gain=...
    delay=... overall=...``."""
    words = " ".join(f"{k}={figures[k]:.3f}" for k in (*CATEGORIES, "overall"))
    return f"SCORE {plan} {controller} {words}"


__all__ = [
    "CATEGORIES",
    "SCORE_VALUES",
    "batch_judge",
    "gain_rows",
    "model_rows",
    "mpc_judge",
    "mpc_trials",
    "score_line",
    "scores",
]
