"""Robustness of tracking: every bundled plan, both controllers, sweeps and Monte Carlo plants.

For each plan of ``problems/*.yaml`` (solved first) and each controller (``tvlqr``,
``tvlqr_timescaled``, ``dfl``), at 1 kHz with a zero-order hold, it measures

* ``perfect``: the largest CP error on the model itself, no noise, no friction;
* ``sweep``: one-at-a-time sweeps of the 18 plant parameters (length, mass, centre of mass and
  inertia of each link; viscous and Coulomb friction of each joint) over +-20 % in 21 steps
  around the benchmark plant (:mod:`cpopt.tracking.robustness`: friction scaled to the plan,
  measurement noise, saturation at the problem's torque limits or 1.5 x the plan's peak);
* ``monte_carlo``: ``--trials`` seeded plants with every one of those parameters within
  +-10 %, noise and friction on;
* ``mass``: the largest error of the masses of links 1 and 2 (both heavier, both lighter,
  uniform rods) the controller survives on the benchmark plant and on the otherwise perfect
  model (no friction, no noise);
* ``MC delay``: for ``tvlqr_timescaled``, the median and largest delay of the Monte Carlo runs,
  how much later than T the slowed reference reached the goal [s].

The motors saturate at the problem's torque limits (``optimizer.limits.torque``), 1.5 times
the plan's peak torque where it has none; ``tvlqr_timescaled`` fits its torques to the same
limits. A run is judged when the controller's progress reaches the end of the plan: at T, or
up to half the plan's duration later for ``tvlqr_timescaled``.

``flat_mpc`` (TVLQR around the plan re-solved from the measured state every 20 ms,
:mod:`cpopt.tracking.mpc`) runs on the same plants one run at a time, its re-plans within
``--replan-deadline`` of wall time (default: the 20 ms period), solved by ``--replan-method``
(``ipopt`` or ``sqp``, as ``tracking.replan_method``), and prints
``REPLAN <plan> median_ms=<ms> p99_ms=<ms> misses=<fraction> feasible=<fraction>`` over all
its re-plans (misses: over the deadline or without a plan to follow; feasible: followed as the
SQP's best feasible iterate, not solved to optimality); it has no mass margins. Every
controller also gets a RealAIGym-style score (:mod:`cpopt.tracking.scores`,
``--score-values`` per category, 0 for none): ``SCORE <plan> <controller> model=...
velocity_noise=... torque_noise=... gain=... delay=... overall=...`` (torque noise up to 10 %
of the motors' limits, both actuator gains 0.5 .. 1.5, actuation delay 0 .. 40 ms).

A run succeeds when at T the CP is within 2 cm and theta within 5 deg of the goal, every joint
velocity within 0.25 rad/s (m/s) of the goal's, and it never diverged
(:class:`cpopt.tracking.Tolerance`). It prints a table and one line per plan and controller,
exactly ``ROBUST <plan> <controller> sweep=<fraction> monte_carlo=<fraction>``.

**Headroom.** Each optimized plan (planner ``optimize`` or ``collocation``) is also solved
again with ``optimizer.limits.torque_headroom`` h (``--headroom``, default
:data:`HEADROOM`, docs/benchmarks.md's recommendation; 0 skips this) on the benchmark's
motors: the problem's own torque limits, or where it has none the 1.5 x peak motors of its
h = 0 plan (then set as its torque limits, which that plan meets, so h = 0 is the same plan). A plan
whose peak torques already leave h of the motors (every plan on 1.5 x peak motors when
h <= 1/3) is itself the optimum with headroom h and is not solved again. The
re-solved plan is tracked with ``tvlqr`` on the h = 0 plan's benchmark plant (the same motors,
friction and Monte Carlo draws), and one line per plan gives
``HEADROOM <plan> h=<h> cost=<objective ratio to h=0> duration=<ratio> monte_carlo=<fraction>``.

With ``--workers N`` (a local Dask cluster of N single-threaded worker processes) or
``--scheduler ADDRESS`` (a running Dask cluster) the work runs as tasks, as ``cpopt sweep``
runs its points: one task solves each plan, then one task per plan and controller runs its
perfect-model run, its sweeps, its Monte Carlo plants and its mass margins (the solves run in
the worker processes themselves, like the serial run's in its process). Every task gets
plain data (the problem file's content, the plan) and gives the same figures as the serial run
(which, like the workers, runs with one BLAS and OpenMP thread):
the Monte Carlo plants of a plan and controller are drawn and simulated as one batch, exactly
as serially (plant i's parameters are row i of one seeded draw, its measurement noise is drawn
from ``default_rng([seed, i])``), so no figure depends on which worker ran what or when.

Usage::

    python benchmarks/robustness.py                       # every bundled plan (minutes)
    python benchmarks/robustness.py --workers 2           # the same figures, on two workers
    python benchmarks/robustness.py --plans paper_transfer --trials 20
    python benchmarks/robustness.py --quick               # a small run (a test)
    python benchmarks/robustness.py --plans swing_up_min_time --headroom 0.1 --trials 20
    python benchmarks/robustness.py --controllers tvlqr,dfl --headroom 0   # issue 24's work
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import dataclass

from cpopt.sweep.task import THREAD_VARIABLES

# One BLAS and OpenMP thread here as in the Dask workers (set before NumPy loads its BLAS): with
# more threads the sums run in another order, and a diverging run's last digits, then its
# errors (the Monte Carlo CP median of a failing controller), differ from the workers'.
os.environ.update(dict.fromkeys(THREAD_VARIABLES, "1"))

import numpy as np

CONTROLLERS = ("tvlqr", "tvlqr_timescaled", "dfl", "flat_mpc")
QUICK_PLANS = "paper_transfer"


@dataclass
class Row:
    """One plan and controller (fractions of successful runs, errors in m, time in s)."""

    plan: str
    planner: str
    controller: str
    perfect: float = float("nan")
    sweep: float = float("nan")
    monte_carlo: float = float("nan")
    median_cp: float = float("nan")
    p95_cp: float = float("nan")
    mass_bench: tuple = (float("nan"), float("nan"))
    mass_model: tuple = (float("nan"), float("nan"))
    delay: tuple = (0.0, 0.0)
    seconds: float = 0.0
    note: str = ""
    replan: dict | None = None
    score: dict | None = None


def measure(problem, plan, name: str, args) -> Row:
    """All measurements of one plan with one controller."""
    from cpopt.tracking import Noise, Plant, track
    from cpopt.tracking.dfl import SingularTrackingError
    from cpopt.tracking.reference import reference
    from cpopt.tracking.robustness import (
        benchmark_plant,
        mass_margin,
        monte_carlo_parameters,
        run_trials,
        sweep_parameters,
    )
    from cpopt.tracking.run import make_controller

    if name == "flat_mpc":
        return measure_mpc(problem, plan, args)
    tic = time.perf_counter()
    row = Row(problem.name, plan.planner, name)
    ref = reference(plan, args.rate)
    plant, noise = benchmark_plant(ref, problem.spec.optimizer.limits.torque)
    try:  # tvlqr_timescaled fits its torques to the benchmark motors
        controller = make_controller(name, ref, torque_limit=plant.torque_limit)
    except SingularTrackingError as err:
        row.note = f"refused: {err}"
        return row
    row.perfect = track(None, controller).max_cp_error
    nominal = plant.parameters()
    sweep = run_trials(controller, sweep_parameters(nominal, 0.2, args.steps), noise)
    mc_rows = monte_carlo_parameters(nominal, args.trials, 0.1, args.seed)
    mc = run_trials(controller, mc_rows, Noise(noise.position, noise.velocity, args.seed))
    row.sweep, row.monte_carlo = sweep.rate, mc.rate
    row.median_cp = float(np.median(mc.final_cp_error))
    row.p95_cp = float(np.percentile(mc.final_cp_error, 95))
    if np.isfinite(mc.delay).any():
        row.delay = (float(np.nanmedian(mc.delay)), float(np.nanmax(mc.delay)))
    frictionless = Plant(plant.arm, torque_limit=plant.torque_limit).parameters()
    if not args.quick:
        row.mass_bench = mass_margin(controller, nominal, noise)
        row.mass_model = mass_margin(controller, frictionless, Noise())
    if args.score_values:
        from cpopt.tracking.scores import batch_judge, scores

        row.score = scores(batch_judge(controller), frictionless, ref.period, args.score_values)
    row.seconds = time.perf_counter() - tic
    return row


def measure_mpc(problem, plan, args) -> Row:
    """flat_mpc on the same plants as the other controllers (one run at a time), its re-plans'
    wall times and misses; no mass margins (each is some fifty runs of the loop)."""
    from cpopt.tracking import Noise, Plant
    from cpopt.tracking.mpc import FlatMPC, MPCSettings, replan_figures
    from cpopt.tracking.robustness import (
        benchmark_plant,
        monte_carlo_parameters,
        sweep_parameters,
    )
    from cpopt.tracking.scores import mpc_judge, mpc_trials, scores

    tic = time.perf_counter()
    row = Row(problem.name, plan.planner, "flat_mpc")
    if problem.planner != "optimize" or problem.spec.optimizer.curve == "path_timing":
        row.note = "refused: flat_mpc re-plans B-spline plans of planner: optimize"
        return row
    settings = MPCSettings(deadline=args.replan_deadline, method=args.replan_method)
    mpc = FlatMPC(problem, plan, args.rate, settings)
    plant, noise = benchmark_plant(mpc.reference, problem.spec.optimizer.limits.torque)
    mpc.torque_limit = plant.torque_limit
    perfect, runs = mpc_trials(mpc, Plant(plan.arm).parameters(), Noise())
    row.perfect = float(perfect.max_cp_error[0])
    nominal = plant.parameters()
    sweep, more = mpc_trials(mpc, sweep_parameters(nominal, 0.2, args.steps), noise)
    mc_rows = monte_carlo_parameters(nominal, args.trials, 0.1, args.seed)
    mc, mc_runs = mpc_trials(mpc, mc_rows, Noise(noise.position, noise.velocity, args.seed))
    row.sweep, row.monte_carlo = sweep.rate, mc.rate
    row.median_cp = float(np.median(mc.final_cp_error))
    row.p95_cp = float(np.percentile(mc.final_cp_error, 95))
    row.replan = replan_figures(runs + more + mc_runs)
    if args.score_values:
        frictionless = Plant(plant.arm, torque_limit=plant.torque_limit).parameters()
        row.score = scores(mpc_judge(mpc), frictionless, mpc.period, args.score_values)
    row.seconds = time.perf_counter() - tic
    return row


# --- Headroom: the plan re-solved with torque headroom, tracked with tvlqr -----------------

HEADROOM = 0.2
"""The headroom docs/benchmarks.md recommends (``--headroom``), "Headroom: room for feedback"."""
HEADROOM_CONTROLLER = "tvlqr"


@dataclass
class HeadroomRow:
    """One plan re-solved with headroom h: ratios to its h = 0 plan (objective, duration),
    tvlqr's success on the h = 0 plan's benchmark plant, time in s."""

    plan: str
    h: float
    cost: float = float("nan")
    duration: float = float("nan")
    sweep: float = float("nan")
    monte_carlo: float = float("nan")
    usage: tuple = (float("nan"), float("nan"))
    seconds: float = 0.0
    note: str = ""


def with_headroom(problem, controller, h: float):
    """The problem with headroom h on the benchmark's motors (its own torque limits, or the
    1.5 x peak motors of the plan the controller tracks), and the benchmark plant and noise."""
    from cpopt.tracking.robustness import benchmark_plant

    plant, noise = benchmark_plant(controller, problem.spec.optimizer.limits.torque)
    motors = [float(v) for v in plant.torque_limit]
    changed = problem.replace(
        **{"optimizer.limits.torque": motors, "optimizer.limits.torque_headroom": h}
    )
    return changed, plant, noise


def measure_headroom(problem, plan, objective: float, args) -> HeadroomRow:
    """The plan re-solved with headroom ``args.headroom``, measured against the h = 0 plan."""
    from cpopt.pipeline import solve
    from cpopt.problem import ProblemError
    from cpopt.tracking import Noise
    from cpopt.tracking.reference import reference
    from cpopt.tracking.robustness import monte_carlo_parameters, run_trials, sweep_parameters
    from cpopt.tracking.run import make_controller

    tic = time.perf_counter()
    row = HeadroomRow(problem.name, args.headroom)
    base = make_controller(HEADROOM_CONTROLLER, reference(plan, args.rate))
    try:
        changed, plant, noise = with_headroom(problem, base, args.headroom)
    except ProblemError as err:
        row.note = f"refused: {err.path}: {err.message}"
        return row
    usage = np.abs(base.reference.tau).max(axis=0) / np.asarray(plant.torque_limit)
    if np.all(usage <= 1 - args.headroom):
        # the h = 0 plan keeps the headroom already (as on 1.5 x peak motors with h <= 1/3):
        # optimal on the larger feasible set and feasible on the smaller, it is the plan
        row.cost, row.duration, row.usage, controller = 1.0, 1.0, tuple(usage), base
    else:
        solution = solve(changed)
        if not solution.ok:
            row.note = f"not solved with headroom ({solution.status})"
            return row
        row.cost = solution.solver.objective / objective
        row.duration = solution.plan.duration / plan.duration
        row.usage = tuple(solution.metrics.torque_usage)
        controller = make_controller(HEADROOM_CONTROLLER, reference(solution.plan, args.rate))
    nominal = plant.parameters()
    sweep = run_trials(controller, sweep_parameters(nominal, 0.2, args.steps), noise)
    mc_rows = monte_carlo_parameters(nominal, args.trials, 0.1, args.seed)
    mc = run_trials(controller, mc_rows, Noise(noise.position, noise.velocity, args.seed))
    row.sweep, row.monte_carlo = sweep.rate, mc.rate
    row.seconds = time.perf_counter() - tic
    return row


def headroom_applies(problem, args) -> bool:
    """Whether a plan gets a HEADROOM line: an optimized plan, and a headroom asked for."""
    return args.headroom > 0 and problem.planner != "closed_form"


def headroom_task(data: dict, source: str, plan, objective: float, args) -> HeadroomRow:
    """:func:`measure_headroom` in a worker, from the problem's data and its h = 0 plan."""
    from cpopt.problem import parse_problem

    return measure_headroom(parse_problem(data, source), plan, objective, args)


def format_headroom(r: HeadroomRow) -> str:
    """One headroom table line (a plan that could not be re-solved says why)."""
    head = f"{r.plan:24s} h={r.h:<5g}"
    if r.note:
        return f"{head} {r.note}"
    usage = "/".join(f"{u:.3f}" for u in r.usage)
    return (
        f"{head} cost x{r.cost:6.3f} duration x{r.duration:6.3f} peak/limit {usage:>11s} "
        f"sweep {r.sweep:6.3f} MC {r.monte_carlo:6.3f} {r.seconds:6.1f}"
    )


def headroom_line(r: HeadroomRow) -> str:
    """``HEADROOM <plan> h=<h> cost=<ratio> duration=<ratio> monte_carlo=<fraction>``."""
    return (
        f"HEADROOM {r.plan} h={r.h:g} cost={r.cost:.3f} duration={r.duration:.3f} "
        f"monte_carlo={r.monte_carlo:.3f}"
    )


# --- The table and the serial and distributed runs ---------------------------------------

HEADER = (
    f"{'plan':24s} {'planner':11s} {'ctrl':16s} {'perfect [m]':>11s} {'sweep':>6s} "
    f"{'MC':>6s} {'MC cp med':>9s} {'MC cp p95':>9s} {'mass+ bench/model':>17s} "
    f"{'mass- bench/model':>17s} {'MC delay med/max':>16s} {'time':>6s}"
)


def format_row(r: Row) -> str:
    """One table line (a refused controller says why)."""
    if r.note:
        return f"{r.plan:24s} {r.planner:11s} {r.controller:16s} {r.note}"
    heavier = f"{r.mass_bench[0]:.2f}/{r.mass_model[0]:.2f}"
    lighter = f"{r.mass_bench[1]:.2f}/{r.mass_model[1]:.2f}"
    delay = f"{r.delay[0]:.3f}/{r.delay[1]:.3f}"
    return (
        f"{r.plan:24s} {r.planner:11s} {r.controller:16s} {r.perfect:11.2e} {r.sweep:6.3f} "
        f"{r.monte_carlo:6.3f} {r.median_cp:9.2e} {r.p95_cp:9.2e} {heavier:>17s} "
        f"{lighter:>17s} {delay:>16s} {r.seconds:6.1f}"
    )


def _problems(selection: str | None):
    from cpopt.problem import bundled_problems, load_problem

    files = {p.stem: p for p in bundled_problems()}
    names = selection.split(",") if selection else list(files)
    unknown = [n for n in names if n not in files]
    if unknown:
        raise SystemExit(f"unknown plan(s) {unknown}; bundled: {', '.join(files)}")
    return [load_problem(files[n]) for n in names]


def run_serial(problems, args, start: float) -> list:
    """Each plan solved, then measured with each controller (then with headroom), in this
    process: its rows (:class:`Row`, :class:`HeadroomRow`)."""
    from cpopt.pipeline import solve

    rows: list[Row] = []
    try:
        for problem in problems:
            if args.time_limit and time.perf_counter() - start > args.time_limit:
                print(f"time limit reached: {problem.name} and later plans not run", flush=True)
                break
            solution = solve(problem)
            if not solution.ok:
                print(f"{problem.name}: not solved ({solution.status}), skipped", flush=True)
                continue
            for name in args.controllers:
                rows.append(measure(problem, solution.plan, name, args))
                print(format_row(rows[-1]), flush=True)
            if headroom_applies(problem, args):
                objective = solution.solver.objective
                rows.append(measure_headroom(problem, solution.plan, objective, args))
                print(format_headroom(rows[-1]), flush=True)
    except KeyboardInterrupt:
        print("interrupted: the results so far follow", flush=True)
    return rows


def solve_task(data: dict, source: str) -> tuple[str, object]:
    """The plan's solve in a worker, as in :func:`run_serial` (in the worker's own process, so
    that its warm caches serve the next plan): its status, its plan (or None) and objective."""
    from cpopt.pipeline import solve
    from cpopt.problem import parse_problem

    solution = solve(parse_problem(data, source))
    return solution.status, solution.plan if solution.ok else None, solution.solver.objective


def measure_task(data: dict, source: str, plan, name: str, args) -> Row:
    """:func:`measure` in a worker, from the problem's data and the plan."""
    from cpopt.problem import parse_problem

    return measure(parse_problem(data, source), plan, name, args)


def run_distributed(problems, args, start: float) -> list:
    """The same work as :func:`run_serial` as Dask tasks (see the module docstring); rows in
    the serial order, printed as they complete (headroom rows after the others)."""
    from dask.distributed import as_completed

    from cpopt.io.safe_yaml import read_yaml
    from cpopt.sweep.engine import connect

    data = {p.name: read_yaml(p.source) for p in problems}
    order = {
        (p.name, c): i
        for i, (p, c) in enumerate((p, c) for p in problems for c in args.controllers)
    }
    done: dict[int, Row] = {}
    headroom: dict[str, HeadroomRow] = {}
    with connect(args.workers, args.scheduler) as client:
        work, solving = as_completed(), {}
        for p in problems:
            future = client.submit(solve_task, data[p.name], p.source, pure=False)
            solving[future.key] = p
            work.add(future)
        try:
            for future in work:
                result = future.result()
                if isinstance(result, Row):
                    done[order[(result.plan, result.controller)]] = result
                    print(format_row(result), flush=True)
                    continue
                if isinstance(result, HeadroomRow):
                    headroom[result.plan] = result
                    print(format_headroom(result), flush=True)
                    continue
                problem, (status, plan, objective) = solving.pop(future.key), result
                if plan is None:
                    print(f"{problem.name}: not solved ({status}), skipped", flush=True)
                elif args.time_limit and time.perf_counter() - start > args.time_limit:
                    print(f"time limit reached: {problem.name} not measured", flush=True)
                else:
                    for name in args.controllers:
                        work.add(client.submit(measure_task, data[problem.name], problem.source,
                                               plan, name, args, pure=False))  # fmt: skip
                    if headroom_applies(problem, args):
                        work.add(client.submit(headroom_task, data[problem.name], problem.source,
                                               plan, objective, args, pure=False))  # fmt: skip
        except KeyboardInterrupt:
            print("interrupted: the results so far follow", flush=True)
    return [done[i] for i in sorted(done)] + [
        headroom[p.name] for p in problems if p.name in headroom
    ]


def main(argv=None) -> int:
    """Run the benchmark; returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plans", help="bundled plans to run, NAME,... (default: all)")
    parser.add_argument("--trials", type=int, default=100, help="Monte Carlo trials (100)")
    parser.add_argument("--steps", type=int, default=21, help="steps of each sweep (21)")
    parser.add_argument("--rate", type=float, default=1000.0, help="control rate [Hz] (1000)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the Monte Carlo plants")
    parser.add_argument("--time-limit", type=float, help="start no new plan after this [s]")
    parser.add_argument(
        "--quick", action="store_true", help=f"{QUICK_PLANS}, 5 trials, 3-step sweeps, no mass"
    )
    parser.add_argument(
        "--workers", type=int, help="run on a local Dask cluster of N single-threaded workers"
    )
    parser.add_argument("--scheduler", help="run on the Dask cluster at ADDRESS (tcp://host:8786)")
    parser.add_argument(
        "--headroom",
        type=float,
        default=HEADROOM,
        help=f"torque headroom h of the HEADROOM lines, 0 <= h < 1 ({HEADROOM}; 0: none)",
    )
    parser.add_argument(
        "--controllers",
        default=",".join(CONTROLLERS),
        help=f"controllers to run, NAME,... (default: {','.join(CONTROLLERS)})",
    )
    parser.add_argument(
        "--score-values",
        type=int,
        default=21,
        help="values per category of the SCORE lines (21; 0: no scores)",
    )
    parser.add_argument(
        "--replan-deadline",
        type=float,
        help="flat_mpc: wall time a re-plan may take [s] (default: its 20 ms period)",
    )
    parser.add_argument(
        "--replan-method",
        choices=("ipopt", "sqp"),
        default="ipopt",
        help="flat_mpc: the re-plans' solver (tracking.replan_method; default ipopt)",
    )
    args = parser.parse_args(argv)
    args.controllers = tuple(args.controllers.split(","))
    unknown = set(args.controllers) - set(CONTROLLERS)
    if unknown or not args.controllers:
        parser.error(f"--controllers: choose among {', '.join(CONTROLLERS)}")
    if not 0 <= args.headroom < 1:
        parser.error(f"--headroom {args.headroom:g}: give a fraction 0 <= h < 1")
    if args.quick:
        args.plans, args.trials, args.steps = args.plans or QUICK_PLANS, 5, 3
        args.score_values = min(args.score_values, 3)
    if args.workers is not None and (args.workers < 1 or args.scheduler):
        parser.error("--workers N (N >= 1) starts a local cluster; --scheduler uses a running one")
    start = time.perf_counter()
    problems = _problems(args.plans)
    distributed = args.workers is not None or args.scheduler is not None
    measured = (run_distributed if distributed else run_serial)(problems, args, start)
    rows = [r for r in measured if isinstance(r, Row)]
    headroom = [r for r in measured if isinstance(r, HeadroomRow)]
    print(f"\n{HEADER}")
    for r in rows:
        print(format_row(r))
    if headroom:
        print(
            f"\nheadroom: the plans with headroom, tracked with {HEADROOM_CONTROLLER} on the h = 0 "
            "plans' benchmark plants"
        )
        for r in headroom:
            print(format_headroom(r))
    print(
        f"\nsuccess: CP within 2 cm and theta within 5 deg of the goal when the reference "
        f"reaches it (T; later for tvlqr_timescaled), joint velocities "
        f"within 0.25 of the goal's, no divergence; {args.trials} Monte Carlo trials, "
        f"{args.steps}-step sweeps; {time.perf_counter() - start:.0f} s in all"
    )
    for r in rows:
        if r.controller == "flat_mpc" and r.note:  # a plan it cannot re-plan: the table says
            continue
        print(f"ROBUST {r.plan} {r.controller} sweep={r.sweep:.3f} monte_carlo={r.monte_carlo:.3f}")
    for r in rows:
        if r.replan is not None:
            f = r.replan
            print(
                f"REPLAN {r.plan} median_ms={f['median_ms']:.1f} p99_ms={f['p99_ms']:.1f} "
                f"misses={f['misses']:.3f} feasible={f['feasible']:.3f}"
            )
    from cpopt.tracking.scores import score_line

    for r in rows:
        if r.score is not None:
            print(score_line(r.plan, r.controller, r.score))
    for r in headroom:
        print(headroom_line(r))
    return 0


if __name__ == "__main__":
    sys.exit(main())
