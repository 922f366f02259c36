"""The flat optimizer against direct collocation of the full dynamics (rockit), in one run.

For each benchmark problem (``benchmarks/problems/``: the paper's T = 1 s transfer and its
swing-up, minimum torque, gamma_min = 2 m/s^2, no torque-continuity constraint) it solves

* ``flat``: the CP-flat optimizer (B-spline coefficients as in the file),
* ``flat_switch``: the same with ``gamma_switches: auto`` and ``gamma_sign: auto`` (switches of
  the sign of gamma at via states that reset xi; collocation without the regularity
  constraint pins no sign either; at most 1000 Ipopt iterations per pattern); its solve time is
  that of every pattern the search solved,
* ``collocation``: direct collocation without the regularity constraint,
* ``collocation_gamma``: direct collocation with ``sign(gamma) gamma >= gamma_min`` at knots,
* ``fatrop_gamma``: the same constraint, rockit's multiple shooting solved by Fatrop (at the
  middle size only),

each ``--repeats`` times from the same cold initial guess (the first call builds, later calls
reuse the solver; a failed solve is not repeated), and prints

* one table row per method and size: build time, solve time (median, min, max), Ipopt
  iterations, the torque integral on a fine grid, min |gamma| (certified over the whole plan
  for flat; on 8 samples per interval for collocation, where it is not certified) and the
  end-state error when the plan's torques are replayed open loop on the full dynamics;
* a scaling table: flat solve time against the number of B-spline coefficients, collocation
  solve time against N;
* one line per problem, exactly (one line, split here)
  ``RATIO <problem> solve_time_collocation_gamma_N100/flat=<x>
  cost_flat/collocation_gamma_N200=<y>``
  (``--quick`` runs small sizes and names them in the line instead of N100 and N200);
* one more line per problem, exactly (one line, split here)
  ``RATIO_SWITCH <problem> cost_flat_switch/collocation_N200=<y>
  solve_time_collocation_N100/flat_switch=<x>`` (collocation without the gamma constraint);
* one more line per problem, exactly (one line, split here)
  ``SPEED <problem> flat_solve=<s> flat_cold=<s> collocation_gamma_N100_solve=<s>
  fatrop_gamma_N100_solve=<s>``: median solve times, and ``flat_cold`` the wall time of the
  first flat solve in the run, building included, with the compiled sample library cached
  (the first call of the run loads it; a cold cache would add its compilation once);
* the median process CPU time of each row's solves (the machine may be shared).

Usage::

    pip install -e .
    python benchmarks/vs_collocation.py            # full run (several minutes)
    python benchmarks/vs_collocation.py --quick    # one repetition, small sizes (a test)
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
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
    cold: float = 0.0
    cpu: float = 0.0
    signs: str = ""

    @property
    def median(self) -> float:
        """Median solve time [s]."""
        return statistics.median(self.solves)


def _load(name: str, quick: bool, coefficients: int | None = None):
    """A benchmark problem; with ``coefficients``, as many samples per B-spline piece as the
    file has (``optimizer.samples`` counts samples per phase)."""
    from cpopt.problem import load_problem, parse_problem

    problem = load_problem(ROOT / "problems" / f"{name}.yaml")
    if quick or coefficients:
        data = problem.spec.model_dump()
        opt = data["optimizer"]
        if quick:
            opt.update(coefficients=14, samples=50)
        if coefficients:
            pieces = opt["coefficients"] - opt["degree"]
            per_piece = opt["samples"] / (pieces + 4)
            opt["coefficients"] = coefficients
            opt["samples"] = round(per_piece * (coefficients - opt["degree"] + 4))
        problem = parse_problem(data, problem.source, problem.name)
    return problem


def _timed(solve, repeats: int) -> tuple[list, float, float]:
    """Call ``solve()`` up to ``repeats`` times (not again after a failure): the results, the
    wall time of the first call and the median process CPU time of the calls [s]."""
    results, walls, cpus = [], [], []
    for _ in range(repeats):
        wall, cpu = time.perf_counter(), time.process_time()
        results.append(solve())
        walls.append(time.perf_counter() - wall)
        cpus.append(time.process_time() - cpu)
        if results[-1].status != "solved":
            break
    return results, walls[0], statistics.median(cpus)


def with_switches(problem, max_iter: int = 1000):
    """The problem with ``gamma_switches: auto``, no sign of gamma asked and at most
    ``max_iter`` Ipopt iterations per pattern (``--quick``: 200, a smoke test)."""
    from cpopt.problem import parse_problem

    data = problem.spec.model_dump()
    data["optimizer"].update(gamma_switches="auto", gamma_sign=None)
    # the seeded search solves one pattern (the transfer's needs 620 iterations, measured)
    # and caps its polish attempts itself; the greedy search's dead ends were cut at 500
    data["optimizer"]["solver"]["max_iter"] = max_iter
    return parse_problem(data, problem.source, problem.name)


def run_flat(problem, repeats: int, label: str, method: str = "flat") -> Row:
    """Solve with the flat optimizer ``repeats`` times; measure the last plan."""
    from cpopt.closedform.plan import SingularPlanError
    from cpopt.closedform.trajectory import metrics, sample
    from cpopt.flatopt import optimize
    from cpopt.model.kinematics import ReachError
    from cpopt.verify.integrate import DivergenceError
    from cpopt.verify.simulate import simulate_open_loop

    results, cold, cpu = _timed(lambda: optimize(problem), repeats)
    first, last = results[0], results[-1]
    plan = last.plan
    try:
        cost = metrics(plan, sample(plan, FINE)).torque_sq_integral
        replay = simulate_open_loop(plan).final_state_error
    except (ReachError, SingularPlanError, DivergenceError):  # a failed plan: its row says so
        cost = replay = float("nan")
    return Row(
        problem.name,
        method,
        label,
        first.solver.build_time_s,
        [r.solver.solve_time_s for r in results],
        last.solver.iterations,
        cost,
        plan.min_abs_gamma()[0],
        replay,
        last.status,
        cold,
        cpu,
        _pattern(last),
    )


def _pattern(result) -> str:
    """The signs of gamma of a flat result's phases and its switch times, in one word."""
    d = result.solver.details
    times = ",".join(f"{t:.3f}" for t in d.switch_times)
    return "/".join(s[:3] for s in d.gamma_signs) + (f"@{times}" if times else "")


def with_fatrop(problem):
    """The problem with ``collocation.solver: fatrop`` (multiple shooting)."""
    from cpopt.problem import parse_problem

    data = problem.spec.model_dump()
    data["collocation"].update(solver="fatrop", method="multiple_shooting")
    return parse_problem(data, problem.source, problem.name)


def run_collocation(problem, intervals: int, gamma: bool, repeats: int) -> Row:
    """Solve by collocation ``repeats`` times (the first call transcribes and builds)."""
    from cpopt.collocation import collocate, joint_metrics, joint_trajectory, replay

    results, cold, cpu = _timed(lambda: collocate(problem, intervals, gamma), repeats)
    first, last = results[0], results[-1]
    plan = last.plan
    measured = joint_metrics(plan, joint_trajectory(plan))
    fatrop = problem.spec.collocation.solver == "fatrop"
    return Row(
        problem.name,
        ("fatrop" if fatrop else "collocation") + ("_gamma" if gamma else ""),
        f"N={intervals}",
        first.solver.build_time_s,
        [r.solver.solve_time_s for r in results],
        last.solver.iterations,
        measured.torque_sq_integral,
        measured.min_abs_gamma,
        replay(plan, problem.nodes[-1]).final_state_error,
        last.status,
        cold,
        cpu,
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


def ratio_switch_line(name: str, rows: list[Row], mid: int, large: int) -> str:
    """The RATIO_SWITCH line of one problem: flat with switches against collocation without
    the gamma constraint."""
    flat = next(r for r in rows if r.method == "flat_switch")
    by_size = {r.size: r for r in rows if r.method == "collocation"}
    cost = flat.cost / by_size[f"N={large}"].cost
    speed = by_size[f"N={mid}"].median / flat.median
    return (
        f"RATIO_SWITCH {name} cost_flat_switch/collocation_N{large}={cost:.4f} "
        f"solve_time_collocation_N{mid}/flat_switch={speed:.3f}"
    )


def speed_line(name: str, rows: list[Row], mid: int) -> str:
    """The SPEED line of one problem."""
    flat = next(r for r in rows if r.method == "flat")
    by = {(r.method, r.size): r for r in rows}
    colloc = by[("collocation_gamma", f"N={mid}")].median
    fatrop = by[("fatrop_gamma", f"N={mid}")].median
    return (
        f"SPEED {name} flat_solve={flat.median:.4f} flat_cold={flat.cold:.4f} "
        f"collocation_gamma_N{mid}_solve={colloc:.4f} fatrop_gamma_N{mid}_solve={fatrop:.4f}"
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
        switching = with_switches(problem, 200 if args.quick else 1000)
        rows.append(run_flat(switching, max(1, repeats // 2), label, "flat_switch"))
        print(format_row(rows[-1]), f"signs {rows[-1].signs}", flush=True)
        for gamma in (False, True):
            for n in sizes:
                rows.append(run_collocation(problem, n, gamma, repeats))
                print(format_row(rows[-1]), flush=True)
        rows.append(run_collocation(with_fatrop(problem), mid, True, repeats))
        print(format_row(rows[-1]), flush=True)
        for count in scaling_coefficients:
            scaled = _load(name, False, count)
            label = f"{count} coef/{scaled.spec.optimizer.samples} smp"
            scaling.append(run_flat(scaled, max(1, repeats // 2), label))
    if scaling:
        print("\nscaling: flat solve time [s] against B-spline coefficients per coordinate")
        for r in scaling:
            print(
                f"  {r.problem:10s} {r.size:16s} {r.median:8.3f}  iter {r.iterations:4d}"
                f"  cost {r.cost:10.1f}  {r.status}"
            )
    print("scaling: collocation_gamma solve time [s] against N")
    for r in rows:
        if r.method == "collocation_gamma":
            print(
                f"  {r.problem:10s} {r.size:10s} {r.median:8.3f}  iter {r.iterations:4d}"
                f"  cost {r.cost:10.1f}"
            )
    print("process CPU time per solve [s] (median)")
    for r in rows:
        print(f"  {r.problem:10s} {r.method:18s} {r.size:16s} {r.cpu:8.3f}")
    for name in names:
        print(ratio_line(name, [r for r in rows if r.problem == name], mid, large))
    for name in names:
        print(ratio_switch_line(name, [r for r in rows if r.problem == name], mid, large))
    for name in names:
        print(speed_line(name, [r for r in rows if r.problem == name], mid))
    return 0


if __name__ == "__main__":
    sys.exit(main())
