"""``cpopt sweep``: validate every point, run the missing ones on Dask, keep the table current.

Order of work: the options, the ``--vary`` values and every point of the grid are validated,
the output folders checked and a ``--scheduler`` asked for a connection (any fault:
:class:`~cpopt.sweep.spec.SweepError`, nothing is written or run); with
``--resume`` the points whose results are complete for the same problem are taken from their
folders; the cluster starts and runs the others, each result written as it arrives (the
point's folder, then ``sweep.csv`` whole); ``sweep.png`` last, with ``--plot``.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path

from ..io.output import OutputError, check_directory, check_problem_directory, make_directory
from .address import check_scheduler, parse_scheduler
from .bar import SweepBar
from .spec import Point, SweepError, build_points, parse_vary
from .table import TABLE, completed, read_table, write_point, write_table

PLOT = "sweep.png"
"""The figure written with ``--plot``, in ``--out``."""


@dataclass
class SweepResult:
    """What a sweep did: points in the grid, taken from earlier results, solved now, failed."""

    points: int
    skipped: int
    solved: int
    failed: int
    table: Path


def _check_outputs(out: Path, points: list[Point]) -> None:
    """Refuse an output folder that cannot hold the sweep's files; nothing is created."""
    try:
        check_directory(out)
        for name in (TABLE, PLOT):
            if (out / name).is_dir():
                raise OutputError(f"{out / name}: is a directory")
        for point in points:
            check_problem_directory(out / point.name)
    except OutputError as err:
        raise SweepError(f"--out {err}") from None


def _line(row: dict) -> str:
    """The one-line summary of a finished point (stdout)."""
    text = f"{row['point']}: {row['status']:<9s}"
    if row.get("duration_s") is not None:
        text += f" T={row['duration_s']:.4g} s"
    for name in ("objective", "torque_sq_integral"):
        if row.get(name) is not None:
            text += f"  {name}={row[name]:.6g}"
    if row.get("iterations"):
        text += f"  iterations={row['iterations']}"
    text += f"  wall={row['wall_time_s']:.2f} s"
    if row["status"] != "solved" and row.get("message"):
        text += f"\n    {row['message']}"
    return text


def _time_optimal(point: Point) -> bool:
    from ..problem import parse_problem

    return "duration" in parse_problem(point.data).free


def sweep(args: argparse.Namespace) -> SweepResult:
    """Run ``cpopt sweep`` with parsed arguments (``base``, ``vary``, ``out``, ``workers``,
    ``scheduler``, ``time_limit``, ``resume``, ``plot``, ``quiet``).

    Raises
    ------
    SweepError
        For bad input, before any work (exit code 2).
    KeyboardInterrupt
        On Ctrl-C, after the cluster is closed (finished points are on disk).
    """
    if args.workers is not None and args.scheduler is not None:
        raise SweepError("--workers starts a local cluster; --scheduler uses a running one")
    scheduler = args.scheduler
    if scheduler is not None:
        parse_scheduler(scheduler)  # its syntax before the slower checks
    varies = [parse_vary(text) for text in args.vary]
    keys = [v.key for v in varies]
    points = build_points(args.base, varies, args.time_limit)
    out = Path(args.out)
    _check_outputs(out, points)
    if scheduler is not None:
        scheduler = check_scheduler(scheduler).url
    try:
        make_directory(out)
    except OutputError as err:
        raise SweepError(f"--out {err}") from None
    rows = {}
    if args.resume:
        rows = {p.index: row for p in points if (row := completed(p, out)) is not None}
    table = out / TABLE
    write_table(table, keys, [rows[i] for i in sorted(rows)])
    skipped = len(rows)
    todo = [p for p in points if p.index not in rows]
    bar = SweepBar(len(points), skipped=skipped, quiet=args.quiet)
    if todo:
        from . import engine

        def done(point: Point, outcome, lost: str) -> None:
            row = write_point(point, outcome, out, lost)
            rows[point.index] = row
            write_table(table, keys, [rows[i] for i in sorted(rows)])
            bar.clear()
            print(_line(row), flush=True)
            bar.advance(point.name, row["status"])

        with engine.connect(args.workers, scheduler) as client:
            bar.begin(engine.slots(client))
            try:
                engine.run(client, todo, args.base, done)
            finally:
                bar.close()
    if args.plot:
        title = points[0].name.split("__")[0]
        time_optimal = len(keys) == 1 and _time_optimal(points[0])
        from .plot import write_plot

        write_plot(out / PLOT, keys, read_table(table), title, time_optimal)
    failed = sum(row["status"] != "solved" for row in rows.values())
    return SweepResult(len(points), skipped, len(rows) - failed, failed, table)


def summary(result: SweepResult) -> str:
    """The last line of a sweep (stdout)."""
    resumed = f" ({result.skipped} taken from earlier results)" if result.skipped else ""
    return (
        f"sweep: {result.points} points{resumed}: {result.solved} solved, {result.failed} failed "
        f"-> {result.table}"
    )


def main(args: argparse.Namespace) -> int:
    """The command: 0 every point solved, 1 a point failed, 2 bad input (130 is the caller's,
    on Ctrl-C)."""
    try:
        result = sweep(args)
    except SweepError as err:
        print(f"error: {err}", file=sys.stderr, flush=True)
        return 2
    print(summary(result), flush=True)
    return 1 if result.failed else 0


__all__ = ["PLOT", "SweepResult", "main", "summary", "sweep"]
