"""The wall clock a user sees: ``cpopt solve`` on every bundled problem, one process each.

For each ``problems/*.yaml`` it runs ``python -m cpopt solve <file> --out <tmp>`` as a user
does, with its stderr on a pseudo-terminal so that the progress lines are written as they are
to a terminal, and timestamps each line as it arrives. The stages:

* ``startup``: from starting the process to its first progress line (imports, reading and
  validating the file, forking the solver process);
* ``plan``: from there to ``sampling the plan`` (every planning stage, the switch search's seed
  included);
* ``verify``: sampling and verification by simulation, up to ``writing results``;
* ``write``: writing the files, up to the end of the process.

It prints one line per problem, exactly::

    E2E <name> wall=<s> startup=<s> plan=<s> verify=<s> write=<s> status=<status>

and ``E2E_MEDIAN wall=<s>``. Every problem is solved once untimed first, so the figures are
those of a warm cache of compiled libraries; the processes may cache Python's
bytecode as a user's do (:func:`user_environment`; ``--keep-environment`` runs them in this
environment as it is). ``solution.json`` holds the stages measured inside the solver process
too (``solver.stage_times``).

Usage::

    python benchmarks/end_to_end.py                    # every bundled problem
    python benchmarks/end_to_end.py --problems paper_swing_up,swing_up_min_torque
    python benchmarks/end_to_end.py --keep-environment  # e.g. PYTHONDONTWRITEBYTECODE kept
"""

from __future__ import annotations

import argparse
import json
import os
import pty
import select
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PROBLEMS = ROOT / "problems"
STAGES = ("startup", "plan", "verify", "write")


def user_environment(keep: bool = False) -> dict[str, str]:
    """The environment ``cpopt solve`` runs in: this one, except that Python may cache its
    bytecode as it does by default (``PYTHONDONTWRITEBYTECODE`` removed, unless ``keep``).
    Without the cache every process compiles cpopt's modules from source (0.1-0.2 s), which
    a user's installation does once (pip compiles them at install; an editable install on the
    first run)."""
    env = dict(os.environ)
    if not keep:
        env.pop("PYTHONDONTWRITEBYTECODE", None)
    return env


def run(
    path: Path, out: Path, env: dict[str, str] | None = None
) -> tuple[float, list[tuple[float, str]], int]:
    """Run ``cpopt solve`` on one file: wall time [s], (arrival [s], line) of every progress
    line, exit code."""
    master, slave = pty.openpty()
    command = [sys.executable, "-m", "cpopt", "solve", str(path), "--out", str(out)]
    start = time.perf_counter()
    child = subprocess.Popen(
        command,
        cwd=ROOT,
        stdout=subprocess.DEVNULL,
        stderr=slave,
        stdin=subprocess.DEVNULL,
        env=env or user_environment(),
    )
    os.close(slave)
    lines, pending = [], b""
    while True:
        ready, _, _ = select.select([master], [], [], 0.05)
        if ready:
            try:
                data = os.read(master, 4096)
            except OSError:  # the child closed the terminal
                data = b""
            if not data:
                break
            pending += data
            *done, pending = pending.split(b"\n")
            now = time.perf_counter() - start
            lines += [(now, line.decode(errors="replace").strip()) for line in done]
        elif child.poll() is not None:
            break
    code = child.wait()
    os.close(master)
    return time.perf_counter() - start, lines, code


def stages(wall: float, lines: list[tuple[float, str]]) -> dict[str, float]:
    """The stage times [s] from the arrival times of the progress lines."""

    def first(*words: str) -> float | None:
        return next((t for t, text in lines if any(w in text for w in words)), None)

    begin = lines[0][0] if lines else wall
    sampled = first("sampling the plan", "open-loop replay") or wall
    writing = first("writing results") or wall
    return {
        "startup": begin,
        "plan": max(sampled - begin, 0.0),
        "verify": max(writing - sampled, 0.0),
        "write": max(wall - writing, 0.0),
    }


def status_of(out: Path, name: str) -> str:
    """The status in the problem's ``solution.json`` (``missing`` without one)."""
    try:
        return json.loads((out / name / "solution.json").read_text())["status"]
    except (OSError, ValueError, KeyError):
        return "missing"


def warm_up(paths: list[Path], env: dict[str, str]) -> None:
    """One untimed solve of every problem: the compiled libraries (the optimizer's samples per
    arm kind, the verification's steps per arm kind and curve degree) and the bytecode cache
    exist afterwards."""
    for path in paths:
        with tempfile.TemporaryDirectory() as tmp:
            run(path, Path(tmp), env)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problems", help="comma-separated names (default: every bundled one)")
    parser.add_argument(
        "--keep-environment",
        action="store_true",
        help="run with this environment as it is (by default PYTHONDONTWRITEBYTECODE is "
        "removed: a user's Python caches bytecode)",
    )
    args = parser.parse_args(argv)
    env = user_environment(args.keep_environment)
    paths = sorted(PROBLEMS.glob("*.yaml"))
    if args.problems:
        wanted = set(args.problems.split(","))
        paths = [p for p in paths if p.stem in wanted]
    warm_up(paths, env)
    walls = []
    for path in paths:
        with tempfile.TemporaryDirectory() as tmp:
            wall, lines, _ = run(path, Path(tmp), env)
            times = stages(wall, lines)
            status = status_of(Path(tmp), path.stem)
        walls.append(wall)
        figures = " ".join(f"{k}={times[k]:.2f}" for k in STAGES)
        print(f"E2E {path.stem} wall={wall:.2f} {figures} status={status}", flush=True)
    print(f"E2E_MEDIAN wall={statistics.median(walls):.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
