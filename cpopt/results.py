"""Solutions and their files: ``solution.json`` and ``trajectory.csv``, written whole or not at all.

The file contract (documented in docs/cli.md, "Output contract"):

* ``solution.json``: ``name``, ``status``, ``planner``, ``duration_s``, ``metrics``
  {``torque_sq_integral``, ``abs_power_integral``, ``peak_torque``, ``min_abs_gamma``,
  ``theta_min_deg``, ``theta_max_deg``, ``max_torque_jump``}, ``verification``
  {``max_cp_error``, ``final_state_error``, ``passive_torque_residual``, ...}, ``solver``
  {``iterations``, ``build_time_s``, ``solve_time_s``, ``message``}, ``free_values``,
  ``cpopt_version``; with a ``tracking`` block also ``tracking`` (see
  :meth:`cpopt.tracking.TrackingOutcome.summary`).
* ``trajectory.csv``: :data:`CSV_COLUMNS`, one row per sample, SI units and radians.
* ``tracking.csv`` (tracked problems): :data:`TRACKING_CSV_COLUMNS`, one row per control period.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import __version__
from .closedform.plan import CPPlan
from .closedform.trajectory import Metrics, Trajectory
from .io.output import atomic_write
from .runtime.solver import SolverStats
from .tracking import CSV_COLUMNS as TRACKING_CSV_COLUMNS
from .tracking import TrackingOutcome, TrackingRefused
from .verify.simulate import Verification

CSV_COLUMNS = (
    "t", "x", "y", "theta", "xdot", "ydot", "thetadot", "q1", "q2", "q3", "q1dot", "q2dot",
    "q3dot", "tau1", "tau2", "gamma", "cp_x", "cp_y", "xi", "eta",
)  # fmt: skip

STATUSES = (
    "solved", "infeasible", "max_iterations", "not_converged", "singular", "unreachable",
    "verification_failed", "limits_violated", "time_limit",
)  # fmt: skip
"""Values of ``status``: only ``solved`` is a success."""


@dataclass(frozen=True)
class Solution:
    """The outcome of solving a problem.

    Attributes
    ----------
    name : str
        Problem name.
    status : str
        One of :data:`STATUSES`.
    planner : str
        ``closed_form`` or ``optimize``.
    plan : CPPlan or None
        The plan (the best iterate when the solve failed), if any.
    trajectory : Trajectory or None
        The sampled plan.
    metrics : Metrics or None
        Figures of merit.
    verification : Verification or None
        Simulation errors.
    solver : SolverStats
        Solver statistics.
    message : str
        What went wrong, for a status other than ``solved``.
    tracking : TrackingOutcome or TrackingRefused or None
        The plan tracked on a realistic plant (problems with a ``tracking`` block).
    """

    name: str
    status: str
    planner: str
    plan: CPPlan | None = None
    trajectory: Trajectory | None = None
    metrics: Metrics | None = None
    verification: Verification | None = None
    solver: SolverStats = field(default_factory=SolverStats)
    message: str = ""
    tracking: TrackingOutcome | TrackingRefused | None = None

    @property
    def ok(self) -> bool:
        """True when the status is ``solved``."""
        return self.status == "solved"

    def as_dict(self) -> dict:
        """The ``solution.json`` document."""
        solver = self.solver.as_dict()
        if self.message and self.message not in solver["message"]:
            # what went wrong after the planner (verification, the time limit) is said too
            solver["message"] = "; ".join(m for m in (solver["message"], self.message) if m)
        document = {
            "name": self.name,
            "status": self.status,
            "planner": self.planner,
            "duration_s": None if self.plan is None else self.plan.duration,
            "metrics": None if self.metrics is None else self.metrics.as_dict(),
            "verification": None if self.verification is None else self.verification.summary(),
            "solver": solver,
            "free_values": {} if self.plan is None else dict(self.plan.free_values),
            "cpopt_version": __version__,
        }
        if self.tracking is not None:
            document["tracking"] = self.tracking.summary()
        return document


def json_safe(value):
    """Make a value JSON-safe: numpy scalars to floats, non-finite floats to None."""
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def trajectory_table(traj: Trajectory) -> np.ndarray:
    """The rows of ``trajectory.csv`` (N, 20) in :data:`CSV_COLUMNS` order."""
    return np.column_stack(
        [
            traj.t,
            traj.z[:, :6],
            traj.q,
            traj.qd,
            traj.tau,
            traj.gamma,
            traj.cp[:, :, 0],
            traj.z[:, 6:8],
        ]
    )


def _write_tracking(solution: Solution, directory: Path) -> list[Path]:
    """``tracking.csv`` of a solved, tracked plan (:data:`TRACKING_CSV_COLUMNS`), else none
    (an earlier run's file is removed)."""
    path = directory / "tracking.csv"
    if not (solution.ok and isinstance(solution.tracking, TrackingOutcome)):
        path.unlink(missing_ok=True)
        return []
    table = solution.tracking.table()

    def write_csv(handle):
        handle.write(",".join(TRACKING_CSV_COLUMNS) + "\n")
        np.savetxt(handle, table, delimiter=",", fmt="%.12g")

    atomic_write(path, write_csv)
    return [path]


def write_solution(solution: Solution, directory: str | Path) -> list[Path]:
    """Write ``solution.json`` and, for a solved plan, ``trajectory.csv`` into a folder.

    A failed solve writes ``solution.json`` with its status and removes any
    ``trajectory.csv`` left there by an earlier run, so nothing that looks like success stays.

    Returns
    -------
    list of Path
        The files written.
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    written = _write_tracking(solution, directory)
    csv_path = directory / "trajectory.csv"
    if solution.ok and solution.trajectory is not None:
        table = trajectory_table(solution.trajectory)

        def write_csv(handle):
            handle.write(",".join(CSV_COLUMNS) + "\n")
            np.savetxt(handle, table, delimiter=",", fmt="%.12g")

        atomic_write(csv_path, write_csv)
        written.append(csv_path)
    else:
        csv_path.unlink(missing_ok=True)
    # the JSON last: when it is there, the files it speaks for are too
    json_path = directory / "solution.json"
    document = json_safe(solution.as_dict())
    atomic_write(json_path, lambda h: h.write(json.dumps(document, indent=2) + "\n"))
    written.insert(0, json_path)
    return written
