"""How ``cpopt sweep`` scales: one sweep run with 1 worker and with 2, as a user runs it.

The sweep is the optimized swing-up's cost against its duration (``swing_up_min_torque`` over
``motion.duration``, 16 points from 1.3 s to 2.0 s by default, 45 to 330 Ipopt iterations each:
at 1.25 s Ipopt stops at its iteration limit after 2079 iterations, and beyond about 2.1 s the
solves take thousands; one such point would make the run a measure of itself).
Each run is a ``cpopt sweep`` process of its own (a fresh local cluster: its start-up is in
the time), the compile cache warmed first. Then every point of the two-worker run is solved
alone in this process and its cost compared. It prints::

    SWEEP workers=1 wall=<s> workers=2 wall=<s> ratio=<wall 2 / wall 1>
    SWEEP_CHECK points=<n> solved=<n> max_rel_diff=<largest relative cost difference>

Usage::

    python benchmarks/sweep_scaling.py                  # 16 points (a few minutes)
    python benchmarks/sweep_scaling.py --points 4       # a small run
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BASE = ROOT / "problems" / "swing_up_min_torque.yaml"


def run_sweep(base: Path, spec: str, workers: int, out: Path) -> float:
    """Wall time [s] of one ``cpopt sweep`` process."""
    vary = f"motion.duration={spec}"
    command = [sys.executable, "-m", "cpopt", "sweep", str(base), "--vary", vary]
    command += ["--workers", str(workers), "--out", str(out), "--quiet"]
    tic = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True)
    wall = time.perf_counter() - tic
    if done.returncode not in (0, 1):
        raise SystemExit(f"cpopt sweep failed ({done.returncode}): {done.stderr[-2000:]}")
    return wall


def check(out: Path) -> tuple[int, int, float]:
    """Solve each point of a sweep alone; points, solved, largest relative cost difference."""
    from cpopt.pipeline import solve
    from cpopt.problem import load_problem
    from cpopt.sweep.table import PROBLEM, TABLE, read_table

    rows = read_table(out / TABLE)
    worst, solved = 0.0, 0
    for row in rows:
        alone = solve(load_problem(out / row["point"] / PROBLEM))
        if alone.status != row["status"]:
            raise SystemExit(f"{row['point']}: {row['status']} in the sweep, {alone.status} alone")
        if alone.ok:
            solved += 1
            cost = float(row["objective"])
            worst = max(worst, abs(cost - alone.solver.objective) / abs(alone.solver.objective))
    return len(rows), solved, worst


def main(argv=None) -> int:
    """Run the benchmark; returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=16, help="points of the sweep (16)")
    parser.add_argument("--first", type=float, default=1.3, help="shortest duration [s] (1.3)")
    parser.add_argument("--last", type=float, default=2.0, help="longest duration [s] (2.0)")
    args = parser.parse_args(argv)
    spec = f"{args.first}:{args.last}:{args.points}"
    from cpopt.pipeline import solve
    from cpopt.problem import load_problem

    solve(load_problem(BASE))  # warms the compile cache the workers read
    with tempfile.TemporaryDirectory() as scratch:
        walls = {n: run_sweep(BASE, spec, n, Path(scratch) / f"w{n}") for n in (1, 2)}
        points, solved, worst = check(Path(scratch) / "w2")
    print(
        f"SWEEP workers=1 wall={walls[1]:.2f} workers=2 wall={walls[2]:.2f} "
        f"ratio={walls[2] / walls[1]:.3f}"
    )
    print(f"SWEEP_CHECK points={points} solved={solved} max_rel_diff={worst:.3g}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
