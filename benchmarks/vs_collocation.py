"""The flat optimizer against direct collocation of the full dynamics (rockit), in one run.

For each benchmark problem (``benchmarks/problems/``: the paper's T = 1 s transfer and its
swing-up, minimum torque, gamma_min = 2 m/s^2, no torque-continuity constraint) it solves

* ``flat``: the CP-flat optimizer (B-spline coefficients as in the file),
* ``collocation``: direct collocation without the regularity constraint,
* ``collocation_gamma``: direct collocation with ``sign(gamma) gamma >= gamma_min`` at knots,

each ``--repeats`` times (the first call builds, later calls reuse the solver), and prints

* one table row per method and size: build time, solve time (median, min, max), Ipopt
  iterations, the torque integral on a fine grid, min |gamma| (certified over the whole plan
  for flat; on 8 samples per interval for collocation, where it is not certified) and the
  end-state error when the plan's torques are replayed open loop on the full dynamics;
* a scaling table: flat solve time against the number of B-spline coefficients, collocation
  solve time against N;
* one line per problem, exactly (one line, split here)
  ``RATIO <problem> solve_time_collocation_gamma_N100/flat=<x>
  cost_flat/collocation_gamma_N200=<y>``
  (``--quick`` runs small sizes and names them in the line instead of N100 and N200).

Usage::

    pip install -e '.[peers]'
    python benchmarks/vs_collocation.py            # full run (several minutes)
    python benchmarks/vs_collocation.py --quick    # one repetition, small sizes (a test)
"""

from __future__ import annotations

import argparse
import statistics
import sys
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent
PROBLEMS = ("transfer", "swing_up")
FINE = 4001
"""Samples per phase of the fine grid on which flat costs are measured."""


@dataclass
class Row:
    """One benchmark result (times in s)."""

    problem: str
    method: str
    size: str
    build: float
    solves: list
    iterations: int
    cost: float
    min_gamma: float
    replay_error: float
    status: str

    @property
    def median(self) -> float:
        """Median solve time [s]."""
        return statistics.median(self.solves)


def _load(name: str, quick: bool, coefficients: int | None = None):
    from cpopt.problem import load_problem, parse_problem

    problem = load_problem(ROOT / "problems" / f"{name}.yaml")
    if quick or coefficients:
        data = problem.spec.model_dump()
        opt = data["optimizer"]
        if quick:
            opt.update(coefficients=14, samples=61)
        if coefficients:
            opt["coefficients"] = coefficients
        problem = parse_problem(data, problem.source, problem.name)
    return problem


def run_flat(problem, repeats: int, label: str) -> Row:
    """Solve with the flat optimizer ``repeats`` times; measure the last plan."""
    from cpopt.flatopt import optimize
    from cpopt.simulate import simulate_open_loop
    from cpopt.trajectory import metrics, sample

    results = [optimize(problem) for _ in range(repeats)]
    first, last = results[0], results[-1]
    plan = last.plan
    cost = metrics(plan, sample(plan, FINE)).torque_sq_integral
    return Row(
        problem.name,
        "flat",
        label,
        first.solver.build_time_s,
        [r.solver.solve_time_s for r in results],
        last.solver.iterations,
        cost,
        plan.min_abs_gamma()[0],
        simulate_open_loop(plan).final_state_error,
        last.status,
    )


def run_collocation(problem, intervals: int, gamma: bool, repeats: int) -> Row:
    """Solve by collocation ``repeats`` times (the first call transcribes and builds)."""
    from cpopt.collocation import collocate, joint_metrics, joint_trajectory, replay

    results = [collocate(problem, intervals, gamma) for _ in range(repeats)]
    first, last = results[0], results[-1]
    plan = last.plan
    measured = joint_metrics(plan, joint_trajectory(plan))
    return Row(
        problem.name,
        "collocation_gamma" if gamma else "collocation",
        f"N={intervals}",
        first.solver.build_time_s,
        [r.solver.solve_time_s for r in results],
        last.solver.iterations,
        measured.torque_sq_integral,
        measured.min_abs_gamma,
        replay(plan, problem.nodes[-1]).final_state_error,
        last.status,
    )


HEADER = (
    f"{'problem':10s} {'method':18s} {'size':16s} {'build':>7s} {'solve med':>9s} "
    f"{'min':>7s} {'max':>7s} {'iter':>5s} {'cost (fine)':>12s} {'min|gamma|':>10s} "
    f"{'replay err':>10s} status"
)


def format_row(r: Row) -> str:
    """One table line."""
    return (
        f"{r.problem:10s} {r.method:18s} {r.size:16s} {r.build:7.2f} {r.median:9.3f} "
        f"{min(r.solves):7.3f} {max(r.solves):7.3f} {r.iterations:5d} {r.cost:12.1f} "
        f"{r.min_gamma:10.3f} {r.replay_error:10.2e} {r.status}"
    )


def ratio_line(name: str, rows: list[Row], mid: int, large: int) -> str:
    """The RATIO line of one problem."""
    flat = next(r for r in rows if r.method == "flat")
    by_size = {r.size: r for r in rows if r.method == "collocation_gamma"}
    speed = by_size[f"N={mid}"].median / flat.median
    cost = flat.cost / by_size[f"N={large}"].cost
    return (
        f"RATIO {name} solve_time_collocation_gamma_N{mid}/flat={speed:.3f} "
        f"cost_flat/collocation_gamma_N{large}={cost:.4f}"
    )


def main(argv=None) -> int:
    """Run the benchmark and print its tables and RATIO lines."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one repetition, small sizes")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--problems", default=",".join(PROBLEMS))
    args = parser.parse_args(argv)
    repeats = 1 if args.quick else args.repeats
    sizes = (10, 20) if args.quick else (50, 100, 200)
    mid, large = sizes[-2], sizes[-1]
    scaling_coefficients = () if args.quick else (14, 20, 26, 34)
    names = args.problems.split(",")
    rows: list[Row] = []
    scaling: list[Row] = []
    print(HEADER, flush=True)
    for name in names:
        problem = _load(name, args.quick)
        o = problem.spec.optimizer
        label = f"{o.coefficients} coef/{o.samples} smp"
        rows.append(run_flat(problem, repeats, label))
        print(format_row(rows[-1]), flush=True)
        for gamma in (False, True):
            for n in sizes:
                rows.append(run_collocation(problem, n, gamma, repeats))
                print(format_row(rows[-1]), flush=True)
        for count in scaling_coefficients:
            scaled = _load(name, False, count)
            scaling.append(run_flat(scaled, max(1, repeats // 2), f"{count} coef"))
    if scaling:
        print("\nscaling: flat solve time [s] against B-spline coefficients per coordinate")
        for r in scaling:
            print(
                f"  {r.problem:10s} {r.size:10s} {r.median:8.3f}  iter {r.iterations:4d}"
                f"  cost {r.cost:10.1f}"
            )
    print("scaling: collocation_gamma solve time [s] against N")
    for r in rows:
        if r.method == "collocation_gamma":
            print(
                f"  {r.problem:10s} {r.size:10s} {r.median:8.3f}  iter {r.iterations:4d}"
                f"  cost {r.cost:10.1f}"
            )
    for name in names:
        print(ratio_line(name, [r for r in rows if r.problem == name], mid, large))
    return 0


if __name__ == "__main__":
    sys.exit(main())
