"""The solution a notebook user holds: :class:`cpopt.results.Solution` with ways to query it.

:func:`cpopt.solve` returns a :class:`Solution`: the record the pipeline produces (status, plan,
trajectory, metrics, verification, solver statistics, tracking) and the problem it solves, with
the plan at any times (:meth:`Solution.sample`), its files (:meth:`Solution.save`), its figures
(:meth:`Solution.plot`) and a short summary in a notebook (``__repr__``, ``_repr_html_``).
"""

from __future__ import annotations

import html
import json
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np

from . import results
from .closedform.trajectory import Trajectory, sample_at
from .io.safe_yaml import echo
from .mujoco_render import ImageFile, Time, check_render_arguments
from .problem import Problem

PLOT_KINDS = ("third_link", "arm", "torques", "gamma", "tracking")
"""The figures :meth:`Solution.plot` draws (those ``cpopt solve --plot`` writes as PNG)."""


def _shown(value) -> str:
    """A given value in a message: its type and a short repr."""
    return f"{type(value).__name__} {echo(value)}"


def _check_axes(ax, counts: tuple[int, ...]) -> None:
    """Refuse an ``ax`` that is neither None nor ``counts`` matplotlib Axes (a list of them,
    or one alone where one is allowed); an empty ``counts`` allows any number."""
    from matplotlib.axes import Axes

    if ax is None:
        return
    items = list(np.ravel(np.asarray(ax, dtype=object)))
    if items and all(isinstance(a, Axes) for a in items):
        if not counts or len(items) in counts:
            return
        allowed = " or ".join(str(c) for c in dict.fromkeys(counts))
        raise ValueError(f"ax must be {allowed} matplotlib Axes here, got {len(items)}")
    raise ValueError(f"ax must be a matplotlib Axes or a list of them, got {_shown(ax)}")


@dataclass(frozen=True, repr=False)
class Solution(results.Solution):
    """The outcome of :func:`cpopt.solve`: what ``solution.json`` holds, and the plan itself.

    Attributes
    ----------
    name, status, planner, plan, trajectory, metrics, verification, solver, message, tracking
        As in :class:`cpopt.results.Solution`: ``status`` is one of
        :data:`cpopt.results.STATUSES` (only ``solved`` is a success); ``metrics``
        (:class:`cpopt.closedform.trajectory.Metrics`) holds the figures of merit in SI units.
    problem : Problem or None
        The problem solved (its limits are drawn on the figures; :func:`cpopt.track` tracks
        with its settings).
    """

    problem: Problem | None = field(default=None, compare=False)

    @classmethod
    def of(cls, record: results.Solution, problem: Problem | None = None) -> Solution:
        """The solution of a pipeline's record and the problem it solves.

        Raises
        ------
        ValueError
            For a ``record`` that is not a :class:`cpopt.results.Solution` or a ``problem``
            that is not a :class:`~cpopt.problem.Problem`.
        """
        if not isinstance(record, results.Solution):
            raise ValueError(f"record must be a cpopt.results.Solution, got {_shown(record)}")
        if problem is not None and not isinstance(problem, Problem):
            raise ValueError(f"problem must be a Problem or None, got {_shown(problem)}")
        values = {f.name: getattr(record, f.name) for f in fields(results.Solution)}
        return cls(**values, problem=problem)

    @property
    def free_values(self) -> dict[str, float]:
        """The values the planner chose, by name (``duration``, ``via[0].x``, ...) in SI units
        and radians; empty without a plan or for the closed form."""
        return {} if self.plan is None else dict(self.plan.free_values)

    def sample(self, t) -> Trajectory:
        """The plan at any times: state, joint motion, torques, CP and gamma.

        Parameters
        ----------
        t : float or array_like
            Times [s] within the plan, in any order. At a join of two phases a flat plan gives
            the later phase's values (the right limit); a collocation plan's torque is
            right-continuous too.

        Returns
        -------
        Trajectory
            One sample per time (arrays of length N = number of times): ``z`` (N, 8) the
            third link's state and compensator (x, y [m], theta [rad], xdot, ydot [m/s],
            thetadot [rad/s], xi [m/s^2], eta [m/s^3]), ``q``, ``qd``, ``qdd`` (N, 3) the
            joints [rad or m, per s, per s^2], ``tau`` (N, 2) the torques [N m or N], ``cp``
            (N, 2, 5) the CP and its derivatives [m/s^k], ``gamma`` (N,) [m/s^2]. For a
            collocation plan the CP's third and fourth derivatives, eta and alpha are NaN
            (undefined under piecewise-constant torques) and q, qd are interpolated between
            the collocation polynomials' samples (:func:`cpopt.collocation.joint_sample_at`).

        Raises
        ------
        ValueError
            Without a plan (the status says why), or for a time outside the plan.
        """
        if self.plan is None:
            raise ValueError(f"{self.name}: no plan to sample (status {self.status})")
        if self.plan.planner == "collocation":
            from .collocation import joint_sample_at

            return joint_sample_at(self.plan, t)
        return sample_at(self.plan, t, self.trajectory)

    def to_dict(self) -> dict:
        """The ``solution.json`` document (JSON-ready: non-finite numbers are None)."""
        return json.loads(json.dumps(results.json_safe(self.as_dict())))

    def save(self, directory: str | Path) -> list[Path]:
        """Write the files ``cpopt solve`` writes into a folder (created if need be):
        ``solution.json``, and for a solved plan ``trajectory.csv`` (and ``tracking.csv``
        when tracked), each whole; figures are :meth:`plot`'s.

        Returns
        -------
        list of Path
            The files written.

        Raises
        ------
        ValueError
            For a ``directory`` that is not a folder name, or a place a folder cannot be
            (an existing file, a path under a file), before anything is written.
        """
        from .io.output import OutputError, check_directory

        if not isinstance(directory, str | Path) or not str(directory).strip():
            raise ValueError(f"directory must be a folder name, got {_shown(directory)}")
        try:
            check_directory(directory)
        except OutputError as err:
            raise ValueError(f"directory {err}") from None
        return results.write_solution(self, directory)

    def plot(self, kind: str = "third_link", ax=None):
        """A figure of the plan, as ``cpopt solve --plot`` draws it.

        Parameters
        ----------
        kind : str
            One of :data:`PLOT_KINDS`: ``third_link`` (strobe of the third link and the CP
            path), ``arm`` (strobe of the arm), ``torques`` (with the problem's torque limits),
            ``gamma`` (with ``optimizer.gamma_min`` for the optimizing planners), ``tracking``
            (a tracked plan against its plan).
        ax : matplotlib.axes.Axes, optional
            Where to draw (for ``third_link`` and ``arm`` one per phase, or a single one);
            a new figure otherwise. ``tracking`` always draws a new figure of three panels.

        Returns
        -------
        matplotlib.figure.Figure

        Raises
        ------
        ValueError
            For an unknown kind, an ``ax`` that is not a matplotlib Axes (or a list of one per
            phase), a solution without a sampled plan, or ``tracking`` for a plan that was not
            tracked.
        """
        from . import plotting

        if not isinstance(kind, str) or kind not in PLOT_KINDS:
            raise ValueError(f"kind must be one of {', '.join(PLOT_KINDS)}; got {echo(kind)}")
        if self.trajectory is None:
            raise ValueError(f"{self.name}: no sampled plan to plot (status {self.status})")
        phases = int(self.trajectory.phase.max()) + 1
        # one panel per phase (or one for all) for the strobes, one panel for the curves
        counts = {"third_link": (1, phases), "arm": (1, phases), "tracking": ()}
        _check_axes(ax, counts.get(kind, (1,)))
        limits, gamma_min = self._drawn_limits()
        if kind == "torques":
            return plotting.plot_torques(self, ax, limits=limits)
        if kind == "gamma":
            return plotting.plot_gamma(self, ax, gamma_min=gamma_min)
        if kind == "tracking":
            from .tracking import TrackingOutcome

            if not isinstance(self.tracking, TrackingOutcome):
                raise ValueError(f"{self.name}: the plan was not tracked (see cpopt.track)")
            return plotting.plot_tracking(self)
        return {"third_link": plotting.plot_third_link, "arm": plotting.plot_arm}[kind](self, ax)

    def render(
        self, path: ImageFile, fps: float = 25.0, tracked: bool = True, at: Time = 0.0
    ) -> str:
        """Write a GIF of the arm (a ``.png`` path: its frame at time ``at``) from MuJoCo's
        offscreen renderer, as ``cpopt solve --animate --engine mujoco`` does: the planned arm,
        and the tracked arm solid beside it (the plan translucent) when the plan was tracked.

        Parameters
        ----------
        path : str or Path
            Output ``.gif`` or ``.png``, in an existing folder.
        fps : float
            Frames per second of real time.
        tracked : bool
            Draw the tracked arm too, when there is one.
        at : float
            The time of a ``.png`` picture [s], within the plan.

        Returns
        -------
        str
            The OpenGL backend that rendered (``egl`` or ``osmesa``).

        Raises
        ------
        ValueError
            Without a plan, or for a bad argument (named).
        cpopt.mujoco_render.RenderUnavailableError
            Where no OpenGL context can be made (EGL, then OSMesa, were tried).
        cpopt.model.mujoco_arm.MujocoMissingError
            Without MuJoCo (``pip install 'cpopt[mujoco]'``).
        """
        from .mujoco_render import render

        if self.plan is None:
            raise ValueError(f"{self.name}: no plan to render (status {self.status})")
        duration = self.plan.duration
        path = check_render_arguments(path, fps, tracked, at, duration)
        t = np.linspace(0.0, duration, max(2, round(duration * fps) + 1))
        if path.suffix.lower() == ".png":
            t = np.array([float(at)])
        q_plan = self.sample(t).q
        q_tracked = None
        outcome = self.tracking
        if tracked and outcome is not None and hasattr(outcome, "x"):
            q_tracked = np.column_stack(
                [np.interp(t, outcome.t[: len(outcome.x)], outcome.x[:, i]) for i in range(3)]
            )
        return render(self.plan.arm, q_plan, path, q_tracked, fps)

    def _drawn_limits(self):
        """The torque limits and gamma margin the CLI draws (none without a problem)."""
        if self.problem is None:
            return None, None
        o = self.problem.spec.optimizer
        return o.limits.torque, None if self.problem.planner == "closed_form" else o.gamma_min

    def summary(self) -> dict[str, str]:
        """The figures shown in a notebook, formatted: status, planner, duration, cost
        (``torque_sq_integral``), peak torques, min |gamma| (and the message of a failure)."""
        out = {"status": self.status, "planner": self.planner}
        if self.plan is not None:
            out["duration"] = f"{self.plan.duration:.4g} s"
        m = self.metrics
        if m is not None:
            out["torque_sq_integral"] = f"{m.torque_sq_integral:.6g} N^2 m^2 s"
            units = ["N m" if r else "N" for r in self.plan.arm.revolute[:2]]
            peaks = ", ".join(f"{v:.4g} {u}" for v, u in zip(m.peak_torque, units, strict=True))
            out["peak_torque"] = f"({peaks})"
            out["min|gamma|"] = f"{m.min_abs_gamma:.4g} m/s^2"
        if not self.ok and self.message:
            out["message"] = self.message
        return out

    def __repr__(self) -> str:
        parts = self.summary()
        message = parts.pop("message", "")
        text = ", ".join(f"{k}={v}" for k, v in parts.items() if k != "status")
        line = f"<Solution {self.name}: {self.status}, {text}"
        if message:
            first = message.splitlines()[0]
            line += f": {first[:117] + '...' if len(first) > 120 else first}"
        return line + ">"

    def _repr_html_(self) -> str:
        rows = "".join(
            f"<tr><th style='text-align:left'>{html.escape(k)}</th>"
            f"<td style='text-align:left'>{html.escape(v)}</td></tr>"
            for k, v in self.summary().items()
        )
        return f"<table><caption>Solution {html.escape(self.name)}</caption>{rows}</table>"
