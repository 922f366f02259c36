"""The MuJoCo plant (``tracking.plant.engine: mujoco``): the same controllers, noise, friction
and saturation as the built-in plant (:mod:`cpopt.tracking.simulation`), the arm integrated by
MuJoCo instead (:func:`cpopt.mujoco_arm.arm_model`, RK4, :func:`~cpopt.mujoco_arm.
steps_per_period` steps per control period).

One run at a time, a Python loop over the control periods: the controller's law is the same
CasADi function, called once per period with the CP through the function's zero-copy buffer;
viscous friction is MuJoCo's joint damping and the
smoothed Coulomb friction is added to the passive forces by a callback, both evaluated at every
RK4 stage as the built-in plant does. A run stops and is judged by the built-in plant's rules
(diverged, or the controller's progress at the end of the plan).
"""

from __future__ import annotations

import contextlib

import casadi as ca
import numpy as np

from ..model.kinematics import kinematic_functions
from ..model.mujoco_arm import arm_model, arm_state, require_mujoco, steps_per_period
from .controller import Controller
from .plant import COULOMB_VELOCITY_SCALE, NO_LIMIT, Plant
from .simulation import DIVERGED_CP, DIVERGED_VELOCITY, Batch, Noise, plan_cp_at


@contextlib.contextmanager
def coulomb_friction(coulomb):
    """MuJoCo's passive-force callback set to the plant's smoothed Coulomb friction of joints
    1..3 [N m or N] for the block (none when all are 0); the previous callback restored."""
    mujoco = require_mujoco()
    level = np.asarray(coulomb, float)
    if not level.any():
        yield
        return

    def passive(model, data):
        data.qfrc_passive[:3] -= level * np.tanh(data.qvel[:3] / COULOMB_VELOCITY_SCALE)

    before = mujoco.get_mjcb_passive()
    mujoco.set_mjcb_passive(passive)
    try:
        yield
    finally:
        mujoco.set_mjcb_passive(before)


class _Log:
    """One run's periods as :attr:`Batch.log` keeps them."""

    def __init__(self) -> None:
        self.rows: dict[str, list] = {k: [] for k in ("x", "qdd", "tau", "saturated", "cp")}
        self.progress: list[float] = []

    def add(self, x, qdd, tau, saturated, cp, s) -> None:
        for key, value in zip(self.rows, (x, qdd, tau, saturated, cp), strict=True):
            self.rows[key].append(np.array(value))
        self.progress.append(s)

    def joined(self, x_last, cp_last, s_last) -> dict:
        out = {k: np.array(v) for k, v in self.rows.items()}
        out["x"] = np.vstack([out["x"].reshape(-1, 6), x_last])
        out["cp"] = np.vstack([out["cp"].reshape(-1, 2), cp_last])
        out["progress"] = np.array([*self.progress, s_last])
        out["qdd"] = out["qdd"].reshape(-1, 3)
        out["tau"] = out["tau"].reshape(-1, 2)
        out["saturated"] = out["saturated"].astype(bool)
        return out


def controller_period(controller: Controller) -> ca.Function:
    """``(r, x, noise, c) -> (tau, c_next, cp)``: the controller's law on the measured state
    x + noise, and the CP of the true state x through the model's kinematics [m]."""
    law, model = controller.law(), controller.reference.arm
    r = ca.MX.sym("r", law.size1_in(0))
    x, noise, c = ca.MX.sym("x", 6), ca.MX.sym("noise", 6), ca.MX.sym("c", 2)
    measured = x + noise
    tau, c_next = law(r, measured[:3], measured[3:], c)
    s = kinematic_functions(model)["pose"](x[:3])
    cp = s[:2] + model.K * ca.vertcat(ca.cos(s[2]), ca.sin(s[2]))
    outs = [ca.densify(v) for v in (tau, c_next, cp)]
    return ca.Function("controller_period", [r, x, noise, c], outs)


class _Buffered:
    """A CasADi function evaluated through its zero-copy buffer into arrays kept between calls
    (a call through DM cost four times MuJoCo's two steps of a period)."""

    def __init__(self, f: ca.Function) -> None:
        self.buffer, self.trigger = f.buffer()
        self.ins = [np.zeros(f.nnz_in(i)) for i in range(f.n_in())]
        self.outs = [np.zeros(f.nnz_out(i)) for i in range(f.n_out())]
        for i, a in enumerate(self.ins):
            self.buffer.set_arg(i, memoryview(a))
        for i, o in enumerate(self.outs):
            self.buffer.set_res(i, memoryview(o))

    def __call__(self, *args) -> list[np.ndarray]:
        for target, value in zip(self.ins, args, strict=True):
            target[:] = np.ravel(value, order="F")
        self.trigger()
        return [o.copy() for o in self.outs]


def _period(mujoco, model, data, tau: np.ndarray, substeps: int):
    """Hold tau (2,) over one control period; the accelerations at its start (3,), as the
    built-in plant logs them, and the state (6,) at its end."""
    data.ctrl[:2] = tau
    mujoco.mj_forward(model, data)
    qdd = data.qacc[:3].copy()
    for _ in range(substeps):
        mujoco.mj_step(model, data)
    return qdd, np.concatenate([data.qpos[:3], data.qvel[:3]])


def _diverged(x: np.ndarray, cp_error: float) -> bool:
    """The built-in plant's rule: a non-finite state, a joint too fast, the CP too far off."""
    finite = bool(np.all(np.isfinite(x)))
    return not (finite and np.all(np.abs(x[3:]) <= DIVERGED_VELOCITY) and cp_error <= DIVERGED_CP)


def simulate_mujoco(controller: Controller, plant: Plant, noise: Noise | None = None) -> Batch:
    """One run of a controller on the plant simulated by MuJoCo, from the plan's start state.

    Parameters
    ----------
    controller : Controller
        The controller (its reference fixes the grid and the model).
    plant : Plant
        The simulated arm: links, viscous and Coulomb friction, torque limits, actuator
        gains (no actuation delay).
    noise : Noise, optional
        Measurement noise, drawn as the built-in plant's run 0 draws it.

    Returns
    -------
    Batch
        One run (N = 1), with its log.

    Raises
    ------
    MujocoMissingError
        Without MuJoCo.
    """
    mujoco = require_mujoco()
    ref, noise = controller.reference, noise or Noise()
    if plant.delay_steps(ref.period) or any(noise.torque):
        raise ValueError("the MuJoCo plant has no actuation delay or torque noise")
    substeps = steps_per_period(ref.period)
    model = arm_model(plant.arm, ref.period / substeps, plant.viscous)
    data = mujoco.MjData(model)
    law, schedule, t = (
        _Buffered(controller_period(controller)),
        controller.schedule(),
        controller.times,
    )
    rng, std = np.random.default_rng([noise.seed, 0]), noise.std
    limit = np.array([NO_LIMIT if v is None else v for v in (plant.torque_limit or (None, None))])

    def progress(k, c):
        return float(np.ravel(controller.progress(np.array([k]), c[:, None]))[0])

    arm_state(model, data, ref.x[0][:3], ref.x[0][3:])
    x, c = ref.x[0].astype(float).copy(), controller.initial_state()
    log, figures = _Log(), {"max_err": 0.0, "max_lag": 0.0, "diverged_at": np.nan}
    arrival, s_k = np.nan, progress(0, c)
    with coulomb_friction(plant.coulomb):
        for k in range(controller.horizon):
            e = rng.standard_normal(6) * std if std.any() else np.zeros(6)
            tau_cmd, c_next, cp = law(schedule[:, k], x, e, c)
            clipped = np.clip(tau_cmd, -limit, limit)
            tau = np.multiply(plant.gain, clipped)
            qdd, x_next = _period(mujoco, model, data, tau, substeps)
            err = float(np.linalg.norm(cp - plan_cp_at(ref, np.array(s_k))))
            log.add(x, qdd, tau, bool(np.any(clipped != tau_cmd)), cp, ref.t[0] + s_k * ref.period)
            figures["max_err"] = max(figures["max_err"], err)
            figures["max_lag"] = max(figures["max_lag"], (k - s_k) * ref.period)
            c, x = c_next, x_next
            s_k = progress(k + 1, c)
            if _diverged(x, err):
                figures["diverged_at"] = t[k + 1]
                break
            if s_k >= ref.steps - 1e-9:
                arrival = t[k + 1]
                break
    cp_last = law(schedule[:, min(k + 1, schedule.shape[1] - 1)], x, np.zeros(6), c)[2]
    return _batch(ref, t, x, cp_last, s_k, log, figures, arrival)


def _batch(ref, t, x, cp, s_last, log: _Log, figures: dict, arrival: float) -> Batch:
    """The run as a :class:`Batch` of one; a run that did not diverge also counts its CP error
    at its final state."""
    ok = np.isnan(figures["diverged_at"])
    end_err = float(np.linalg.norm(cp - ref.cp[-1, :, 0]))
    max_err = max(figures["max_err"], end_err) if ok else figures["max_err"]
    joined = log.joined(x, cp, ref.t[0] + s_last * ref.period)
    return Batch(
        t=t,
        x_final=x[None, :].copy(),
        max_cp_error=np.array([max_err]),
        diverged_at=np.array([figures["diverged_at"]]),
        peak_torque=np.abs(joined["tau"]).max(axis=0, initial=0.0)[None, :],
        saturated_fraction=np.array(
            [joined["saturated"].mean() if joined["saturated"].size else 0.0]
        ),
        arrival=np.array([arrival]),
        max_lag=np.array([figures["max_lag"]]),
        log=joined,
    )
