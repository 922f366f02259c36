"""Path and timing, separated, against the free B-spline curves, in one run.

The paper (section 6) expects low-order paths y(s) with a timing law s(t) to wander less than
high-order time polynomials. For each problem (``transfer``: problems/transfer_straight_line.yaml,
the CP on the straight line between its ends; ``swing_up``: problems/swing_up_path_timing.yaml,
two free cubic Bezier paths; optionally ``transfer_min_time``: transfer_min_time_on_path.yaml)
it solves

* ``path_timing``: the file as it is,
* ``bspline``: the same problem (nodes, freed values, objective, limits, samples) with the free
  B-spline curves of degree 8 and 14 coefficients per coordinate and phase,

each ``--repeats`` times (the first call builds the solver, later calls reuse it), and prints one
row per method: status, objective, the torque integral on a fine grid, peak torques, build and
solve time (median, min, max) [s], Ipopt iterations, decision variables (``core``: what the
optimizer chooses; ``all``: with the lifted samples), and the CP path's wandering: its length
over the straight distance between its ends, its largest distance from the segment between
its ends [m], and the largest distance of each phase from the segment between its own nodes
(a via state off the start-goal segment dominates the whole motion's excursion) [m]. Then one
line per problem, exactly (one line, split here)::

    WANDER <problem> length_ratio path_timing=<a> bspline=<b>
    excursion_m path_timing=<c> bspline=<d> phase_excursion_m path_timing=<e> bspline=<f>
    cost_path_timing/bspline=<g>

Usage::

    python benchmarks/path_timing.py             # three repetitions (a few minutes)
    python benchmarks/path_timing.py --quick     # one repetition (a test)
"""

from __future__ import annotations

import argparse
import statistics
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PROBLEMS = {
    "transfer": "transfer_straight_line",
    "swing_up": "swing_up_path_timing",
    "transfer_min_time": "transfer_min_time_on_path",
}
FINE = 2001
"""Samples per phase of the fine grid on which costs and wandering are measured."""


@dataclass
class Row:
    """One benchmark result (times in s)."""

    problem: str
    method: str
    status: str
    objective: float
    cost: float
    peak: tuple
    build: float
    solves: list
    iterations: int
    core: int
    variables: int
    length_ratio: float
    excursion: float
    phase_excursion: float


def problems(name: str):
    """The path_timing problem and its free B-spline twin."""
    from cpopt.problem import load_problem, parse_problem

    problem = load_problem(ROOT / "problems" / f"{PROBLEMS[name]}.yaml")
    data = problem.spec.model_dump()
    data["optimizer"].update(curve="bspline", degree=8, coefficients=14, path=None)
    return problem, parse_problem(data, problem.source, problem.name)


def run(name: str, method: str, problem, repeats: int) -> Row:
    """Solve ``repeats`` times; measure the last solution."""
    from cpopt.closedform.paths import wandering
    from cpopt.closedform.trajectory import sample
    from cpopt.flatopt.transcribe import build
    from cpopt.pipeline import solve

    solutions = [solve(problem) for _ in range(repeats)]
    first, last = solutions[0], solutions[-1]
    signs = tuple(1 if s == "positive" else -1 for s in last.solver.details.gamma_signs)
    nlp = build(problem, signs)  # the first round's NLP, cached by the solve: no new build
    traj = sample(last.plan, per_phase=FINE)
    ratio, excursion = wandering(traj.cp[:, :, 0])
    phases = [wandering(traj.cp[traj.phase == k, :, 0])[1] for k in range(len(last.plan.phases))]
    return Row(
        name,
        method,
        last.status,
        last.solver.objective,
        last.metrics.torque_sq_integral,
        last.metrics.peak_torque,
        first.solver.build_time_s,
        [s.solver.solve_time_s for s in solutions],
        last.solver.iterations,
        nlp.layout.size,
        int(nlp.solver.size_in(0)[0]),
        ratio,
        excursion,
        max(phases),
    )


HEADER = (
    f"{'problem':17s} {'method':11s} {'status':7s} {'objective':>11s} {'cost (fine)':>11s} "
    f"{'peak tau1, tau2':>15s} {'build':>6s} {'solve med':>9s} {'min':>6s} {'max':>6s} "
    f"{'iter':>5s} {'core':>5s} {'all':>5s} {'length':>7s} {'excursion':>9s} {'phase exc':>9s}"
)


def format_row(r: Row) -> str:
    """One table line."""
    return (
        f"{r.problem:17s} {r.method:11s} {r.status:7s} {r.objective:11.5g} {r.cost:11.1f} "
        f"{r.peak[0]:7.1f},{r.peak[1]:7.1f} {r.build:6.2f} {statistics.median(r.solves):9.3f} "
        f"{min(r.solves):6.3f} {max(r.solves):6.3f} {r.iterations:5d} {r.core:5d} "
        f"{r.variables:5d} {r.length_ratio:7.3f} {r.excursion:9.4f} {r.phase_excursion:9.4f}"
    )


def wander_line(name: str, path: Row, spline: Row) -> str:
    """The WANDER line of one problem."""
    return (
        f"WANDER {name} length_ratio path_timing={path.length_ratio:.4f} "
        f"bspline={spline.length_ratio:.4f} excursion_m path_timing={path.excursion:.4f} "
        f"bspline={spline.excursion:.4f} phase_excursion_m path_timing="
        f"{path.phase_excursion:.4f} bspline={spline.phase_excursion:.4f} "
        f"cost_path_timing/bspline={path.cost / spline.cost:.4f}"
    )


def main(argv=None) -> int:
    """Run the benchmark and print its table and WANDER lines."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one repetition")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--problems", default="transfer,swing_up", help=", ".join(PROBLEMS))
    args = parser.parse_args(argv)
    repeats = 1 if args.quick else args.repeats
    names = args.problems.split(",")
    lines = []
    print(HEADER, flush=True)
    for name in names:
        path_problem, spline_problem = problems(name)
        path = run(name, "path_timing", path_problem, repeats)
        print(format_row(path), flush=True)
        spline = run(name, "bspline", spline_problem, repeats)
        print(format_row(spline), flush=True)
        lines.append(wander_line(name, path, spline))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
