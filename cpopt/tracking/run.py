"""One tracking run of a plan: choose the controller, build the plant, simulate, measure."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model.robot import Arm
from .controller import Controller
from .dfl import DEFAULT_POLES, DFLController, SingularTrackingError
from .outcome import Tolerance, TrackingOutcome, final_errors
from .plant import Plant
from .reference import Reference, reference
from .simulation import Noise, simulate_batch
from .timescaled import MAX_DELAY, TimeScaledTVLQR
from .tvlqr import DEFAULT_Q, DEFAULT_QF, TVLQRController

CONTROLLERS = ("tvlqr", "tvlqr_timescaled", "dfl")
ENGINES = ("cpopt", "mujoco")
"""Plants a run can be simulated on (``tracking.plant.engine``)."""
DEFAULT_RATE_HZ = 1000.0
"""Default control rate [Hz]."""


def make_controller(
    name: str,
    ref: Reference,
    Q=DEFAULT_Q,
    R=None,
    Qf=DEFAULT_QF,
    poles=DEFAULT_POLES,
    torque_limit=None,
    max_delay: float = MAX_DELAY,
) -> Controller:
    """A controller by name (``tvlqr`` uses Q, R, Qf, R None for the plan-relative default
    :func:`~cpopt.tracking.tvlqr.relative_R`; ``tvlqr_timescaled`` those and the motors'
    ``torque_limit`` [N m or N] and ``max_delay`` (a fraction of the plan's duration);
    ``dfl`` uses the poles)."""
    if name == "tvlqr":
        return TVLQRController(ref, Q, R, Qf)
    if name == "tvlqr_timescaled":
        return TimeScaledTVLQR(ref, torque_limit, Q, R, Qf, max_delay)
    if name == "dfl":
        return DFLController(ref, poles)
    raise ValueError(f"controller must be one of {CONTROLLERS}, got {name!r}")


def model_plant(arm: Arm, torque_limit=None) -> Plant:
    """The plant equal to the model: no friction, saturation at ``torque_limit`` if given."""
    return Plant(arm, torque_limit=None if torque_limit is None else tuple(torque_limit))


def track(
    plan,
    controller: str | Controller = "tvlqr",
    plant: Plant | None = None,
    noise: Noise | None = None,
    rate_hz: float = DEFAULT_RATE_HZ,
    tolerance: Tolerance | None = None,
    engine: str = "cpopt",
    **gains,
) -> TrackingOutcome:
    """Track a plan with a controller on a plant, sampled at ``rate_hz``.

    Parameters
    ----------
    plan : CPPlan or JointPlan
        The plan (its arm is the controller's model). Ignored when ``controller`` is a
        :class:`Controller`, which carries its own reference.
    controller : str or Controller
        ``tvlqr``, ``tvlqr_timescaled`` or ``dfl``, or a controller built by
        :func:`make_controller` (a ``tvlqr_timescaled`` built here fits the plant's torque
        limits).
    plant : Plant, optional
        The simulated arm (default: the model, no friction, no saturation).
    noise : Noise, optional
        Measurement and torque noise (default: none).
    rate_hz : float
        Control rate [Hz].
    tolerance : Tolerance, optional
        Success criterion.
    engine : str
        ``cpopt`` (the built-in plant: CasADi's RK4, compiled) or ``mujoco`` (MuJoCo's RK4,
        :mod:`cpopt.tracking.mujoco_plant`; needs ``cpopt[mujoco]``; without actuator gains,
        delay or torque noise).
    **gains
        ``Q``, ``R``, ``Qf``, ``poles`` or ``max_delay`` for :func:`make_controller`.

    A run lasts until the controller's progress reaches the end of the plan (at T, or later
    for ``tvlqr_timescaled`` after slowing its reference; :attr:`TrackingOutcome.delay`) and
    is judged there against the goal.
    """
    if isinstance(controller, str):
        limit = plant.torque_limit if plant is not None else None
        controller = make_controller(
            controller, reference(plan, rate_hz), torque_limit=limit, **gains
        )
    ref = controller.reference
    plant = plant or model_plant(ref.arm)
    if engine not in ENGINES:
        raise ValueError(f"engine must be one of {ENGINES}, got {engine!r}")
    if engine == "mujoco":
        from .mujoco_plant import simulate_mujoco  # MuJoCo is imported only when asked for

        batch = simulate_mujoco(controller, plant, noise)
    else:
        delay = plant.delay_steps(ref.period)
        batch = simulate_batch(
            controller, plant.parameters()[None, :], noise, log=True, delay=delay
        )
    log = batch.log
    m = log["tau"].shape[0]
    diverged = None if not batch.diverged[0] else float(batch.diverged_at[0])
    progress = log["progress"]
    return TrackingOutcome(
        controller=controller.name,
        rate_hz=1.0 / ref.period,
        t=batch.t[: m + 1],
        x=log["x"],
        qdd=log["qdd"],
        tau=log["tau"],
        saturated=log["saturated"],
        cp=log["cp"],
        cp_ref=np.column_stack([np.interp(progress, ref.t, ref.cp[:, i, 0]) for i in (0, 1)]),
        diverged_at=diverged,
        progress=progress,
        arrived=bool(batch.arrived[0]),
        final=final_errors(ref.arm, ref.goal, log["x"][-1:]),
        tolerance=tolerance or Tolerance(),
    )


@dataclass(frozen=True)
class TrackingRefused:
    """A controller that cannot follow the plan (dfl where gamma crosses zero), and why."""

    controller: str
    message: str

    def summary(self) -> dict:
        """The ``tracking`` entry of ``solution.json``: not a success, with the reason."""
        return {"controller": self.controller, "success": False, "error": self.message}


def track_problem(problem, plan) -> TrackingOutcome | TrackingRefused:
    """Track a plan as the problem's ``tracking`` block asks (see docs/problems.md);
    ``flat_mpc`` re-plans from the problem (:func:`cpopt.tracking.mpc.track_flat_mpc`).

    The plant's torque limits are ``tracking.plant.torque_limit``, else the problem's
    ``optimizer.limits.torque``; its links are the arm's with the block's overrides.
    """
    from dataclasses import replace

    from ..problem import plant_links

    spec = problem.spec.tracking
    limit = spec.plant.torque_limit or problem.spec.optimizer.limits.torque
    plant = Plant(
        arm=replace(plan.arm, links=tuple(plant_links(problem.spec))),
        viscous=tuple(spec.plant.friction.viscous),
        coulomb=tuple(spec.plant.friction.coulomb),
        torque_limit=None if all(v is None for v in limit) else tuple(limit),
        gain=tuple(spec.plant.gain),
        delay=spec.plant.delay,
    )
    noise = Noise(
        tuple(spec.noise.position),
        tuple(spec.noise.velocity),
        spec.noise.seed,
        tuple(spec.plant.torque_noise),
    )
    gains = {"Q": spec.Q, "R": spec.R, "Qf": spec.Qf, "poles": spec.poles}
    if spec.controller == "flat_mpc":  # re-plans with the flat optimizer: imported when used
        from .mpc import MPCSettings, track_flat_mpc

        settings = MPCSettings(
            spec.replan_period, spec.replan_delay, spec.replan_deadline, method=spec.replan_method
        )
        return track_flat_mpc(problem, plan, plant, noise, spec.rate_hz, None, settings, **gains)
    try:
        return track(
            plan, spec.controller, plant, noise, spec.rate_hz, engine=spec.plant.engine, **gains
        )
    except SingularTrackingError as err:
        return TrackingRefused(spec.controller, str(err))
