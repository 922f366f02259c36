"""A sweep's files: each point's folder, ``sweep.csv``, and what ``--resume`` may skip.

A point's folder ``DIR/<point>/`` holds what ``cpopt solve`` writes there (``solution.json``,
``trajectory.csv``, ``tracking.csv``), the point's problem as ``problem.yaml`` (``cpopt solve``
runs it alone) and, written last, ``sweep_point.json``: the point's values, the SHA-256 of its
problem data and its row of ``sweep.csv``. A point is complete when that record is there, its
hash is the point's and its status is one of :data:`cpopt.results.STATUSES`; ``--resume``
skips complete points and reuses their rows. ``sweep.csv`` is rewritten whole (atomically)
after every point, rows in grid order: a crash or Ctrl-C loses no finished point.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import yaml

from ..io.output import OUTPUT_FILES, atomic_write, clear, locked, make_directory
from ..results import STATUSES, json_safe, write_solution
from .spec import Point
from .task import Outcome

RECORD = "sweep_point.json"
"""A point's record, written last into its folder."""
PROBLEM = "problem.yaml"
"""A point's problem data, as a problem file."""
TABLE = "sweep.csv"
"""The sweep's table, in ``--out``."""

COLUMNS = (
    "point", "status", "planner", "duration_s", "objective", "torque_sq_integral",
    "abs_power_integral", "peak_torque_1", "peak_torque_2", "min_abs_gamma", "max_torque_jump",
    "max_cp_error", "final_state_error", "tracking_success", "tracking_final_cp_error",
    "iterations", "build_time_s", "solve_time_s", "wall_time_s", "worker", "problem_sha256",
    "message",
)  # fmt: skip
"""Columns of ``sweep.csv``; the varied key paths come right after ``point``."""

ERROR, WORKER_LOST = "error", "worker_lost"
"""Statuses of a point without a solution: an exception inside cpopt (a bug), or its worker
lost more often than the scheduler retries a task."""


def columns(keys: list[str]) -> list[str]:
    """The header of ``sweep.csv`` for the varied key paths ``keys``."""
    return [COLUMNS[0], *keys, *COLUMNS[1:]]


def _row(point: Point, document: dict | None, outcome: Outcome, status: str, message: str):
    doc = document or {}
    metrics = doc.get("metrics") or {}
    verification = doc.get("verification") or {}
    solver = doc.get("solver") or {}
    tracking = doc.get("tracking") or {}
    peak = metrics.get("peak_torque") or [None, None]
    row = {"point": point.name, **point.values}
    row.update(
        status=status,
        planner=doc.get("planner", point.data.get("planner", "closed_form")),
        duration_s=doc.get("duration_s"),
        objective=solver.get("objective"),
        torque_sq_integral=metrics.get("torque_sq_integral"),
        abs_power_integral=metrics.get("abs_power_integral"),
        peak_torque_1=peak[0],
        peak_torque_2=peak[1],
        min_abs_gamma=metrics.get("min_abs_gamma"),
        max_torque_jump=metrics.get("max_torque_jump"),
        max_cp_error=verification.get("max_cp_error"),
        final_state_error=verification.get("final_state_error"),
        tracking_success=tracking.get("success"),
        tracking_final_cp_error=tracking.get("final_cp_error"),
        iterations=solver.get("iterations"),
        build_time_s=solver.get("build_time_s"),
        solve_time_s=solver.get("solve_time_s"),
        wall_time_s=outcome.wall_s,
        worker=outcome.worker,
        problem_sha256=point.digest,
        message=" ".join(message.split()),
    )
    return json_safe(row)  # numbers as Python's (the CSV and JSON write them the same)


def row_of(point: Point, outcome: Outcome | None, lost: str = "") -> dict:
    """A point's row of ``sweep.csv`` (``lost``: why the task never returned)."""
    if outcome is None:
        return _row(point, None, Outcome(None, 0.0, ""), WORKER_LOST, lost)
    if outcome.solution is None:
        return _row(point, None, outcome, ERROR, outcome.error)
    doc = json_safe(outcome.solution.as_dict())
    message = doc["solver"].get("message", "") if outcome.solution.status != "solved" else ""
    return _row(point, doc, outcome, outcome.solution.status, message)


def write_point(point: Point, outcome: Outcome | None, out: Path, lost: str = "") -> dict:
    """Replace a point's folder with its results (the record last); returns its row."""
    folder = make_directory(out / point.name)
    row = row_of(point, outcome, lost)
    with locked(folder):
        clear(folder, (RECORD, *OUTPUT_FILES))
        text = yaml.safe_dump(point.data, sort_keys=False, allow_unicode=True)
        atomic_write(folder / PROBLEM, lambda h: h.write(text))
        if outcome is not None and outcome.solution is not None:
            write_solution(outcome.solution, folder)
        record = {"point": point.name, "index": point.index, "values": point.values, "row": row}
        record["problem_sha256"] = point.digest
        atomic_write(folder / RECORD, lambda h: h.write(json.dumps(record, indent=2) + "\n"))
    return row


def completed(point: Point, out: Path) -> dict | None:
    """The row of a point whose results in ``out`` are complete for the same problem, else
    None (no record, another problem, no ``solution.json``, or no solution at all)."""
    folder = out / point.name
    try:
        record = json.loads((folder / RECORD).read_text(encoding="utf-8"))
        row = record["row"]
        ok = (
            record["problem_sha256"] == point.digest
            and row["status"] in STATUSES
            and (folder / "solution.json").is_file()
        )
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return row if ok else None


def _cell(value) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return repr(value)  # every digit: a row equals its point's solve exactly
    return str(value)


def write_table(path: Path, keys: list[str], rows: list[dict]) -> None:
    """Write ``sweep.csv`` whole (rows in the order given)."""
    header = columns(keys)

    def write(handle):
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(header)
        for row in rows:
            writer.writerow([_cell(row.get(name)) for name in header])

    atomic_write(path, write)


def read_table(path: str | Path) -> list[dict]:
    """The rows of a ``sweep.csv`` as dicts of strings (for plots and tests)."""
    with open(path, encoding="utf-8", newline="") as handle:
        return list(csv.DictReader(handle))


__all__ = [
    "COLUMNS",
    "ERROR",
    "PROBLEM",
    "RECORD",
    "TABLE",
    "WORKER_LOST",
    "columns",
    "completed",
    "read_table",
    "row_of",
    "write_point",
    "write_table",
]
