"""Figures a newcomer can read: units on the axes, torque limits and +-gamma_min drawn."""

import matplotlib.pyplot as plt
import numpy as np
import pytest

from cpopt.plotting import plot_gamma, plot_torques


def _horizontal_lines(ax) -> list[float]:
    """The y values of the axes' horizontal lines (axhline), sorted."""
    ys = []
    for line in ax.get_lines():
        y = np.asarray(line.get_ydata(), float)
        if y.size == 2 and y[0] == y[1] and tuple(line.get_xdata()) == (0, 1):
            ys.append(float(y[0]))
    return sorted(ys)


def test_torques_carry_units_and_their_limits(paper_solutions):
    fig = plot_torques(paper_solutions["paper_transfer"], limits=(400.0, None))
    try:
        ax = fig.axes[0]
        assert ax.get_xlabel() == "t [s]" and "[N m]" in ax.get_ylabel()
        assert _horizontal_lines(ax) == [-400.0, 400.0]  # tau2 has no limit: no line
        labels = ax.get_legend_handles_labels()[1]
        assert labels == ["tau1 [N m]", "tau2 [N m]", "|tau1| limit"]
    finally:
        plt.close(fig)


def test_gamma_shows_the_margin_and_its_certified_minimum(paper_solutions):
    solution = paper_solutions["paper_swing_up"]
    fig = plot_gamma(solution, gamma_min=2.0)
    try:
        ax = fig.axes[0]
        assert ax.get_ylabel() == "gamma [m/s^2]" and ax.get_xlabel() == "t [s]"
        assert _horizontal_lines(ax) == [-2.0, 0.0, 2.0]
        labels = ax.get_legend_handles_labels()[1]
        assert labels[-1] == "+-gamma_min = 2"
        minimum = float(labels[1].split("= ")[1])
        assert minimum == pytest.approx(solution.metrics.min_abs_gamma, rel=1e-2)
    finally:
        plt.close(fig)
