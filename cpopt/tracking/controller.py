"""The interface every tracking controller offers.

A controller is a sampled-data law: at instant t_k it reads the measured joint positions and
velocities, updates its own state c (two numbers; the compensator's (xi, eta) for ``dfl``,
unused for ``tvlqr``) and returns the torques (tau1, tau2) held until t_{k+1}. The law is one
CasADi function of ``(r_k, q, qd, c)`` where r_k is the controller's data for instant k (a
column of :meth:`Controller.schedule`), so the simulation evaluates it inside a single mapped
function with the plant; :meth:`Controller.torque` calls it one instant at a time (for a user's
own simulator or arm).

A controller may track the plan at its own pace (``tvlqr_timescaled`` slows the reference when
the motors saturate): :meth:`Controller.progress` says which instant of the plan it tracks, and
:attr:`Controller.horizon` how many periods a run may last (the plan's, or more for a controller
that can fall behind). A run is judged when its progress reaches the end of the plan.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import casadi as ca
import numpy as np

from .reference import Reference


class Controller(ABC):
    """A tracking controller for one plan (see the module docstring).

    Parameters
    ----------
    reference : Reference
        The plan on the control grid; its period is the controller's.
    """

    name: str = ""

    def __init__(self, reference: Reference) -> None:
        self.reference = reference
        self._state = self.initial_state()
        self._compiled: tuple | None = None  # law and schedule, built at the first torque()

    @property
    def period(self) -> float:
        """Control period [s]."""
        return self.reference.period

    @abstractmethod
    def law(self) -> ca.Function:
        """``(r, q, qd, c) -> (tau, c_next)``: the law at one instant (CasADi)."""

    @abstractmethod
    def schedule(self) -> np.ndarray:
        """The law's data r_k at every instant, one column per instant (rows, n + 1)."""

    @property
    def horizon(self) -> int:
        """Control periods a run may last: the plan's (:attr:`Reference.steps`) by default."""
        return self.reference.steps

    @property
    def times(self) -> np.ndarray:
        """The control instants of a whole run (horizon + 1,) [s]."""
        ref = self.reference
        later = ref.t[-1] + ref.period * np.arange(1, self.horizon - ref.steps + 1)
        return np.concatenate([ref.t, later])

    def progress(self, k: np.ndarray, c: np.ndarray) -> np.ndarray:
        """The plan's instant tracked at control instant k with controller state c, in periods
        (a fractional index of the reference grid): k itself for a controller at the plan's
        pace. k (...) and c (2, ...) broadcast."""
        return np.broadcast_to(np.asarray(k, float), np.shape(c)[1:]).copy()

    def initial_state(self) -> np.ndarray:
        """The controller's state c at the first instant (2,)."""
        return np.zeros(2)

    def reset(self) -> None:
        """Start again from the first instant (:meth:`torque` keeps a state between calls)."""
        self._state = self.initial_state()

    def torque(self, t: float, q, qd) -> np.ndarray:
        """Torques (tau1, tau2) [N m or N] for measured joint positions and velocities.

        Call it once per control period, in time order (a ``dfl`` controller integrates its
        compensator over one period per call); t [s] selects the instant (rounded).
        """
        ref = self.reference
        k = int(np.clip(round((t - ref.t[0]) / ref.period), 0, self.horizon))
        if self._compiled is None:
            self._compiled = (self.law(), self.schedule())
        law, schedule = self._compiled
        tau, c = law(schedule[:, k], np.asarray(q, float), np.asarray(qd, float), self._state)
        self._state = np.asarray(c).ravel()
        return np.asarray(tau).ravel()
