"""Where a zoo problem's gap to unconstrained collocation comes from (issue 30): the search, the
regularity margin, or the flat plan's basis.

For each problem file (``benchmarks/zoo.py --save DIR`` writes them) it solves the flat
optimizer's ``auto`` search and then, on the same problem,

* ``pattern``: Hermite-Simpson collocation (``--intervals``, N = 200 by default) with the flat
  plan's pattern of signs of gamma imposed (``sign * gamma >= gamma_min`` on every piece, the
  torque free to step at a switch, as the flat plan's xi reset): what the flat plan's pattern
  costs without the flat basis;
* ``unconstrained``: the same collocation without the regularity constraint;
* ``c<n>``: the flat ``auto`` search with ``optimizer.coefficients`` raised to each of
  ``--coefficients``.

and prints one line per problem::

    GAP <name> flat=<x> pattern=<x> unconstrained=<x> c<n>=<x> ... pattern_signs=<signs@times>

(torque integrals: the flat plans' on a fine grid, collocation's on its own). flat / pattern
far above 1 with pattern / unconstrained near 1 says the basis, not the margin or the search,
holds the plan back; c<n> then shows how much a larger basis recovers.

Usage::

    python benchmarks/zoo.py --count 30 --seed 1 --save /tmp/zoo
    python benchmarks/zoo_gap.py /tmp/zoo/zoo1_16.yaml /tmp/zoo/zoo1_24.yaml --coefficients 20 28
"""

from __future__ import annotations

import argparse
import math
import sys

import yaml

SIGNS = {"positive": 1, "negative": -1}
FINE = 4001
"""Samples per phase of the fine grid on which flat costs are measured."""


def flat_cost(data: dict, time_limit: float, coefficients: int | None = None):
    """(torque integral or NaN, the solution) of the ``auto`` search on ``data``."""
    import cpopt
    from cpopt.closedform.trajectory import metrics, sample

    overrides = {} if coefficients is None else {"optimizer.coefficients": coefficients}
    solution = cpopt.solve(cpopt.load(data, **overrides), time_limit=time_limit)
    if solution.status != "solved":
        return math.nan, solution
    return metrics(solution.plan, sample(solution.plan, FINE)).torque_sq_integral, solution


def collocation_cost(data: dict, intervals: int, pattern) -> float:
    """Hermite-Simpson collocation's torque integral with ``pattern`` (switch times [s], signs)
    imposed, or without the regularity constraint when it is None; NaN when it fails."""
    import cpopt
    from cpopt.collocation import joint_metrics, joint_trajectory
    from cpopt.collocation.hermite_simpson import hermite_simpson
    from cpopt.flatopt.seed import coarse_seed

    problem = cpopt.load(data)
    seed = coarse_seed(problem)
    try:
        status, plan, _ = hermite_simpson(problem, intervals, pattern, seed.trajectory, 1000)
    except (RuntimeError, ValueError, ArithmeticError):  # CasADi's errors are these
        return math.nan
    if status != "solved":
        return math.nan
    return joint_metrics(plan, joint_trajectory(plan)).torque_sq_integral


def gap_line(data: dict, intervals: int, coefficients: list[int], time_limit: float) -> str:
    """The GAP line of one problem."""
    flat, solution = flat_cost(data, time_limit)
    details = solution.solver.details
    signs = tuple(SIGNS[w] for w in details.gamma_signs)
    pattern = (tuple(details.switch_times), signs)
    shown = "/".join(w[:3] for w in details.gamma_signs)
    shown += "@" + ",".join(f"{t:.3f}" for t in details.switch_times)
    parts = [
        f"flat={flat:.6g}",
        f"pattern={collocation_cost(data, intervals, pattern):.6g}",
        f"unconstrained={collocation_cost(data, intervals, None):.6g}",
    ]
    parts += [f"c{n}={flat_cost(data, time_limit, n)[0]:.6g}" for n in coefficients]
    return f"GAP {data['name']} " + " ".join(parts) + f" pattern_signs={shown}"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("files", nargs="+", help="problem files (zoo.py --save)")
    parser.add_argument("--intervals", type=int, default=200, help="collocation intervals N")
    parser.add_argument(
        "--coefficients", type=int, nargs="*", default=[28], help="larger bases to try"
    )
    parser.add_argument("--time-limit", type=float, default=120.0, help="per flat solve [s]")
    args = parser.parse_args(argv)
    for path in args.files:
        with open(path) as handle:
            data = yaml.safe_load(handle)
        print(gap_line(data, args.intervals, args.coefficients, args.time_limit), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
