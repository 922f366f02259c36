"""Shared fixtures: the paper's three case studies, planned once per test session."""

import os

os.environ.setdefault("MPLBACKEND", "Agg")
# One BLAS thread per process: the suite runs two workers on two cores, each starting child
# processes (the CLI's solver, notebook kernels); OpenBLAS's threads, spinning while they
# wait, then take the cores from each other (notebook 04 ran 114 s in the suite, 23 s alone).
# Set before NumPy or CasADi is imported; child processes inherit it.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

from pathlib import Path

import pytest

from cpopt.pipeline import solve
from cpopt.problem import load_problem

ROOT = Path(__file__).resolve().parent.parent
PROBLEMS = ROOT / "problems"
VERSIONS = (
    "casadi",
    "rockit-meco",
    "numpy",
    "scipy",
    "matplotlib",
    "PyYAML",
    "pydantic",
    "distributed",
    "pin",
    "mujoco",
)
"""The dependencies whose versions a run reports (CI installs the newest allowed ones)."""


def pytest_report_header(config):
    from importlib.metadata import PackageNotFoundError, version

    def said(name: str) -> str:
        try:
            return f"{name} {version(name)}"
        except PackageNotFoundError:
            return f"{name} (not installed)"

    return "cpopt dependencies: " + ", ".join(said(n) for n in VERSIONS)


@pytest.fixture(scope="session")
def paper_solutions():
    """Solutions of the three paper problems, keyed by file stem."""
    names = ("paper_transfer", "paper_transfer_slow", "paper_swing_up")
    return {n: solve(load_problem(PROBLEMS / f"{n}.yaml")) for n in names}


def forbid(monkeypatch, *targets: str) -> None:
    """Make each of ``targets`` (dotted names) fail the test when called: the work a refusal
    must come before (solving, starting a cluster)."""

    def refuse(*args, **kwargs):
        raise AssertionError("work started before the bad input was refused")

    for target in targets:
        monkeypatch.setattr(target, refuse)
