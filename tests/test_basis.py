"""The plan's basis refined after the search (optimizer.refine_basis, cpopt.flatopt.basis)."""

import numpy as np
import pytest
from conftest import PROBLEMS

import cpopt
from cpopt.closedform.bspline import SplineBasis
from cpopt.flatopt.basis import GAIN, HALVINGS, finer


def test_a_finer_basis_halves_every_knot_interval():
    """14 coefficients of degree 8 (6 intervals) become 20 (12), 32 (24), 56 (48), then
    none (the schema's 60 is the most); the finer basis holds the coarser one's splines
    exactly (its breaks contain the coarser breaks)."""
    problem = cpopt.load(PROBLEMS / "transfer_min_torque.yaml", **{"optimizer.degree": 8})
    counts = []
    current = cpopt.load(PROBLEMS / "transfer_min_torque.yaml", **{"optimizer.coefficients": 14})
    while (current := finer(current)) is not None:
        counts.append(current.spec.optimizer.coefficients)
    assert counts == [20, 32, 56]
    coarse, fine = SplineBasis(8, 14), SplineBasis(8, 20)
    assert set(np.round(coarse.breaks, 12)) <= set(np.round(fine.breaks, 12))
    assert problem.spec.optimizer.refine_basis == "auto"  # refined only far above the seed


def test_refining_the_basis_lowers_the_cost_and_reports_each_step():
    """transfer_min_torque with refine_basis: each kept refinement lowered the cost by at least
    GAIN, the plan's phases are in the finer basis, and solver.search.basis lists the steps."""
    plain = cpopt.solve(PROBLEMS / "transfer_min_torque.yaml")
    problem = cpopt.load(PROBLEMS / "transfer_min_torque.yaml", **{"optimizer.refine_basis": True})
    refined = cpopt.solve(problem)
    assert plain.status == refined.status == "solved"
    basis = refined.solver.details.search_figures["basis"]
    steps = basis["steps"]
    assert 1 <= len(steps) <= HALVINGS
    assert steps[0]["coefficients"] == 2 * (14 - 8) + 8
    kept = [s for s in steps if s["status"] == "solved"]
    assert refined.solver.objective <= plain.solver.objective * (1 - GAIN) or not kept
    previous = plain.solver.objective
    for step in kept:
        if step["objective"] <= previous * (1 - GAIN):
            previous = step["objective"]
    assert refined.solver.objective == pytest.approx(previous, rel=1e-12)
    assert "basis:" in refined.solver.details.search
    assert refined.verification.passed()


def test_refine_basis_needs_a_bspline():
    with pytest.raises(cpopt.ProblemError) as caught:
        cpopt.load(
            PROBLEMS / "transfer_min_torque.yaml",
            **{"optimizer.refine_basis": True, "optimizer.curve": "polynomial"},
        )
    assert caught.value.path == "optimizer.refine_basis"
    assert "curve: bspline" in str(caught.value)
