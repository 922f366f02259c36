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
* ``torque_noise``, ``gain`` (actuator gain 0.5 .. 1.5) and ``delay`` (0 .. 40 ms): NaN, the
  simulated plant has no torque noise, actuator gain or measurement delay yet;

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
CATEGORIES = ("model", "velocity_noise", "torque_noise", "gain", "delay")


def mpc_trials(
    mpc: FlatMPC, parameters: np.ndarray, noise: Noise, tolerance: Tolerance | None = None
) -> tuple[Trials, list[MPCRun]]:
    """``flat_mpc`` on plants with the given parameter rows (N, 20), run i's noise drawn from
    ``default_rng([noise.seed, i])`` as in a batch; the judged trials and the runs."""
    runs = [mpc.run(row, noise, i) for i, row in enumerate(np.atleast_2d(parameters))]
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


Judge = Callable[[np.ndarray, Noise], np.ndarray]
"""``judge(parameter rows (N, 20), noise) -> success (N,)``: one controller's runs."""


def batch_judge(controller, tolerance: Tolerance | None = None) -> Judge:
    """A judge running a tracking controller's batch (:func:`run_trials`)."""
    return lambda rows, noise: run_trials(controller, rows, noise, tolerance).success


def mpc_judge(mpc: FlatMPC, tolerance: Tolerance | None = None) -> Judge:
    """A judge running ``flat_mpc`` one plant at a time (:func:`mpc_trials`)."""
    return lambda rows, noise: mpc_trials(mpc, rows, noise, tolerance)[0].success


def model_rows(nominal: np.ndarray, values: int = SCORE_VALUES) -> np.ndarray:
    """Parameter rows (12 * values, 20): each link parameter scaled by 1 -+ MODEL_SPAN."""
    factors = np.linspace(1 - MODEL_SPAN, 1 + MODEL_SPAN, values)
    rows = np.tile(nominal, (LINK_PARAMETERS * values, 1))
    for i in range(LINK_PARAMETERS):
        rows[i * values : (i + 1) * values, i] *= factors
    return rows


def scores(judge: Judge, nominal: np.ndarray, values: int = SCORE_VALUES) -> dict[str, float]:
    """The score of each category and ``overall`` (see the module docstring) of a controller
    on a plant with parameters ``nominal`` (20,) (the model with the benchmark's motors)."""
    out = dict.fromkeys(CATEGORIES, math.nan)
    out["model"] = float(judge(model_rows(nominal, values), Noise()).mean())
    noisy = [
        judge(nominal[None, :], Noise(velocity=(float(s),) * 3, seed=k))[0]
        for k, s in enumerate(np.linspace(0.0, VELOCITY_NOISE_MAX, values))
    ]
    out["velocity_noise"] = float(np.mean(noisy))
    measured = [v for v in out.values() if not math.isnan(v)]
    out["overall"] = float(np.mean(measured))
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
    "model_rows",
    "mpc_judge",
    "mpc_trials",
    "score_line",
    "scores",
]
