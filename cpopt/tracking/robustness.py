"""Robustness of a controller on a plan: parameter sweeps and Monte Carlo plants.

The *benchmark plant* of a plan is the model with realistic imperfections (module constants
below): joint friction scaled to the plan, measurement noise, and saturation at the problem's
torque limits (1.5 times the plan's peak torque where the problem has none: motors sized
with a 50 % margin). Around it,

* a **sweep** moves one parameter at a time (the 12 link parameters and the 6 friction
  coefficients of :data:`~cpopt.tracking.plant.PARAMETER_NAMES`) over +-``sweep_range`` in
  ``sweep_steps`` steps, the others at their benchmark values;
* **Monte Carlo** trials draw every one of those parameters uniformly within
  +-``monte_carlo_range``, each trial with its own noise seed.

A run succeeds by :class:`~cpopt.tracking.outcome.Tolerance`, judged when its controller's
progress reaches the end of the plan (T, or later for ``tvlqr_timescaled``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .controller import Controller
from .outcome import Tolerance, final_errors
from .plant import Plant
from .reference import Reference
from .simulation import Noise, simulate_batch

NOISE_POSITION = 1e-4
"""Standard deviation of measured joint positions [rad or m] (a 16-bit encoder's step)."""
NOISE_VELOCITY = 1e-2
"""Standard deviation of measured joint velocities [rad/s or m/s] (filtered differences)."""
FRICTION_FRACTION = (0.02, 0.02, 0.002)
"""Coulomb friction of joints 1..3 as a fraction of their torque scale (actuated joints: the
plan's peak torque, as of a geared motor; the passive joint: m3 g0 d3, its largest gravity
torque, as of a sealed bearing without a gearbox). The viscous coefficient is the same
fraction per unit velocity [s/rad or s/m]: at 1 rad/s or 1 m/s it equals the Coulomb level."""
MOTOR_MARGIN = 1.5
"""Torque limit of a problem without one: this factor times the plan's peak torque."""
VARIED = 18
"""The parameters varied: the 12 link parameters and the 6 friction coefficients."""


def benchmark_plant(controller: Controller | Reference, torque_limit=None) -> tuple[Plant, Noise]:
    """The benchmark plant and noise of a controller's plan (see the module docstring).

    Parameters
    ----------
    controller : Controller or Reference
        Gives the plan (its reference) and the model.
    torque_limit : sequence of (float or None), optional
        The problem's torque limits [N m or N].
    """
    ref = controller if isinstance(controller, Reference) else controller.reference
    arm = ref.arm
    peak_tau = np.abs(ref.tau).max(axis=0)
    link3 = arm.links[2]
    scale = np.array([*peak_tau, link3.mass * arm.gravity * link3.d])
    limits = list(torque_limit or (None, None))
    limits = tuple(
        MOTOR_MARGIN * p if v is None else float(v) for v, p in zip(limits, peak_tau, strict=True)
    )
    plant = Plant(
        arm=arm,
        viscous=tuple(np.multiply(FRICTION_FRACTION, scale)),
        coulomb=tuple(np.multiply(FRICTION_FRACTION, scale)),
        torque_limit=limits,
    )
    noise = Noise(position=(NOISE_POSITION,) * 3, velocity=(NOISE_VELOCITY,) * 3)
    return plant, noise


def sweep_parameters(nominal: np.ndarray, span: float = 0.2, steps: int = 21) -> np.ndarray:
    """Parameter rows (VARIED * steps, 22): each varied parameter scaled by 1 - span .. 1 + span."""
    factors = np.linspace(1 - span, 1 + span, steps)
    rows = np.tile(nominal, (VARIED * steps, 1))
    for i in range(VARIED):
        rows[i * steps : (i + 1) * steps, i] *= factors
    return rows


def monte_carlo_parameters(nominal: np.ndarray, trials: int, span: float = 0.1, seed: int = 0):
    """Parameter rows (trials, 22): every varied parameter scaled by U(1 - span, 1 + span)."""
    rng = np.random.default_rng(seed)
    rows = np.tile(nominal, (trials, 1))
    rows[:, :VARIED] *= rng.uniform(1 - span, 1 + span, (trials, VARIED))
    return rows


@dataclass(frozen=True)
class Trials:
    """Outcome of a set of runs: success per run, errors, divergence, and how much later than
    the plan each run was judged [s] (NaN where it did not arrive) (one entry per run)."""

    success: np.ndarray
    max_cp_error: np.ndarray
    final_cp_error: np.ndarray
    diverged: np.ndarray
    delay: np.ndarray

    @property
    def rate(self) -> float:
        """Fraction of runs that succeeded."""
        return float(self.success.mean())


def run_trials(
    controller: Controller,
    parameters: np.ndarray,
    noise: Noise,
    tolerance: Tolerance | None = None,
    jit: bool = True,
    delay: int = 0,
) -> Trials:
    """Run a controller on plants with the given parameter rows and judge each run (with an
    actuation delay of ``delay`` control periods)."""
    batch = simulate_batch(controller, parameters, noise, jit=jit, delay=delay)
    ref = controller.reference
    final = final_errors(ref.arm, ref.goal, batch.x_final)
    return Trials(
        success=final.success(tolerance or Tolerance(), batch.diverged | ~batch.arrived),
        max_cp_error=batch.max_cp_error,
        final_cp_error=final.cp,
        diverged=batch.diverged,
        delay=batch.arrival - ref.t[-1],
    )


MASS_PARAMETERS = (1, 3, 5, 7)
"""Masses and inertias of links 1 and 2 in the parameter vector: scaled together, a link
stays a uniform rod of another mass."""


def mass_margin(
    controller: Controller,
    nominal: np.ndarray,
    noise: Noise,
    largest: float = 0.5,
    step: float = 0.01,
    tolerance: Tolerance | None = None,
    jit: bool = True,
) -> tuple[float, float]:
    """The largest mass error of links 1 and 2 (both heavier, both lighter) a controller
    survives: every error from 0 up to it succeeds, in steps of ``step`` (fractions)."""
    errors = np.arange(step, largest + step / 2, step)
    factors = np.concatenate([1 + errors, 1 - errors])
    rows = np.tile(nominal, (factors.size, 1))
    rows[:, list(MASS_PARAMETERS)] *= factors[:, None]
    ok = run_trials(controller, rows, noise, tolerance, jit).success.reshape(2, -1)
    # the number of leading successes on each side gives the margin
    survived = [int(np.argmin(side)) if not side.all() else side.size for side in ok]
    return tuple(float(n * step) for n in survived)
