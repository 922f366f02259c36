"""Re-plans in a loop (issue 31): wall time, Ipopt iterations and solved fraction per plan.

Along each ``--plans`` plan, every ``--period`` seconds, :func:`cpopt.flatopt.replan.replan`
re-plans from the newest plan's state perturbed by normal noise (``--dq`` [rad or m],
``--dqd`` [rad/s or m/s]), as :mod:`cpopt.tracking.mpc` does in its loop: the compensator
held, warm started from the newest plan, its samples and the newest solved re-plan's
multipliers. ``--rounds`` repeats the sweep with new noise; ``--method`` picks the re-plan's solver
(``ipopt``, the default, or ``sqp``) and ``--deadline`` its wall-time limit [s] (none by
default). It prints per plan (usable: solved, or the SQP's ``feasible`` iterate at its
deadline)::

    LOOP <plan> replans=<n> solved=<%> usable=<%> median_ms=<ms> p99_ms=<ms> cpu_median_ms=<ms>
         cpu_p99_ms=<ms> iterations=<median> statuses=<status:count,...>

(wall times, and this process's CPU times, which other processes on the machine do not
inflate).

With ``--profile FILE`` the first plan's loop runs under cProfile (stats written to FILE).

Usage::

    python benchmarks/replan_loop.py --plans transfer_min_torque,swing_up_holding
"""

from __future__ import annotations

import argparse
import cProfile
import math
import sys
import time
from collections import Counter

import numpy as np

import cpopt
from cpopt.closedform.trajectory import sample, sample_at
from cpopt.flatopt.replan import METHODS, Replan, replan
from cpopt.problem import bundled_problems


def sweep(
    solution,
    period: float,
    dq: float,
    dqd: float,
    rng,
    method: str = "ipopt",
    deadline: float = math.inf,
) -> list[tuple[Replan, float]]:
    """One sweep of re-plans every ``period`` [s] from the newest plan's perturbed states:
    each re-plan and the CPU time of this process it took [s] (unlike its wall time, not
    inflated by other processes on the machine: the figure to compare designs by)."""
    problem, plan = solution.problem, solution.plan
    newest, samples, warm = plan, sample(plan), None
    out = []
    for t in np.arange(period, plan.t0 + plan.duration, period):
        now = sample_at(newest, [t], samples)
        q = now.q[0] + rng.normal(0.0, dq, 3)
        qd = now.qd[0] + rng.normal(0.0, dqd, 3)
        tic = time.process_time()
        r = replan(problem, newest, float(t), q, qd, deadline, seed=samples, warm=warm,
                   free_compensator=False, method=method)  # fmt: skip
        if r.status == "holding":
            break
        out.append((r, time.process_time() - tic))
        if r.usable:
            newest, samples, warm = r.plan, r.samples, r.multipliers
    return out


def summary(name: str, timed: list[tuple[Replan, float]]) -> str:
    """The LOOP line of one plan's re-plans."""
    replans = [r for r, _ in timed]
    ms = 1e3 * np.array([r.time_s for r in replans])
    cpu = 1e3 * np.array([c for _, c in timed])
    solved = np.mean([r.solved for r in replans])
    usable = np.mean([r.usable for r in replans])
    iterations = np.median([r.iterations for r in replans])
    statuses = ",".join(f"{k}:{v}" for k, v in Counter(r.status for r in replans).items())
    return (
        f"LOOP {name} replans={len(replans)} solved={100 * solved:.1f}% "
        f"usable={100 * usable:.1f}% "
        f"median_ms={np.median(ms):.1f} p99_ms={np.percentile(ms, 99):.1f} "
        f"cpu_median_ms={np.median(cpu):.1f} cpu_p99_ms={np.percentile(cpu, 99):.1f} "
        f"iterations={iterations:.0f} statuses={statuses}"
    )


def main(argv=None) -> int:
    """Run the loops; returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plans", default="transfer_min_torque,swing_up_holding")
    parser.add_argument("--period", type=float, default=0.02, help="re-plan period [s]")
    parser.add_argument("--dq", type=float, default=0.002, help="position noise [rad or m]")
    parser.add_argument("--dqd", type=float, default=0.02, help="velocity noise [rad/s]")
    parser.add_argument("--rounds", type=int, default=3, help="sweeps per plan (3)")
    parser.add_argument("--seed", type=int, default=0, help="noise seed")
    parser.add_argument("--profile", default=None, help="cProfile the first plan to FILE")
    parser.add_argument("--method", choices=METHODS, default="ipopt", help="re-plan solver")
    parser.add_argument("--deadline", type=float, default=math.inf, help="per re-plan [s]")
    args = parser.parse_args(argv)
    files = {f.stem: f for f in bundled_problems()}
    for i, name in enumerate(args.plans.split(",")):
        solution = cpopt.solve(cpopt.load(files[name]))
        rng = np.random.default_rng(args.seed)
        sweep(
            solution, args.period, args.dq, args.dqd, rng, args.method, args.deadline
        )  # builds: untimed
        profiler = cProfile.Profile() if args.profile and i == 0 else None
        if profiler:
            profiler.enable()
        replans = [
            r for _ in range(args.rounds) for r in sweep(solution, args.period, args.dq,
                                                         args.dqd, rng, args.method,
                                                         args.deadline)
        ]  # fmt: skip
        if profiler:
            profiler.disable()
            profiler.dump_stats(args.profile)
        print(summary(name, replans), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
