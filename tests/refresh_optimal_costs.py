"""Re-solve the bundled optimized problems and rewrite ``tests/optimal_costs.json``.

Run it deliberately, after a change that is meant to move an optimal cost:

    python tests/refresh_optimal_costs.py

It prints the old and the new value of every entry; commit the table with the change.
"""

import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
TABLE = HERE / "optimal_costs.json"
OPTIMIZED = (
    "transfer_min_torque",
    "swing_up_min_torque",
    "swing_up_torque_limited",
    "swing_up_min_time",
    "swing_up_free_via",
    "swing_up_one_phase",
    "transfer_straight_line",
    "transfer_min_time_on_path",
    "swing_up_path_timing",
    "swing_up_holding",
    "transfer_switch",
    "swing_up_switches",
)


def measure(solution) -> dict:
    """The regression figures of one solved problem."""
    return {
        "objective": solution.solver.objective,
        "torque_sq_integral": solution.metrics.torque_sq_integral,
        "duration_s": solution.plan.duration,
    }


def main() -> int:
    sys.path.insert(0, str(HERE.parent))
    from cpopt.pipeline import solve
    from cpopt.problem import load_problem

    old = json.loads(TABLE.read_text()) if TABLE.exists() else {}
    new = {}
    for name in OPTIMIZED:
        sol = solve(load_problem(HERE.parent / "problems" / f"{name}.yaml"))
        if sol.status != "solved":
            print(f"{name}: {sol.status} ({sol.message}); table not written")
            return 1
        new[name] = measure(sol)
        for key, value in new[name].items():
            before = old.get(name, {}).get(key)
            print(f"{name:26s} {key:20s} old {before!s:>22s}  new {value:.10g}")
    TABLE.write_text(json.dumps(new, indent=2) + "\n")
    print(f"wrote {TABLE}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
