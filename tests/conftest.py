"""Shared fixtures: the paper's three case studies, planned once per test session."""

import os

os.environ.setdefault("MPLBACKEND", "Agg")

from pathlib import Path

import pytest

from cpopt.pipeline import solve
from cpopt.problem import load_problem

ROOT = Path(__file__).resolve().parent.parent
PROBLEMS = ROOT / "problems"


@pytest.fixture(scope="session")
def paper_solutions():
    """Solutions of the three paper problems, keyed by file stem."""
    names = ("paper_transfer", "paper_transfer_slow", "paper_swing_up")
    return {n: solve(load_problem(PROBLEMS / f"{n}.yaml")) for n in names}
