"""The ``cpopt`` command line: argument parsing and exit codes, nothing else.

Exit codes: 0 every problem solved; 1 a solve failed (its status is still written);
2 bad input (a file that does not validate, or wrong arguments). Bad input wins over a failure.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # argparse exits with 2 too; keep its usage line
        self.print_usage(sys.stderr)
        self.exit(EXIT_BAD_INPUT, f"cpopt: error: {message}\n")


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="cpopt",
        description=(
            "Plan and optimize motions of three-link planar arms with a passive third joint under "
            "gravity (De Luca & Oriolo's centre-of-percussion flat outputs)."
        ),
    )
    from . import __version__

    parser.add_argument("--version", action="version", version=f"cpopt {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    solve = sub.add_parser("solve", help="solve problem files and write their results")
    solve.add_argument("files", nargs="+", metavar="FILE", help="YAML problem files")
    solve.add_argument(
        "--out", default="out", metavar="DIR", help="results go to DIR/<name>/ (default: out)"
    )
    solve.add_argument("--plot", action="store_true", help="also write PNG figures")
    solve.add_argument("--animate", action="store_true", help="also write arm.gif")
    solve.add_argument("--verbose", action="store_true", help="show Ipopt's iterations")
    check = sub.add_parser("check", help="validate problem files without solving")
    check.add_argument("files", nargs="+", metavar="FILE")
    sub.add_parser("list", help="show the bundled problems")
    return parser


def _load(path: str):
    from .problem import ProblemError, load_problem

    try:
        return load_problem(path), None
    except ProblemError as err:
        return None, str(err)


def _cmd_check(files) -> int:
    code = EXIT_OK
    for path in files:
        problem, error = _load(path)
        if error:
            print(f"error: {error}", file=sys.stderr)
            code = EXIT_BAD_INPUT
        else:
            print(
                f"ok: {path} ({problem.name}: {problem.arm.kind} arm, "
                f"{len(problem.nodes) - 1} phase(s), planner {problem.planner})"
            )
    return code


def _summary(solution, outdir: Path) -> str:
    line = f"{solution.name}: {solution.status:<9s} {solution.planner:<11s}"
    if solution.metrics is not None:
        m = solution.metrics
        line += (
            f" T={solution.plan.duration:.3g} s  torque_sq_integral={m.torque_sq_integral:.6g}"
            f"  min|gamma|={m.min_abs_gamma:.4g}  max_torque_jump={m.max_torque_jump:.4g}"
        )
    if solution.verification is not None:
        line += f"  max_cp_error={solution.verification.max_cp_error:.2g} m"
    if solution.solver.iterations:
        line += f"  iterations={solution.solver.iterations}"
    if not solution.ok and solution.message:
        line += f"\n    {solution.message}"
    return line + f"  -> {outdir}/"


def _cmd_solve(args) -> int:
    import matplotlib

    matplotlib.use("Agg")
    from .pipeline import solve
    from .results import write_solution

    code = EXIT_OK
    for path in args.files:
        problem, error = _load(path)
        if error:
            print(f"error: {error}", file=sys.stderr)
            code = EXIT_BAD_INPUT
            continue
        if args.verbose:
            problem = problem.with_print_level(5)
        solution = solve(problem)
        outdir = Path(args.out) / problem.name
        write_solution(solution, outdir)
        if solution.ok and (args.plot or args.animate):
            from .plotting import animate, write_figures

            if args.plot:
                write_figures(solution, outdir)
            if args.animate:
                animate(solution, outdir / "arm.gif")
        print(_summary(solution, outdir), flush=True)
        if not solution.ok and code == EXIT_OK:
            code = EXIT_FAILED
    return code


def _cmd_list() -> int:
    from .problem import ProblemError, bundled_problems, load_problem

    for path in bundled_problems():
        try:
            p = load_problem(path)
            about = (p.spec.description or "").strip().splitlines()
            print(f"{path.name:34s} {p.arm.kind}  {p.planner:<11s} {about[0] if about else ''}")
        except ProblemError as err:
            print(f"{path.name:34s} invalid: {err}")
    return EXIT_OK


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``cpopt`` command; returns the exit code."""
    args = _parser().parse_args(argv)
    if args.command == "check":
        return _cmd_check(args.files)
    if args.command == "list":
        return _cmd_list()
    return _cmd_solve(args)


if __name__ == "__main__":
    sys.exit(main())
