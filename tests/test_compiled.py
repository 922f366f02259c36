"""Compiled CasADi libraries cached on disk, and the flat optimizer's per-sample library."""

import logging
import multiprocessing
import os
import signal
import time
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from cpopt.closedform.plan import closed_form
from cpopt.closedform.trajectory import sample
from cpopt.flatopt.samples import (
    ARM_PARAMETERS,
    ParametricArm,
    arm_vector,
    sample_library,
    sample_outputs,
    sample_values,
)
from cpopt.problem import load_problem
from cpopt.runtime import compiled

PROBLEMS = Path(__file__).resolve().parent.parent / "problems"


def _tiny() -> list[ca.Function]:
    x = ca.SX.sym("x", 2)
    return [ca.Function("tiny", [x], [ca.sin(x[0]) * x[1] ** 2])]


def _refuse() -> list[ca.Function]:
    raise AssertionError("the cached library must be found without generating code")


def _build_in_process(args) -> str:
    directory, source = args
    lib = compiled.load_library("tiny", [Path(source)], _tiny, Path(directory))
    return str(lib.path)


def test_library_is_compiled_once_and_found_by_its_source_key(tmp_path):
    source = tmp_path / "generator.py"
    source.write_text("version 1")
    lib = compiled.load_library("tiny", [source], _tiny, tmp_path)
    assert lib.compiled and lib.path.exists() and lib.path.parent == tmp_path
    assert float(lib.functions["tiny"]([0.5, 3.0])) == pytest.approx(np.sin(0.5) * 9.0, abs=1e-15)
    again = compiled.load_library("tiny", [source], _refuse, tmp_path)
    assert again.path == lib.path
    source.write_text("version 2")  # another generator: a new key, the same code, no recompile
    third = compiled.load_library("tiny", [source], _tiny, tmp_path)
    assert third.path == lib.path
    assert len(list(tmp_path.glob("tiny-*.json"))) == 2


def test_two_processes_may_build_the_same_library_at_once(tmp_path):
    source = tmp_path / "generator.py"
    source.write_text("same")
    with multiprocessing.get_context("spawn").Pool(2) as pool:
        paths = pool.map(_build_in_process, [(str(tmp_path), str(source))] * 2)
    assert paths[0] == paths[1]
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary left
    lib = compiled.load_library("tiny", [source], _refuse, tmp_path)
    assert float(lib.functions["tiny"]([0.5, 3.0])) == pytest.approx(np.sin(0.5) * 9.0)


class _Stop(BaseException):
    """Stands for a time limit or a Ctrl-C arriving while the compiler runs."""


@pytest.mark.skipif(os.name != "posix", reason="the detached compile is POSIX's")
def test_a_compile_cut_short_still_fills_the_cache(tmp_path, monkeypatch):
    """A solve stopped while the compiler runs (here 0.3 s into a compile that takes more
    than 1 s) leaves the compile to finish: the library and its index appear within seconds,
    and the next load uses them without generating code or compiling again (the compiler is
    then one that cannot work)."""
    slow = tmp_path / "slow-cc"
    slow.write_text(f'#!/bin/sh\nsleep 1\nexec {compiled.compiler()} "$@"\n')
    slow.chmod(0o755)
    monkeypatch.setenv("CC", str(slow))
    source = tmp_path / "generator.py"
    source.write_text("v")

    def stop(signum, frame):
        raise _Stop

    previous = signal.signal(signal.SIGALRM, stop)
    signal.setitimer(signal.ITIMER_REAL, 0.3)
    try:
        with pytest.raises(_Stop):
            compiled.load_library("tiny", [source], _tiny, tmp_path)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    deadline = time.monotonic() + 20
    while not list(tmp_path.glob("tiny-*.json")) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert len(list(tmp_path.glob("tiny-casadi*"))) == 1
    monkeypatch.setenv("CC", "false")  # found on the PATH, and fails whatever it is given
    lib = compiled.load_library("tiny", [source], _refuse, tmp_path)  # the index is there
    assert lib.compiled
    assert float(lib.functions["tiny"]([0.5, 3.0])) == pytest.approx(np.sin(0.5) * 9.0)
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".build-")]


def test_a_failed_compile_runs_interpreted_and_says_why(tmp_path, monkeypatch, caplog):
    broken = tmp_path / "broken-cc"
    broken.write_text('#!/bin/sh\necho "no such header" >&2\nexit 1\n')
    broken.chmod(0o755)
    monkeypatch.setenv("CC", str(broken))
    source = tmp_path / "generator.py"
    source.write_text("v")
    with caplog.at_level(logging.WARNING, logger="cpopt"):
        lib = compiled.load_library("tiny", [source], _tiny, tmp_path)
    assert not lib.compiled
    assert float(lib.functions["tiny"]([0.5, 3.0])) == pytest.approx(np.sin(0.5) * 9.0)
    assert "no such header" in caplog.records[-1].getMessage()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".build-")]


def test_without_a_compiler_the_functions_run_interpreted_and_say_so(tmp_path, monkeypatch, caplog):
    monkeypatch.setenv("CC", "no-such-compiler-for-cpopt")
    source = tmp_path / "generator.py"
    source.write_text("v")
    with caplog.at_level(logging.WARNING, logger="cpopt"):
        lib = compiled.load_library("tiny", [source], _tiny, tmp_path)
    assert not lib.compiled and lib.path is None
    assert float(lib.functions["tiny"]([0.5, 3.0])) == pytest.approx(np.sin(0.5) * 9.0)
    messages = [r.getMessage() for r in caplog.records]
    assert len(messages) == 1 and "interpreted" in messages[0] and "\n" not in messages[0]


def test_cache_folder_follows_xdg_cache_home(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert compiled.cache_dir() == tmp_path / "cpopt"
    monkeypatch.delenv("XDG_CACHE_HOME")
    assert compiled.cache_dir() == Path.home() / ".cache" / "cpopt"


@pytest.mark.parametrize("name", ["paper_transfer", "rpr_transfer", "prr_swing_up", "ppr_transfer"])
def test_sample_outputs_with_parametric_arm_match_the_numeric_chain(name):
    """The per-sample chain with the arm's parameters as inputs gives the torques, joint
    velocities and positions of trajectory.sample (flat inverse map, IK, inverse dynamics)."""
    problem = load_problem(PROBLEMS / f"{name}.yaml")
    plan = closed_form(problem.arm, problem.nodes)
    traj = sample(plan, per_phase=41)
    P = ca.SX.sym("P", 2, 5)
    sigma = ca.SX.sym("sigma")
    values = ca.SX.sym("arm", len(ARM_PARAMETERS))
    f = ca.Function(
        "f", [P, sigma, values], [sample_outputs(ParametricArm(problem.arm.kind, values), P, sigma)]
    )
    sig = np.array([plan.phases[k].sigma for k in traj.phase], float)
    n = traj.t.size
    y = np.asarray(
        f.map(n)(
            traj.cp.transpose(1, 0, 2).reshape(2, 5 * n), sig[None, :], arm_vector(problem.arm)
        )
    ).T
    assert np.abs(y[:, :2] - traj.tau).max() < 1e-8 * max(1.0, np.abs(traj.tau).max())
    assert np.abs(y[:, 5:8] - traj.qd).max() < 1e-9
    wrapped = np.angle(np.exp(1j * (y[:, 2:5] - traj.q)))
    revolute = np.array(problem.arm.revolute)
    assert np.abs(np.where(revolute, wrapped, y[:, 2:5] - traj.q)).max() < 1e-9
    assert np.all(y[:, 8] > 0)  # inside the reach


def test_compiled_sample_library_matches_its_symbolic_functions():
    problem = load_problem(PROBLEMS / "paper_transfer.yaml")
    plan = closed_form(problem.arm, problem.nodes)
    traj = sample(plan, per_phase=11)
    lib = sample_library("RRR")
    y = sample_values(problem.arm, traj.cp, plan.phases[0].sigma)
    assert np.abs(y[:, :2] - traj.tau).max() < 1e-8 * np.abs(traj.tau).max()
    P, av = traj.cp[3], arm_vector(problem.arm)
    f = lib.functions
    mu, W = np.linspace(-1, 1, 9), np.diag(np.linspace(1, 2, 9))

    def grad(v):  # J' mu: its Jacobian is the curvature sum_i mu_i hess y_i
        _, J = f["sample_jac"](v.reshape(2, 5, order="F"), 1.0, av)
        return np.asarray(J).T @ mu

    v = P.ravel(order="F")
    eps = 1e-6
    fd = np.column_stack([(grad(v + eps * e) - grad(v - eps * e)) / (2 * eps) for e in np.eye(10)])
    curvature = np.asarray(f["sample_hess"](P, 1.0, av, mu, np.zeros((9, 9))))
    assert np.allclose(curvature, np.triu(fd), rtol=1e-5, atol=1e-6 * np.abs(fd).max())
    J = np.asarray(f["sample_jac"](P, 1.0, av)[1])
    gauss_newton = np.triu(J.T @ W @ J)
    assert np.allclose(np.asarray(f["sample_gn"](P, 1.0, av, W)), gauss_newton, rtol=1e-12)
    both = np.asarray(f["sample_hess"](P, 1.0, av, mu, W))
    assert np.allclose(both, curvature + gauss_newton, rtol=1e-12, atol=1e-9)
