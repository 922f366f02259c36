"""The verification's errors and time for every bundled problem, one line each.

Each problem is solved as ``cpopt solve`` does (in this process), then its plan is verified
again and timed (the simulations' functions already built, as in a sweep's worker)::

    VERIFY <name> time=<s> reduced_cp=<m> closed_loop_cp=<m> closed_loop_final=<max abs>
        open_loop_final=<max abs>

(one line each). ``reduced_cp`` is the reduced model's largest CP error, ``closed_loop_cp``
the full arm's under dynamic feedback linearisation, ``*_final`` the largest final-state error
(x, y, theta and their rates; m, rad, m/s, rad/s).

Usage::

    python benchmarks/verification_errors.py [--problems a,b,...]
"""

from __future__ import annotations

import argparse
import time


def main(argv=None) -> int:
    """Print one ``VERIFY`` line per bundled problem (or per name given)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problems", default="", help="comma-separated names (default: all)")
    args = parser.parse_args(argv)

    from cpopt.pipeline import solve
    from cpopt.problem import bundled_problems, load_problem
    from cpopt.verify.simulate import verify

    wanted = set(filter(None, args.problems.split(",")))
    for path in bundled_problems():
        if wanted and path.stem not in wanted:
            continue
        plan = solve(load_problem(path)).plan
        tic = time.perf_counter()
        v = verify(plan, 0.0)
        elapsed = time.perf_counter() - tic
        if not hasattr(v, "reduced"):
            print(f"VERIFY {path.stem} time={elapsed:.3f} diverged={v.mode}", flush=True)
            continue
        print(
            f"VERIFY {path.stem} time={elapsed:.3f} reduced_cp={v.reduced.max_cp_error:.2g} "
            f"closed_loop_cp={v.closed_loop.max_cp_error:.2g} "
            f"closed_loop_final={v.closed_loop.final_state_error:.2g} "
            f"open_loop_final={v.open_loop.final_state_error:.2g}",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
