"""Bounded ODE integration of a Python right-hand side (the collocation replay): steps, state
size and wall clock all capped. The verification's simulations of a CP plan step along its
curve with :mod:`cpopt.verify.extrapolation` instead, under the same bounds (defined here).

A plan that is near-singular, or a closed loop that diverges, makes an adaptive integrator
shrink its steps and crawl for minutes. :func:`integrate` steps scipy's DOP853 itself (the
same steps and dense output as ``solve_ivp``, so the same numbers) and stops with
:class:`DivergenceError`, saying when and why, as soon as the state leaves a bound, is not
finite, the integrator fails, or the steps exceed a budget that grows with the time span. It
checks the wall-clock budget of the problem being solved (:func:`cpopt.runtime.budget.check_time`).
"""

from __future__ import annotations

import numpy as np

from ..runtime.budget import check_time

STATE_BOUND = 1e8
"""Largest |state| entry [SI units] before a simulation counts as diverged."""
STEPS_PER_SECOND = 1000
"""Step budget per second of simulated time, on top of :data:`BASE_STEPS` (the bundled
problems take at most about 300 per second; a closed loop gets more for poles faster than
-10 1/s, see :mod:`cpopt.verify.simulate`)."""
BASE_STEPS = 1000
"""Step budget of any integration, however short."""


class DivergenceError(RuntimeError):
    """A simulation stopped early: it diverged, crawled or failed at time ``t`` [s].

    Attributes
    ----------
    t : float
        Simulated time where it stopped [s].
    reason : str
        What happened.
    """

    def __init__(self, t: float, reason: str) -> None:
        self.t, self.reason = float(t), reason
        super().__init__(f"simulation stopped at t = {self.t:.6g} s: {reason}")


def integrate(
    rhs,
    x0: np.ndarray,
    t0: float,
    t1: float,
    t_eval: np.ndarray,
    rtol: float,
    atol: float,
    steps_per_second: float = STEPS_PER_SECOND,
) -> tuple[np.ndarray, np.ndarray]:
    """Integrate ``x' = rhs(t, x)`` from t0 to t1 with DOP853, bounded.

    Parameters
    ----------
    rhs : callable
        ``rhs(t, x) -> x'``.
    x0 : numpy.ndarray
        Initial state.
    t0, t1 : float
        Time span [s], t1 > t0.
    t_eval : numpy.ndarray
        Increasing output times in [t0, t1] [s].
    rtol, atol : float
        Integrator tolerances.
    steps_per_second : float
        Step budget per second of simulated time, on top of :data:`BASE_STEPS` (more for fast
        dynamics, such as a closed loop with fast poles).

    Returns
    -------
    t : numpy.ndarray
        The output times.
    x : numpy.ndarray
        States at those times (len(t), n).

    Raises
    ------
    DivergenceError
        When the state leaves :data:`STATE_BOUND` or is not finite, the integrator fails, or
        the steps exceed the budget.
    cpopt.runtime.budget.TimeLimitExceeded
        When the problem's wall-clock budget runs out.
    """
    max_steps = int(BASE_STEPS + steps_per_second * (t1 - t0))
    from scipy.integrate import DOP853  # imported where used: start-up time

    solver = DOP853(rhs, t0, np.asarray(x0, float), t1, rtol=rtol, atol=atol)
    t_eval = np.asarray(t_eval, float)
    ts, xs, i, steps = [], [], 0, 0
    while solver.status == "running":
        message = solver.step()
        steps += 1
        if solver.status == "failed":
            raise DivergenceError(solver.t, f"the integrator failed ({message})")
        if not np.all(np.isfinite(solver.y)) or np.max(np.abs(solver.y)) > STATE_BOUND:
            raise DivergenceError(solver.t, f"the state left |x| <= {STATE_BOUND:g}")
        if steps > max_steps:
            raise DivergenceError(
                solver.t, f"more than {max_steps} integration steps (stiff or diverging)"
            )
        if steps % 16 == 0:
            check_time()
        # output points inside this step, from its dense output (as solve_ivp does)
        j = np.searchsorted(t_eval, solver.t, side="right")
        if j > i:
            ts.append(t_eval[i:j])
            xs.append(solver.dense_output()(t_eval[i:j]))
            i = j
    return np.concatenate(ts), np.hstack(xs).T


__all__ = ["DivergenceError", "integrate"]
