"""A zoo of random problems: the flat optimizer's switch search judged on problems nobody tuned
it for (issue 30).

Each draw is a valid problem of one of the four arm kinds (link lengths and masses, duration,
start and goal poses hanging or inverted at rest, an optional via state at rest with the link
horizontal), minimum torque, ``gamma_min`` and ``smooth_torque`` drawn too, the compensator
values freed as the bundled files free them (xi and eta at the start, the goal and the via
state, eta after the via state). For each it solves

* ``collocation``: direct collocation of the full dynamics without the regularity constraint
  (``--intervals``, N = 200 by default): the unconstrained optimum, the reference of the ratios;
  a draw that collocation does not solve is redrawn (counted: ``redraws``);
* ``one_sign``: the flat optimizer with ``gamma_switches: 0`` (each allowed sign);
* ``auto``: the flat optimizer with ``gamma_switches: auto`` (the seeded switch search),

both through :func:`cpopt.solve` with ``--time-limit``, and prints a table row, then exactly::

    ZOO <name> ratio_auto=<x> ratio_one_sign=<x> auto_s=<s> status=<status>

(ratios: the torque integral on a fine grid over collocation's), and at the end::

    ZOO_SUMMARY count=<n> median=<x> p90=<x> worst=<x> auto_worse_than_one_sign=<n>
    tracebacks=<n> over_time=<n> median_s=<s> max_s=<s> redraws=<n>

(one line): the ratios of ``auto``, the problems where ``auto`` costs more than one sign (by
more than :data:`SAME` relative), the solves that raised, the solves that overran their time
limit by more than :data:`OVERRUN` s, ``auto``'s wall times.

Usage::

    pip install -e .
    python benchmarks/zoo.py --count 30 --seed 1
    python benchmarks/zoo.py --count 3 --seed 0 --intervals 60 --save /tmp/zoo   # quick
    python benchmarks/zoo.py --count 30 --seed 1 --refine-basis   # the same draws, finer bases
    python benchmarks/zoo.py --count 30 --seed 1 --refine-basis false   # the bases as drawn

The draws leave ``optimizer.refine_basis`` at the schema's default (``auto``: a plan more than
5 % above its collocation seed gets a finer basis) unless ``--refine-basis`` sets it.

``--save DIR`` writes each drawn problem (its ``auto`` version) as ``DIR/<name>.yaml``, so that
a bad case can be run alone with ``cpopt solve``.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
import traceback
from dataclasses import dataclass
from pathlib import Path

import numpy as np

FINE = 4001
"""Samples per phase of the fine grid on which flat costs are measured."""
SAME = 1e-3
"""Relative difference of two costs below which they count as the same plan's."""
OVERRUN = 1.0
"""Seconds a solve may run past its time limit before it counts as over time."""
MAX_REDRAWS = 20
"""Draws per problem before the zoo gives up on a slot."""
FREE_XI = [-40.0, 40.0]
FREE_ETA = [-200.0, 200.0]
"""The bounds the bundled files give free xi [m/s^2] and eta [m/s^3]."""


def _poses(rng: np.random.Generator, kind: str, links: list[dict], count: int) -> list:
    """``count`` positions (x, y) [m] of the third link's base well inside the arm's reach."""
    l1, l2 = links[0]["length"], links[1]["length"]
    out = []
    for _ in range(count):
        if kind == "RRR":
            lo, hi = abs(l1 - l2) + 0.15 * (l1 + l2), 0.85 * (l1 + l2)
            r, phi = rng.uniform(lo, hi), rng.uniform(-0.3, 0.5 * math.pi + 0.3)
        elif kind == "RPR":
            r, phi = rng.uniform(0.4, 1.6), rng.uniform(-0.3, 0.5 * math.pi + 0.3)
        elif kind == "PRR":
            out.append((rng.uniform(-0.5, 1.5), rng.uniform(-0.7, 0.7) * l2))
            continue
        else:
            out.append((rng.uniform(-0.5, 1.0), rng.uniform(-0.5, 1.0)))
            continue
        out.append((r * math.cos(phi), r * math.sin(phi)))
    return out


def _rest(xy, theta_deg: float) -> dict:
    return {"x": round(xy[0], 4), "y": round(xy[1], 4), "theta_deg": theta_deg, "xi": 0, "eta": 0}


def draw(rng: np.random.Generator, name: str) -> dict:
    """One random problem's data (the ``auto`` version)."""
    kind = str(rng.choice(["RRR", "RPR", "PRR", "PPR"]))
    links = [
        {"length": round(rng.uniform(0.6, 1.8), 3), "mass": round(rng.uniform(0.5, 10.0), 3)},
        {"length": round(rng.uniform(0.6, 1.8), 3), "mass": round(rng.uniform(0.5, 6.0), 3)},
        {"length": round(rng.uniform(0.4, 1.2), 3), "mass": round(rng.uniform(0.2, 2.0), 3)},
    ]
    arm = {"kind": kind, "base": [0.0, 0.0], "links": links}
    if kind == "RRR":
        arm["branch"] = str(rng.choice(["elbow_up", "elbow_down"]))
    elif kind == "PRR":
        arm["branch"] = "forward"
    motion_kind = str(rng.choice(["swing_up", "transfer", "transfer_hanging", "swing_down"]))
    theta0, theta1 = {
        "swing_up": (-90, 90),
        "transfer": (90, 90),
        "transfer_hanging": (-90, -90),
        "swing_down": (90, -90),
    }[motion_kind]
    start, goal, via_xy = _poses(rng, kind, links, 3)
    duration = round(rng.uniform(0.8, 2.5), 3)
    motion = {"duration": duration, "start": _rest(start, theta0), "goal": _rest(goal, theta1)}
    free = {"start.xi": FREE_XI, "start.eta": FREE_ETA, "goal.xi": FREE_XI, "goal.eta": FREE_ETA}
    if rng.uniform() < 0.35:
        t = round(rng.uniform(0.35, 0.65) * duration, 3)
        if theta0 == theta1:  # a transfer: a pinned via state, the link tilted at rest
            theta_via = theta0 + round(rng.uniform(-30, 30))
        elif rng.uniform() < 0.5:  # through the horizontal on the right
            theta_via = 0
        else:  # through the horizontal on the left: theta continuous, the goal a turn away
            theta_via = -180 if theta0 < 0 else 180
            motion["goal"]["theta_deg"] = theta1 - 360 if theta0 < 0 else theta1 + 360
        motion["via"] = [{"t": t, **_rest(via_xy, theta_via)}]
        free.update({"via[0].xi": FREE_XI, "via[0].eta": FREE_ETA, "via[0].eta_after": FREE_ETA})
    return {
        "name": name,
        "description": f"zoo: {kind} {motion_kind}" + (" via" if "via" in motion else ""),
        "arm": arm,
        "motion": motion,
        "planner": "optimize",
        "optimizer": {
            "curve": "bspline",
            "degree": 8,
            "coefficients": 14,
            "objective": "torque",
            "gamma_min": round(rng.uniform(1.0, 3.0), 2),
            "gamma_switches": "auto",
            "smooth_torque": bool(rng.uniform() < 0.5),
            "samples": 50,
            "free": free,
        },
    }


@dataclass
class Flat:
    """One flat solve through :func:`cpopt.solve`."""

    cost: float = math.nan
    wall: float = math.nan
    status: str = "not_run"
    pattern: str = ""
    search: str = ""
    stages: str = ""
    raised: bool = False


def _pattern(solution) -> str:
    details = solution.solver.details
    if details is None or not hasattr(details, "gamma_signs"):
        return ""
    signs = "/".join(s[:3] for s in details.gamma_signs)
    times = ",".join(f"{t:.3f}" for t in details.switch_times)
    return signs + (f"@{times}" if times else "")


def _stages(search: dict, stage_times: dict) -> str:
    """Where a solve's time went [s]: the search's stages, then sampling and verifying."""
    parts = [f"seed {search['seed']['time_s']:.2f}"] if "seed" in search else []
    for name in ("bound", "patterned", "flat", "near", "polish", "greedy"):
        if search.get(name, {}).get("patterns"):
            parts.append(f"{name} {search[name]['time_s']:.2f}")
    parts += [f"{k} {stage_times[k]:.2f}" for k in ("sample", "verify") if k in stage_times]
    return ", ".join(parts)


def run_flat(data: dict, switches, time_limit: float) -> Flat:
    """Solve ``data`` with ``gamma_switches`` set to ``switches``; never raises."""
    import cpopt
    from cpopt.closedform.trajectory import metrics, sample

    out = Flat()
    tic = time.perf_counter()
    try:
        problem = cpopt.load(data, **{"optimizer.gamma_switches": switches})
        solution = cpopt.solve(problem, time_limit=time_limit)
        out.wall = time.perf_counter() - tic
        out.status = solution.status
        out.pattern = _pattern(solution)
        search = getattr(solution.solver.details, "search_figures", {}) or {}
        out.search = search.get("summary", "")
        out.stages = _stages(search, solution.solver.stage_times)
        if solution.plan is not None and solution.status == "solved":
            out.cost = metrics(solution.plan, sample(solution.plan, FINE)).torque_sq_integral
    except Exception:  # a traceback on a valid problem: counted, printed
        out.wall = time.perf_counter() - tic
        out.raised, out.status = True, "traceback"
        traceback.print_exc()
    return out


def _collocation_cost(data: dict, intervals: int) -> float | None:
    """The unconstrained collocation optimum's torque integral, or None when it fails (run in
    a worker process, :func:`run_collocation`)."""
    import cpopt
    from cpopt.collocation import collocate, joint_metrics, joint_trajectory
    from cpopt.problem import ProblemError

    try:
        problem = cpopt.load(data)
        result = collocate(problem, intervals, gamma_constraint=False)
    except ProblemError:
        return None
    if result.status != "solved":
        return None
    return joint_metrics(result.plan, joint_trajectory(result.plan)).torque_sq_integral


COLLOCATIONS_PER_WORKER = 4
"""Collocation references a worker process solves before a fresh one takes over: rockit keeps
every transcription's state in the process, and one process grew to 12 GB by the 27th draw,
where one transcription then took minutes."""


def run_collocation(data: dict, intervals: int, pool=None) -> float | None:
    """:func:`_collocation_cost` in ``pool``'s worker (in this process without one)."""
    if pool is None:
        return _collocation_cost(data, intervals)
    return pool.submit(_collocation_cost, data, intervals).result()


def collocation_pool():
    """A one-worker process pool renewed every :data:`COLLOCATIONS_PER_WORKER` tasks (this
    file's folder on the path it inherits: a worker imports this module by name)."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    here = str(Path(__file__).resolve().parent)
    if here not in sys.path:
        sys.path.insert(0, here)

    context = multiprocessing.get_context("spawn")
    return ProcessPoolExecutor(1, context, max_tasks_per_child=COLLOCATIONS_PER_WORKER)


@dataclass
class Row:
    """One problem of the zoo: its unconstrained collocation cost and both flat solves."""

    name: str
    description: str
    collocation: float
    one_sign: Flat
    auto: Flat

    @property
    def ratio_auto(self) -> float:
        return self.auto.cost / self.collocation

    @property
    def ratio_one_sign(self) -> float:
        return self.one_sign.cost / self.collocation

    @property
    def auto_worse(self) -> bool:
        """``auto`` costs more than the one-sign plan (or failed where it solved)."""
        if not math.isfinite(self.one_sign.cost):
            return False
        return not self.auto.cost <= self.one_sign.cost * (1 + SAME)


def _valid(data: dict) -> bool:
    """True when the file format takes the drawn data."""
    import cpopt
    from cpopt.problem import ProblemError

    try:
        cpopt.load(data)
    except ProblemError:
        return False
    return True


def zoo(
    count: int,
    seed: int,
    intervals: int,
    time_limit: float,
    save: Path | None,
    refine_basis: bool | str | None = None,
):
    """Draw and run ``count`` problems (with ``optimizer.refine_basis`` set to
    ``refine_basis``, the schema's default when None); yields each Row, then the redraw
    count."""
    rng = np.random.default_rng(seed)
    redraws = 0
    pool = collocation_pool()
    for i in range(count):
        for _ in range(MAX_REDRAWS):
            data = draw(rng, f"zoo{seed}_{i:02d}")
            if refine_basis is not None:
                data["optimizer"]["refine_basis"] = refine_basis
            collocation = run_collocation(data, intervals, pool) if _valid(data) else None
            if collocation is not None and collocation > 0:
                break
            redraws += 1
        else:
            continue
        if save is not None:
            import yaml

            save.mkdir(parents=True, exist_ok=True)
            (save / f"{data['name']}.yaml").write_text(yaml.safe_dump(data, sort_keys=False))
        one = run_flat(data, 0, time_limit)
        auto = run_flat(data, "auto", time_limit)
        yield Row(data["name"], data["description"], collocation, one, auto)
    pool.shutdown()
    yield redraws


def _g(x: float) -> str:
    return f"{x:.4g}" if math.isfinite(x) else "inf"


def summary(rows: list[Row], redraws: int, time_limit: float) -> str:
    """The ZOO_SUMMARY line."""
    ratios = sorted(r.ratio_auto if math.isfinite(r.ratio_auto) else math.inf for r in rows)
    walls = [r.auto.wall for r in rows]
    flats = [f for r in rows for f in (r.one_sign, r.auto)]
    p90 = ratios[min(len(ratios) - 1, math.ceil(0.9 * len(ratios)) - 1)] if ratios else math.nan
    return (
        f"ZOO_SUMMARY count={len(rows)} "
        f"median={_g(statistics.median(ratios) if ratios else math.nan)} p90={_g(p90)} "
        f"worst={_g(ratios[-1] if ratios else math.nan)} "
        f"auto_worse_than_one_sign={sum(r.auto_worse for r in rows)} "
        f"tracebacks={sum(f.raised for f in flats)} "
        f"over_time={sum(f.wall > time_limit + OVERRUN for f in flats)} "
        f"median_s={statistics.median(walls) if walls else math.nan:.2f} "
        f"max_s={max(walls, default=math.nan):.2f} redraws={redraws}"
    )


def report(r: Row) -> None:
    """Print a problem's table row (costs, times [s], the pattern, the search's summary and
    where its time went) and its ZOO line."""
    print(
        f"{r.name:10s} {r.description[5:]:26s} {r.collocation:10.5g} "
        f"{r.one_sign.cost:10.5g} {r.one_sign.wall:5.1f} {r.auto.cost:10.5g} "
        f"{r.auto.wall:5.1f} {r.auto.status:10s} {r.auto.pattern} / {r.auto.search}"
        f" / time: {r.auto.stages}"
    )
    print(
        f"ZOO {r.name} ratio_auto={_g(r.ratio_auto)} ratio_one_sign={_g(r.ratio_one_sign)} "
        f"auto_s={r.auto.wall:.2f} status={r.auto.status}",
        flush=True,
    )


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--count", type=int, default=30, help="problems in the zoo")
    parser.add_argument("--seed", type=int, default=1, help="the random generator's seed")
    parser.add_argument("--intervals", type=int, default=200, help="collocation intervals N")
    parser.add_argument("--time-limit", type=float, default=20.0, help="per flat solve [s]")
    parser.add_argument("--save", type=Path, help="write the drawn problems here")
    parser.add_argument(
        "--refine-basis",
        nargs="?",
        const="true",
        choices=("auto", "true", "false"),
        help="set optimizer.refine_basis in every draw (alone: true; default: the schema's, "
        "auto; the same draws: the flag draws nothing)",
    )
    args = parser.parse_args(argv)
    rows: list[Row] = []
    redraws = 0
    print(
        f"{'name':10s} {'problem':26s} {'colloc':>10s} {'one_sign':>10s} {'s':>5s} "
        f"{'auto':>10s} {'s':>5s} {'status':10s} pattern (auto) / search"
    )
    refine = {"true": True, "false": False}.get(args.refine_basis, args.refine_basis)
    runs = zoo(args.count, args.seed, args.intervals, args.time_limit, args.save, refine)
    for item in runs:
        if isinstance(item, int):
            redraws = item
            break
        rows.append(item)
        report(item)
    print(summary(rows, redraws, args.time_limit))
    return 0


if __name__ == "__main__":
    sys.exit(main())
