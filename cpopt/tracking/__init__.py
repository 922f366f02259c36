"""Tracking a plan on a realistic arm: controllers, plant, sampled-data simulation, outcome.

* :mod:`~cpopt.tracking.reference`: the plan on the control grid (flat or collocation plans);
* :mod:`~cpopt.tracking.dfl`, :mod:`~cpopt.tracking.tvlqr`,
  :mod:`~cpopt.tracking.timescaled`: the controllers, one interface
  (:class:`~cpopt.tracking.controller.Controller`, ``torque(t, q, qd) -> tau``);
* :mod:`~cpopt.tracking.plant`: the simulated arm (its own parameters, friction, saturation);
* :mod:`~cpopt.tracking.simulation`: the sampled-data loop, many runs in one mapped call;
* :mod:`~cpopt.tracking.mujoco_plant`: the same loop on MuJoCo (``tracking.plant.engine``);
* :mod:`~cpopt.tracking.outcome`: errors, success criterion, ``tracking.csv`` rows;
* :mod:`~cpopt.tracking.run`: :func:`track`, one run from a plan.
"""

from .outcome import CSV_COLUMNS, Tolerance, TrackingOutcome
from .plant import Plant
from .run import CONTROLLERS, TrackingRefused, make_controller, track, track_problem
from .simulation import Noise

__all__ = [
    "CONTROLLERS",
    "CSV_COLUMNS",
    "Noise",
    "Plant",
    "Tolerance",
    "TrackingOutcome",
    "TrackingRefused",
    "make_controller",
    "track",
    "track_problem",
]
