"""Figures like the paper's (third-link strobe with the CP path, arm strobe, torques), gamma,
and an animation of the arm, as PNG and GIF files. Uses the active matplotlib backend (Agg when
there is no display; the CLI forces Agg).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from .closedform.trajectory import Trajectory
from .io.output import atomic_path
from .model.kinematics import kinematic_functions
from .results import Solution
from .tracking import TrackingOutcome


def _strobe_indices(traj: Trajectory, phase: int, count: int) -> np.ndarray:
    idx = np.flatnonzero(traj.phase == phase)
    return idx[np.linspace(0, idx.size - 1, count).round().astype(int)]


def _link3_tips(traj: Trajectory, length: float) -> np.ndarray:
    th = traj.z[:, 2]
    return traj.z[:, :2] + length * np.column_stack([np.cos(th), np.sin(th)])


def plot_third_link(solution: Solution, ax=None, strobes: int = 25):
    """Stroboscopic motion of the third link with the CP path, one panel per phase.

    Returns the figure.
    """
    traj = solution.trajectory
    arm = solution.plan.arm
    phases = int(traj.phase.max()) + 1
    fig, axes = _axes(ax, phases)
    tips = _link3_tips(traj, arm.links[2].length)
    for k, a in enumerate(axes):
        for i in _strobe_indices(traj, k, strobes):
            a.plot([traj.z[i, 0], tips[i, 0]], [traj.z[i, 1], tips[i, 1]], "-", color="0.35", lw=1)
            a.plot(*traj.z[i, :2], "o", color="0.35", ms=2)
        sel = traj.phase == k
        a.plot(traj.cp[sel, 0, 0], traj.cp[sel, 1, 0], "r-", lw=1.5, label="CP path")
        a.set_aspect("equal")
        a.set_xlabel("x [m]")
        a.set_ylabel("y [m]")
        a.set_title(f"{solution.name}: third link" + (f", phase {k + 1}" if phases > 1 else ""))
        a.legend(loc="best", fontsize="small")
    return fig


def plot_arm(solution: Solution, ax=None, strobes: int = 15):
    """Stroboscopic motion of the whole arm, one panel per phase. Returns the figure."""
    traj = solution.trajectory
    points = kinematic_functions(solution.plan.arm)["points"]
    phases = int(traj.phase.max()) + 1
    fig, axes = _axes(ax, phases)
    for k, a in enumerate(axes):
        idx = _strobe_indices(traj, k, strobes)
        for j, i in enumerate(idx):
            pts = np.asarray(points(traj.q[i]))
            shade = 0.75 - 0.6 * j / max(len(idx) - 1, 1)
            a.plot(pts[0], pts[1], "-o", color=str(shade), lw=1.2, ms=2.5)
        a.set_aspect("equal")
        a.set_xlabel("x [m]")
        a.set_ylabel("y [m]")
        a.set_title(
            f"{solution.name}: {solution.plan.arm.kind} arm"
            + (f", phase {k + 1}" if phases > 1 else "")
        )
    return fig


def _torque_units(kind: str) -> tuple[list[str], str]:
    """Units of tau1, tau2 (N m for a revolute joint, N for a prismatic one) and the axis label."""
    units = ["N" if c == "P" else "N m" for c in kind[:2]]
    names = {"N m": "torque [N m]", "N": "force [N]"}
    label = names[units[0]] if units[0] == units[1] else "torque [N m] / force [N]"
    return units, label


def plot_torques(solution: Solution, ax=None, limits=None):
    """Torques tau1 (solid) and tau2 (dashed) over time, with their limits. Returns the figure.

    Parameters
    ----------
    solution : Solution
        A solution with a trajectory.
    ax : matplotlib.axes.Axes, optional
        Where to draw (a new figure otherwise).
    limits : sequence of float or None, optional
        |tau1|, |tau2| limits [N m or N] (``optimizer.limits.torque``), drawn as red lines;
        where the plan kept a headroom h (``metrics.torque_headroom``), its bound (1 - h) times
        the limit is drawn thin and dotted.
    """
    traj = solution.trajectory
    fig, (a,) = _axes(ax, 1, size=(6, 3.2))
    units, label = _torque_units(solution.plan.arm.kind)
    styles = ("-", "--")
    for i in range(2):
        a.plot(traj.t, traj.tau[:, i], "k" + styles[i], label=f"tau{i + 1} [{units[i]}]")
    for i, tmax in enumerate(limits or ()):
        if tmax is not None:
            a.axhline(tmax, color="r", ls=styles[i], lw=0.9, label=f"|tau{i + 1}| limit")
            a.axhline(-tmax, color="r", ls=styles[i], lw=0.9)
            h = solution.metrics.torque_headroom[i] if solution.metrics is not None else 0.0
            if h:
                bound = (1 - h) * tmax
                a.axhline(bound, color="r", ls=":", lw=0.7, label=f"tau{i + 1} plan bound")
                a.axhline(-bound, color="r", ls=":", lw=0.7)
    a.set_xlabel("t [s]")
    a.set_ylabel(label)
    a.set_title(f"{solution.name}: torques")
    a.grid(alpha=0.3)
    a.legend(fontsize="small")
    return fig


def plot_gamma(solution: Solution, ax=None, gamma_min: float | None = None):
    """gamma [m/s^2] over time with the certified minimum of |gamma| and +-gamma_min.

    Returns the figure.
    """
    traj = solution.trajectory
    fig, (a,) = _axes(ax, 1, size=(6, 3.2))
    a.plot(traj.t, traj.gamma, "b-", label="gamma")
    a.axhline(0, color="k", lw=0.8)
    m = solution.metrics
    if m is not None:
        a.plot(
            m.min_abs_gamma_time,
            np.sign(np.interp(m.min_abs_gamma_time, traj.t, traj.gamma)) * m.min_abs_gamma,
            "rv",
            label=f"min |gamma| = {m.min_abs_gamma:.3g}",
        )
    if gamma_min:
        a.axhline(gamma_min, color="r", ls=":", lw=0.9, label=f"+-gamma_min = {gamma_min:g}")
        a.axhline(-gamma_min, color="r", ls=":", lw=0.9)
    a.set_xlabel("t [s]")
    a.set_ylabel("gamma [m/s^2]")
    a.set_title(f"{solution.name}: regularity margin")
    a.grid(alpha=0.3)
    a.legend(fontsize="small")
    return fig


def plot_tracking(solution: Solution):
    """The plan against the tracked motion: CP coordinates, CP error, torques over time.

    Returns the figure.
    """
    out = solution.tracking
    traj = solution.trajectory
    fig, (path, err, tau) = plt.subplots(3, 1, figsize=(6, 9), sharex=True)
    for i, name in enumerate(("x", "y")):
        path.plot(out.t, out.cp_ref[:, i], "k--", lw=1.2, label=f"CP {name} plan")
        path.plot(out.t, out.cp[:, i], "r-" if i == 0 else "b-", lw=0.9, label=f"CP {name} tracked")
    path.set_ylabel("CP [m]")
    path.set_title(f"{solution.name}: {out.controller} at {out.rate_hz:g} Hz on the plant")
    path.grid(alpha=0.3)
    path.legend(fontsize="small", ncol=2)
    err.semilogy(out.t, np.maximum(out.cp_error, 1e-12), "r-")
    err.axhline(out.tolerance.cp, color="k", ls=":", lw=0.8, label="success tolerance at T")
    err.set_ylabel("CP error [m]")
    err.grid(True, which="both", alpha=0.3)
    err.legend(fontsize="small")
    for i, style in enumerate(("-", "--")):
        tau.plot(traj.t, traj.tau[:, i], "k" + style, lw=1, label=f"tau{i + 1} plan")
        tau.step(out.t[:-1], out.tau[:, i], "r" + style, where="post", lw=0.8,
                 label=f"tau{i + 1} applied")  # fmt: skip
    tau.set_xlabel("t [s]")
    tau.set_ylabel("torque [N m or N]")
    tau.grid(alpha=0.3)
    tau.legend(fontsize="small", ncol=2)
    return fig


def _axes(ax, count: int, size=(6, 4)):
    if ax is not None:
        axes = np.atleast_1d(ax)
        return axes[0].figure, list(axes)
    fig, axes = plt.subplots(count, 1, figsize=(size[0], size[1] * count), squeeze=False)
    return fig, list(axes[:, 0])


def write_figures(
    solution: Solution,
    directory: str | Path,
    torque_limits=None,
    gamma_min: float | None = None,
) -> list[Path]:
    """Write ``third_link.png``, ``arm.png``, ``torques.png``, ``gamma.png`` and, for a
    tracked plan, ``tracking.png``, each whole.

    Parameters
    ----------
    solution : Solution
        A solution with a trajectory.
    directory : str or Path
        The problem's folder.
    torque_limits : sequence of float or None, optional
        Limits drawn on ``torques.png`` [N m or N].
    gamma_min : float, optional
        The margin drawn on ``gamma.png`` [m/s^2].

    Returns
    -------
    list of Path
        The files written.
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    written = []
    figures = [
        ("third_link", plot_third_link),
        ("arm", plot_arm),
        ("torques", lambda s: plot_torques(s, limits=torque_limits)),
        ("gamma", lambda s: plot_gamma(s, gamma_min=gamma_min)),
    ]
    if isinstance(solution.tracking, TrackingOutcome):
        figures.append(("tracking", plot_tracking))
    for name, draw in figures:
        fig = draw(solution)
        try:
            fig.tight_layout()
            path = directory / f"{name}.png"
            with atomic_path(path) as tmp:
                fig.savefig(tmp, dpi=110)
        finally:
            plt.close(fig)
        written.append(path)
    return written


def animate(solution: Solution, path: str | Path, fps: int = 25, trail: bool = True) -> Path:
    """Write a GIF of the arm following the plan (matplotlib's Pillow writer).

    Parameters
    ----------
    solution : Solution
        A solution with a trajectory.
    path : str or Path
        Output ``.gif`` file.
    fps : int
        Frames per second of real time.
    trail : bool
        Draw the CP path.
    """
    from matplotlib.animation import FuncAnimation, PillowWriter

    traj = solution.trajectory
    points = kinematic_functions(solution.plan.arm)["points"]
    t = traj.t
    frames = np.searchsorted(t, np.arange(t[0], t[-1] + 1e-9, 1.0 / fps))
    frames = np.clip(frames, 0, t.size - 1)
    all_pts = np.concatenate([np.asarray(points(traj.q[i])).T for i in frames])
    lo, hi = all_pts.min(axis=0) - 0.2, all_pts.max(axis=0) + 0.2
    fig, ax = plt.subplots(figsize=(5, 5))
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.grid(alpha=0.3)
    ax.set_title(solution.name)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    if trail:
        ax.plot(traj.cp[:, 0, 0], traj.cp[:, 1, 0], "r-", lw=0.8, alpha=0.6, label="CP path")
        ax.legend(loc="upper right", fontsize="small")
    (line,) = ax.plot([], [], "-o", color="k", lw=2, ms=4)
    label = ax.text(0.02, 0.95, "", transform=ax.transAxes)

    def draw(i):
        pts = np.asarray(points(traj.q[i]))
        line.set_data(pts[0], pts[1])
        label.set_text(f"t = {t[i]:.2f} s")
        return line, label

    anim = FuncAnimation(fig, draw, frames=frames, blit=True)
    path = Path(path)
    try:
        with atomic_path(path) as tmp:
            anim.save(tmp, writer=PillowWriter(fps=fps))
    finally:
        plt.close(fig)
    return path
