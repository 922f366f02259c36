"""``sweep.png``: the cost against the varied values, failed points marked.

* one varied key: the cost against its value (and, for a time-optimal problem, the duration T
  in a second panel);
* two: a heat map of the cost over the grid, failed cells crossed;
* more: the cost against the first key, one line per combination of the others.

The cost is the optimizer's objective where the planner has one, else the torque integral
``torque_sq_integral``. Failed points are red crosses at their cost when the failed solve still
measured one, else on the bottom edge of the axes.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..io.output import atomic_path


def _number(text) -> float:
    try:
        return float(text)
    except (TypeError, ValueError):
        return math.nan


def cost_column(rows: list[dict]) -> str:
    """``objective`` when any row has one, else ``torque_sq_integral``."""
    if any(str(r.get("objective", "")) not in ("", "None") for r in rows):
        return "objective"
    return "torque_sq_integral"


def _axis_values(rows: list[dict], key: str) -> tuple[list, bool]:
    """The distinct values of a key in grid order, and whether they are all numbers."""
    values = list(dict.fromkeys(r[key] for r in rows))
    numeric = all(not math.isnan(_number(v)) for v in values)
    return values, numeric


def _line(ax, rows, key, column, label=None) -> None:
    x = [_number(r[key]) for r in rows]
    y = [_number(r[column]) for r in rows]
    ok = [r["status"] == "solved" for r in rows]
    good = [(a, b) for a, b, g in zip(x, y, ok, strict=True) if g]
    if good:
        ax.plot(*zip(*good, strict=True), "o-", ms=4, label=label)
    bad = [(a, b) for a, b, g in zip(x, y, ok, strict=True) if not g]
    if bad:
        bottom = ax.get_ylim()[0]
        xs = [a for a, _ in bad]
        ys = [bottom if math.isnan(b) else b for _, b in bad]
        failed = "failed" if label is None else None
        ax.plot(xs, ys, "x", color="red", ms=9, mew=2, clip_on=False, label=failed)


def _one(fig, rows, key, column, time_optimal) -> None:
    axes = fig.subplots(2 if time_optimal else 1, 1, sharex=True, squeeze=False)[:, 0]
    _line(axes[0], rows, key, column)
    axes[0].set_ylabel(column)
    if time_optimal:
        _line(axes[1], rows, key, "duration_s")
        axes[1].set_ylabel("duration T [s]")
    axes[-1].set_xlabel(key)
    if any(r["status"] != "solved" for r in rows):
        axes[0].legend(loc="best", fontsize="small")


def _tick(value) -> str:
    number = _number(value)
    return str(value) if math.isnan(number) else f"{number:.4g}"


def _heat(fig, rows, keys, column) -> None:
    (xs, _), (ys, _) = (_axis_values(rows, k) for k in keys)
    grid = np.full((len(ys), len(xs)), np.nan)
    failed = []
    for r in rows:
        i, j = ys.index(r[keys[1]]), xs.index(r[keys[0]])
        if r["status"] == "solved":
            grid[i, j] = _number(r[column])
        else:
            failed.append((j, i))
    ax = fig.subplots()
    image = ax.imshow(grid, origin="lower", aspect="auto", cmap="viridis")
    fig.colorbar(image, ax=ax, label=column)
    if failed:
        ax.plot(*zip(*failed, strict=True), "x", color="red", ms=10, mew=2, label="failed")
        ax.legend(loc="upper right", fontsize="small")
    ax.set_xticks(range(len(xs)), [_tick(v) for v in xs], rotation=45)
    ax.set_yticks(range(len(ys)), [_tick(v) for v in ys])
    ax.set_xlabel(keys[0])
    ax.set_ylabel(keys[1])


def _lines(fig, rows, keys, column) -> None:
    ax = fig.subplots()
    others = keys[1:]
    groups = list(dict.fromkeys(tuple(r[k] for k in others) for r in rows))
    for group in groups:
        members = [r for r in rows if tuple(r[k] for k in others) == group]
        label = ", ".join(f"{k}={v}" for k, v in zip(others, group, strict=True))
        _line(ax, members, keys[0], column, label)
    if len(groups) <= 12:
        ax.legend(loc="best", fontsize="x-small")
    ax.set_xlabel(keys[0])
    ax.set_ylabel(column)


def write_plot(
    path: str | Path, keys: list[str], rows: list[dict], title: str, time_optimal: bool = False
) -> Path:
    """Write ``sweep.png`` from the rows of ``sweep.csv`` (values as read back, strings).

    Parameters
    ----------
    path : str or Path
        The PNG file (written atomically).
    keys : list of str
        The varied key paths, in ``--vary`` order.
    rows : list of dict
        The table's rows.
    title : str
        The figure's title (the base problem).
    time_optimal : bool
        Also plot the duration T [s] (one varied key).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    column = cost_column(rows)
    fig = plt.figure(figsize=(7, 6.5 if time_optimal and len(keys) == 1 else 4.5))
    try:
        if len(keys) == 1:
            words, numeric = _axis_values(rows, keys[0])
            if not numeric:  # words (a list SPEC): evenly spaced, in order
                rows = [{**r, keys[0]: words.index(r[keys[0]])} for r in rows]
            _one(fig, rows, keys[0], column, time_optimal)
            if not numeric:
                fig.axes[-1].set_xticks(range(len(words)), words)
        elif len(keys) == 2:
            _heat(fig, rows, keys, column)
        else:
            _lines(fig, rows, keys, column)
        fig.suptitle(f"{title}: {column}" + (" and duration" if time_optimal else ""))
        fig.tight_layout()
        path = Path(path)
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=110, format="png")
    finally:
        plt.close(fig)
    return path


__all__ = ["cost_column", "write_plot"]
