"""What a tracking run achieved: errors, torques, saturation and the success criterion.

Positions are measured the way the controller sees them: the CP and the third link's state
come from the plant's true joint positions through the *model's* kinematics. A plant whose
link lengths differ from the model's therefore feels them in its dynamics (inertia, gravity,
coupling), but the Cartesian offset of a mis-measured length, a calibration error that no
feedback on joint encoders can remove, is not counted as a tracking error. Likewise the CP is
the point at the model's distance K along the third link.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..closedform.plan import Node
from ..model.kinematics import joint_state, kinematic_functions
from ..model.mapping import mapped
from ..model.robot import Arm

CSV_COLUMNS = (
    "t", "q1", "q2", "q3", "q1dot", "q2dot", "q3dot", "q1ddot", "q2ddot", "q3ddot", "tau1",
    "tau2", "cp_x", "cp_y", "cp_x_ref", "cp_y_ref",
)  # fmt: skip
"""Columns of ``tracking.csv``: one row per control period (the state at its start, the
accelerations there, the torques held over it after saturation)."""


@dataclass(frozen=True)
class Tolerance:
    """When a tracking run counts as a success: judged when the controller's progress reaches
    the end of the plan (at T, or later for a controller that slowed its reference, within its
    bounded extra time), and no divergence.

    Attributes
    ----------
    cp : float
        CP distance from the goal's CP [m].
    theta_deg : float
        Third link's angle from the goal's [deg] (modulo 360).
    joint_velocity : float
        Largest |qdot_i - qdot_goal,i| [rad/s or m/s]: a link still moving at 0.25 rad/s
        passes 5 deg in 0.35 s, so the arm is not yet at the goal.
    """

    cp: float = 0.02
    theta_deg: float = 5.0
    joint_velocity: float = 0.25

    def as_dict(self) -> dict:
        """JSON-ready dict (``cp`` [m], ``theta_deg``, ``joint_velocity`` [rad/s or m/s])."""
        return {"cp": self.cp, "theta_deg": self.theta_deg, "joint_velocity": self.joint_velocity}


def cp_points(model: Arm, q: np.ndarray) -> np.ndarray:
    """CP (N, 2) [m] of joint positions q (N, 3) through the model's kinematics."""
    n = q.shape[0]
    s = np.asarray(mapped(kinematic_functions(model)["pose"], n)(q.T)).T
    return s[:, :2] + model.K * np.column_stack([np.cos(s[:, 2]), np.sin(s[:, 2])])


@dataclass(frozen=True)
class FinalErrors:
    """Errors at the end of runs against the goal, one entry per run (SI units, degrees).

    Attributes
    ----------
    cp : CP distance [m]
    theta_deg : |theta error| modulo 360 [deg]
    joint_velocity : max_i |qdot_i - qdot_goal,i| [rad/s or m/s]
    state : largest |error| of (x, y, theta, xdot, ydot, thetadot) [m, rad, m/s, rad/s]
    """

    cp: np.ndarray
    theta_deg: np.ndarray
    joint_velocity: np.ndarray
    state: np.ndarray

    def success(self, tolerance: Tolerance, diverged: np.ndarray) -> np.ndarray:
        """True where a run ends within the tolerance and did not diverge."""
        with np.errstate(invalid="ignore"):
            return (
                ~diverged
                & (self.cp <= tolerance.cp)
                & (self.theta_deg <= tolerance.theta_deg)
                & (self.joint_velocity <= tolerance.joint_velocity)
            )


def final_errors(model: Arm, goal: Node, X: np.ndarray) -> FinalErrors:
    """:class:`FinalErrors` of end joint states X (N, 6) against a goal node."""
    n = X.shape[0]
    kin = kinematic_functions(model)
    s = np.asarray(mapped(kin["pose"], n)(X[:, :3].T)).T
    J = np.asarray(mapped(kin["jacobian"], n)(X[:, :3].T)).T.reshape(n, 3, 3).transpose(0, 2, 1)
    state = np.column_stack([s, np.einsum("nij,nj->ni", J, X[:, 3:6])])
    err = state - goal.state()[:6]
    err[:, 2] = (err[:, 2] + np.pi) % (2 * np.pi) - np.pi
    _, qd_goal = joint_state(model, goal.state())
    goal_cp = cp_points(model, joint_state(model, goal.state())[0][None, :])[0]
    return FinalErrors(
        cp=np.linalg.norm(cp_points(model, X[:, :3]) - goal_cp, axis=1),
        theta_deg=np.degrees(np.abs(err[:, 2])),
        joint_velocity=np.abs(X[:, 3:6] - qd_goal).max(axis=1),
        state=np.abs(err).max(axis=1),
    )


@dataclass(frozen=True)
class TrackingOutcome:
    """One tracking run on a plant (SI units, radians).

    Attributes
    ----------
    controller : str
        ``tvlqr``, ``tvlqr_timescaled``, ``dfl`` or ``flat_mpc``.
    rate_hz : float
        Control rate [Hz].
    t : numpy.ndarray
        Control instants reached (m + 1,) [s]: up to T (m = n), earlier when the run diverged,
        later when the controller slowed its reference.
    x : numpy.ndarray
        True plant joint states at the instants (m + 1, 6).
    qdd : numpy.ndarray
        Plant accelerations at the start of each period (m, 3).
    tau : numpy.ndarray
        Torques applied over each period, after saturation (m, 2) [N m or N].
    saturated : numpy.ndarray
        Whether a torque was clipped in each period (m,).
    cp, cp_ref : numpy.ndarray
        CP of the plant (model kinematics) and of the plan at the instants the controller
        tracked (m + 1, 2) [m].
    diverged_at : float or None
        When the run was stopped as diverged [s].
    final : FinalErrors
        Errors at the last instant against the goal.
    tolerance : Tolerance
        The success criterion.
    progress : numpy.ndarray or None
        The plan's instant the controller tracked at each instant (m + 1,) [s]: ``t`` itself
        for a controller at the plan's pace (None: the same).
    arrived : bool
        Whether the controller's progress reached the end of the plan (a run that diverged or
        ran out of extra time did not).
    replans : dict or None
        ``flat_mpc``'s re-plans: ``count``, ``median_ms``, ``p99_ms`` (wall time), ``misses``
        (the fraction over their deadline or not solved), ``applied`` (how many took effect).
    """

    controller: str
    rate_hz: float
    t: np.ndarray
    x: np.ndarray
    qdd: np.ndarray
    tau: np.ndarray
    saturated: np.ndarray
    cp: np.ndarray
    cp_ref: np.ndarray
    diverged_at: float | None
    final: FinalErrors
    tolerance: Tolerance = field(default_factory=Tolerance)
    progress: np.ndarray | None = None
    arrived: bool = True
    replans: dict | None = None

    @property
    def delay(self) -> float:
        """How much later than the plan the run was judged [s]: t at the last instant less the
        plan's instant tracked then (0 for a controller at the plan's pace)."""
        return 0.0 if self.progress is None else float(self.t[-1] - self.progress[-1])

    @property
    def max_lag(self) -> float:
        """Largest lag of the plan's instant tracked behind the clock, max(t - s(t)) [s]."""
        return 0.0 if self.progress is None else float(np.max(self.t - self.progress))

    @property
    def cp_error(self) -> np.ndarray:
        """|CP - CP_ref| at the instants [m]."""
        return np.linalg.norm(self.cp - self.cp_ref, axis=1)

    @property
    def max_cp_error(self) -> float:
        """Largest CP tracking error [m]."""
        return float(self.cp_error.max())

    @property
    def success(self) -> bool:
        """True when the run arrives within the tolerance without diverging."""
        diverged = np.array([self.diverged_at is not None or not self.arrived])
        return bool(self.final.success(self.tolerance, diverged)[0])

    def summary(self) -> dict:
        """The ``tracking`` entry of ``solution.json``."""
        return {
            "controller": self.controller,
            "rate_hz": self.rate_hz,
            "max_cp_error": self.max_cp_error,
            "final_state_error": float(self.final.state[0]),
            "final_cp_error": float(self.final.cp[0]),
            "final_theta_error_deg": float(self.final.theta_deg[0]),
            "final_joint_velocity_error": float(self.final.joint_velocity[0]),
            "peak_torque": np.abs(self.tau).max(axis=0).tolist(),
            "saturated_fraction": float(self.saturated.mean()) if self.saturated.size else 0.0,
            "diverged_at": self.diverged_at,
            "delay": self.delay,
            "max_lag": self.max_lag,
            "success": self.success,
            "tolerance": self.tolerance.as_dict(),
            **({} if self.replans is None else {"replans": self.replans}),
        }

    def table(self) -> np.ndarray:
        """Rows of ``tracking.csv`` (m, 16) in :data:`CSV_COLUMNS` order."""
        m = self.tau.shape[0]
        return np.column_stack(
            [self.t[:m], self.x[:m], self.qdd, self.tau, self.cp[:m], self.cp_ref[:m]]
        )
