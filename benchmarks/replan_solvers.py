"""Solvers for a re-plan (issue 31): Ipopt warm started against a dense SQP, the same NLP.

A re-plan of ``--plan`` at ``--at`` seconds from the plan's own state, the compensator held
(:func:`cpopt.flatopt.replan.replan`, ``free_compensator=False``), solved three ways:

* ``ipopt``: the re-plan as :func:`cpopt.replan` solves it (the flat NLP with its lifted
  samples, Gauss-Newton Hessian, warm started from the plan refitted);
* ``ipopt_condensed``: the same NLP on its core variables alone (the lifted samples are
  functions of them, :attr:`FlatNLP.lift`): gradient, Jacobian and Hessian chained through
  the lift's Jacobian J, the Hessian J' H J (Gauss-Newton in the samples);
* ``sqp``: CasADi ``sqpmethod`` with the dense QP solver ``qrqp`` on the condensed NLP, the
  same J' H J Hessian, regularised where it is indefinite (the constraints' curvature).

It prints one line per solver and repetition:
``SOLVER <name> status=<...> iterations=<n> ms=<wall time> objective=<...>``.

Usage::

    python benchmarks/replan_solvers.py --plan transfer_min_torque --at 0.3
"""

from __future__ import annotations

import argparse
import sys
import time

import casadi as ca
import numpy as np

import cpopt
from cpopt.closedform.trajectory import sample, sample_at
from cpopt.flatopt import replan as rp
from cpopt.flatopt.remaining_motion import remaining
from cpopt.flatopt.transcribe import build, initial_grids
from cpopt.problem import bundled_problems


def condensed(nlp, keep: np.ndarray, p_size: int) -> tuple[dict, dict]:
    """The NLP on its core variables (``keep``: the rows that are not lifting rows): the
    problem dict and the derivative functions (Ipopt's triangular and a full Hessian)."""
    xc = ca.MX.sym("xc", nlp.layout.size)
    pp = ca.MX.sym("p", p_size)
    X = ca.vertcat(xc, nlp.lift(xc, pp))
    J = ca.jacobian(X, xc)
    f, grad = nlp.solver.get_function("nlp_grad_f")(X, pp)
    g, jac = nlp.solver.get_function("nlp_jac_g")(X, pp)
    rows = np.where(keep)[0].tolist()
    lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", len(rows))
    lam = ca.MX(keep.size, 1)
    lam[rows] = lam_g
    H = nlp.solver.get_function("nlp_hess_l")(X, pp, lam_f, lam)  # upper triangle
    H = H + H.T - ca.diag(ca.diag(H))
    Hc = ca.mtimes([J.T, H, J])
    io = ([xc, pp, lam_f, lam_g], ["x", "p", "lam_f", "lam_g"])
    functions = {
        "grad_f": ca.Function("grad_f", [xc, pp], [f, J.T @ grad], ["x", "p"], ["f", "grad"]),
        "jac_g": ca.Function(
            "jac_g", [xc, pp], [g[rows], jac[rows, :] @ J], ["x", "p"], ["g", "jac"]
        ),
        "jac_fg": ca.Function(
            "jac_fg",
            [xc, pp],
            [f, J.T @ grad, g[rows], jac[rows, :] @ J],
            ["x", "p"],
            ["f", "grad_f_x", "g", "jac_g_x"],
        ),
        "triu": ca.Function("hess_lag", *io[:1], [ca.triu(Hc)], io[1], ["triu_hess"]),
        "full": ca.Function("hess_lag", *io[:1], [Hc], io[1], ["hess"]),
    }
    F = ca.Function("F", [xc, pp], [f])
    G = ca.Function("G", [xc, pp], [g[rows]])
    return {"x": xc, "p": pp, "f": F(xc, pp), "g": G(xc, pp)}, functions


COMMON = {"no_nlp_grad": True, "expand": False, "calc_lam_p": False, "print_time": False}


def solvers(problem_dict: dict, functions: dict, sqp_iterations: int) -> dict:
    """The condensed NLP's Ipopt and SQP solvers."""
    ipopt = ca.nlpsol(
        "ipopt_condensed", "ipopt", problem_dict,
        {**COMMON, "grad_f": functions["grad_f"], "jac_g": functions["jac_g"],
         "hess_lag": functions["triu"],
         "ipopt": {**rp.SOLVER_SETTINGS, "mu_init": 1e-3, "sb": "yes", "max_iter": 100}},
    )  # fmt: skip
    sqp = ca.nlpsol(
        "sqp", "sqpmethod", problem_dict,
        {**COMMON, "jac_fg": functions["jac_fg"], "hess_lag": functions["full"],
         "qpsol": "qrqp", "convexify_strategy": "regularize", "max_iter": sqp_iterations,
         "qpsol_options": {"print_iter": False, "print_header": False,
                           "error_on_fail": False},
         "print_header": False, "print_iteration": False, "error_on_fail": False,
         "tol_pr": 1e-6, "tol_du": 1e-6},
    )  # fmt: skip
    return {"ipopt_condensed": ipopt, "sqp": sqp}


def main(argv=None) -> int:
    """Measure the three solvers on one re-plan; returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plan", default="transfer_min_torque", help="a bundled plan")
    parser.add_argument("--at", type=float, default=0.3, help="re-plan instant [s]")
    parser.add_argument("--repeat", type=int, default=3, help="solves per solver (3)")
    parser.add_argument("--sqp-iterations", type=int, default=10, help="SQP iterations (10)")
    parser.add_argument(
        "--solvers", default="ipopt_condensed,sqp", help="condensed solvers to run, NAME,..."
    )
    args = parser.parse_args(argv)
    files = {f.stem: f for f in bundled_problems()}
    solution = cpopt.solve(cpopt.load(files[args.plan]))
    seed = sample(solution.plan)
    now = sample_at(solution.plan, [args.at], seed)
    q, qd = now.q[0], now.qd[0]
    for _ in range(args.repeat):
        r = rp.replan(solution.problem, solution.plan, args.at, q, qd, seed=seed,
                     free_compensator=False)  # fmt: skip
        print(f"SOLVER ipopt status={r.message} iterations={r.iterations} "
              f"ms={1e3 * r.time_s:.1f} objective={r.objective:.6g}", flush=True)  # fmt: skip
    rest = remaining(solution.problem, solution.plan, args.at, q, qd, False)
    problem = rp.with_replan_settings(rest.problem)
    nlp = build(problem, rest.signs, initial_grids(problem), warm=True, gamma_grid=rp.GAMMA_GRID)
    p = nlp.parameters(problem.values)
    lbx, ubx = rp.variable_bounds(nlp, problem)
    x0 = rp.start_vector(nlp, problem, rest.signs, rp.shifted_seed(seed, args.at), p)
    keep = np.array([not name.startswith("lifted samples") for name, _ in nlp.rows])
    n = nlp.layout.size
    print(f"condensed: {n} variables, {keep.sum()} constraints (full: {x0.size}, {keep.size})")
    bounds = {"lbx": lbx[:n], "ubx": ubx[:n], "lbg": nlp.lbg[keep], "ubg": nlp.ubg[keep]}
    chosen = solvers(*condensed(nlp, keep, p.size), args.sqp_iterations)
    for name, solver in ((k, v) for k, v in chosen.items() if k in args.solvers.split(",")):
        for _ in range(args.repeat):
            tic = time.perf_counter()
            out = solver(x0=x0[:n], p=p, **bounds)
            ms = 1e3 * (time.perf_counter() - tic)
            stats = solver.stats()
            print(f"SOLVER {name} status={stats.get('return_status')} "
                  f"iterations={stats.get('iter_count')} ms={ms:.1f} "
                  f"objective={float(out['f']):.6g}", flush=True)  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
