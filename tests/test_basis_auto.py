"""``refine_basis: auto`` (the default): the basis of a plan far above its collocation seed is
refined, within a time budget; a plan near its seed, or a search without one, is left alone
(cpopt.flatopt.basis.wanted, seed_gap, auto_deadline)."""

import math
import time
from types import SimpleNamespace

import pytest
from conftest import PROBLEMS
from zoo_draws import RPR_TRANSFER_HANGING

import cpopt
from cpopt.flatopt.basis import AUTO_GAP, AUTO_MIN_TIME, auto_deadline, seed_gap, wanted


def searched(objective: float, seed: dict, status: str = "solved") -> SimpleNamespace:
    """What ``wanted`` and ``seed_gap`` read of a search: its best plan and its figures."""
    return SimpleNamespace(best=SimpleNamespace(status=status, objective=objective),
                           figures={"seed": seed})  # fmt: skip


def test_auto_refines_only_a_solved_bspline_plan_above_its_seed():
    seed = {"status": "solved", "objective": 100.0}
    assert seed_gap(searched(123.5, seed)) == pytest.approx(0.235, rel=1e-12)
    assert wanted("auto", "bspline", searched(100 * (1 + AUTO_GAP) + 0.01, seed))
    assert not wanted("auto", "bspline", searched(100 * (1 + AUTO_GAP) - 0.01, seed))
    assert not wanted("auto", "polynomial", searched(200.0, seed))
    assert not wanted("auto", "bspline", searched(200.0, seed, status="not_converged"))
    assert not wanted("auto", "bspline", searched(200.0, {}))  # no seeded search
    failed = {"status": "not_converged", "objective": 100.0}
    assert math.isnan(seed_gap(searched(200.0, failed)))
    assert not wanted("auto", "bspline", searched(200.0, failed))
    assert wanted(True, "bspline", searched(100.0, seed))  # true refines whatever the gap
    assert not wanted(False, "bspline", searched(200.0, seed))


def test_the_auto_budget_is_the_searchs_time_at_least_two_seconds_within_the_deadline():
    now = time.monotonic()
    assert auto_deadline(now, math.inf) == pytest.approx(now + AUTO_MIN_TIME, abs=0.05)
    assert auto_deadline(now - 5.0, math.inf) == pytest.approx(now + 5.0, abs=0.05)
    assert auto_deadline(now - 5.0, now + 1.0) == now + 1.0


def test_a_one_sign_plan_23_percent_above_its_seed_gets_a_finer_basis():
    """benchmarks/zoo.py --seed 31, draw 8: 301.96 with the drawn 14 coefficients a phase
    (refine_basis false), 249.94 by default (20, then 32 coefficients), within 2.2 % of its
    seed; the summary says why it was refined."""
    plain = cpopt.solve(cpopt.load(RPR_TRANSFER_HANGING, **{"optimizer.refine_basis": False}))
    refined = cpopt.solve(RPR_TRANSFER_HANGING)
    assert plain.status == refined.status == "solved"
    assert plain.solver.objective == pytest.approx(301.96, rel=2e-3)
    assert refined.solver.objective == pytest.approx(249.94, rel=2e-3)
    figures = refined.solver.details.search_figures
    assert "basis" not in plain.solver.details.search_figures
    assert [s["coefficients"] for s in figures["basis"]["steps"]] == [20, 32]
    assert figures["basis"]["seed_gap"] == pytest.approx(0.235, abs=0.005)
    assert refined.solver.objective < 1.025 * figures["seed"]["objective"]
    assert "basis: refined automatically, the plan 23." in refined.solver.details.search
    assert refined.verification.passed()


def test_a_plan_near_its_seed_keeps_its_basis():
    """transfer_switch (the bundled seeded search) ends within AUTO_GAP of its seed: no
    refinement, no ``basis`` figures."""
    solution = cpopt.solve(PROBLEMS / "transfer_switch.yaml")
    figures = solution.solver.details.search_figures
    assert solution.status == "solved"
    assert seed_gap(SimpleNamespace(best=solution.solver, figures=figures)) <= AUTO_GAP
    assert "basis" not in figures
    assert solution.problem.spec.optimizer.refine_basis == "auto"
