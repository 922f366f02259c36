"""The ``cpopt`` command line: argument parsing and exit codes, nothing else.

Exit codes: 0 every problem solved; 1 a solve failed (its status is still written);
2 bad input (a file that does not validate, two problems of one name, an output folder that
cannot be written, wrong arguments), found before any solving; 130 interrupted (Ctrl-C).
Bad input wins over a failure.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import math
import os
import signal
import sys
import threading
from pathlib import Path

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT, EXIT_INTERRUPTED = 0, 1, 2, 130
MAX_WORKERS = 1024
"""Most worker processes of a local cluster: more is a typo (each is a Python process of
about 150 MB), refused before any is started."""
SWEEP_GRACE = 15.0
"""Seconds ``cpopt sweep`` gets after Ctrl-C to cancel its tasks and close its cluster before
the process is ended (other commands get :data:`cpopt.runtime.budget.INTERRUPT_GRACE`)."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # argparse exits with 2 too; keep its usage line
        self.print_usage(sys.stderr)
        self.exit(EXIT_BAD_INPUT, f"cpopt: error: {message}\n")


def _seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a positive number of seconds, got {text!r}")
    return value


def _path(text: str) -> str:
    """A file or folder name: not empty (``Path("")`` is the current folder)."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"expected a file or folder name, got {text!r}")
    return text


def make_parser() -> argparse.ArgumentParser:
    """The parser of every verb and option (public: the tests walk it to try each option)."""
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
    solve.add_argument("files", nargs="+", type=_path, metavar="FILE", help="YAML problem files")
    solve.add_argument(
        "--out",
        default="out",
        type=_path,
        metavar="DIR",
        help="results go to DIR/<name>/ (default: out)",
    )
    solve.add_argument("--plot", action="store_true", help="also write PNG figures")
    solve.add_argument("--animate", action="store_true", help="also write arm.gif")
    solve.add_argument(
        "--engine",
        choices=("matplotlib", "mujoco"),
        default="matplotlib",
        metavar="ENGINE",
        help="what draws arm.gif: matplotlib (default) or mujoco (MuJoCo's offscreen renderer, "
        "the tracked arm beside the plan; needs cpopt[mujoco] and EGL or OSMesa)",
    )
    solve.add_argument(
        "--time-limit",
        type=_seconds,
        metavar="SECONDS",
        help="wall-clock limit of each problem, planning and verification together "
        "(default: the file's optimizer.solver.max_time, 300 s)",
    )
    solve.add_argument(
        "--verbose", action="store_true", help="show Ipopt's iterations, each run labelled"
    )
    solve.add_argument(
        "--quiet", action="store_true", help="no progress messages (shown on a terminal)"
    )
    _sweep_parser(sub)
    check = sub.add_parser("check", help="validate problem files without solving")
    check.add_argument("files", nargs="+", type=_path, metavar="FILE")
    sub.add_parser("list", help="show the bundled problems")
    export = sub.add_parser(
        "export-urdf", help="write a problem's arm as URDF (arm: {urdf: FILE} reads it back)"
    )
    export.add_argument("file", type=_path, metavar="FILE", help="a YAML problem file")
    export.add_argument(
        "--out", type=_path, metavar="OUT.urdf", help="write OUT.urdf (default: standard output)"
    )
    return parser


def _workers(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if not 1 <= value <= MAX_WORKERS:
        raise argparse.ArgumentTypeError(
            f"expected a whole number of workers from 1 to {MAX_WORKERS}, got {text!r}"
        )
    return value


def _sweep_parser(sub) -> None:
    sweep = sub.add_parser(
        "sweep",
        help="solve a grid of variants of one problem file on Dask (a local cluster or a "
        "running one)",
    )
    sweep.add_argument(
        "base", type=_path, metavar="BASE.yaml", help="the problem file the points vary"
    )
    sweep.add_argument(
        "--vary",
        action="append",
        required=True,
        metavar="KEY=SPEC",
        help="a key path (motion.duration, arm.links[2].mass, optimizer.limits.torque[0]) and "
        "its values: a:b:n (n evenly spaced), a,b,c (a list) or random:a:b:n:seed; several "
        "--vary make a full grid",
    )
    sweep.add_argument(
        "--out",
        default="out",
        type=_path,
        metavar="DIR",
        help="DIR/<point>/ and DIR/sweep.csv (default: out)",
    )
    sweep.add_argument(
        "--workers",
        type=_workers,
        metavar="N",
        help="single-threaded worker processes of the local cluster (default: one per core)",
    )
    sweep.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="use the running Dask cluster at ADDRESS ([tcp://]host:port) instead of a local "
        "one; it must accept a connection within a few seconds, before any work",
    )
    sweep.add_argument(
        "--time-limit",
        type=_seconds,
        metavar="SECONDS",
        help="wall-clock limit of each point (default: the file's optimizer.solver.max_time)",
    )
    sweep.add_argument(
        "--resume",
        action="store_true",
        help="skip points whose results in DIR are complete for the same problem",
    )
    sweep.add_argument("--plot", action="store_true", help="also write DIR/sweep.png")
    sweep.add_argument("--quiet", action="store_true", help="no progress bar on stderr")


def _error(message: str) -> None:
    print(f"error: {message}", file=sys.stderr, flush=True)


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
            _error(error)
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


def _problems(files) -> tuple[list, bool]:
    """The problems that load, one per name; and whether any input was bad."""
    problems, seen, bad = [], {}, False
    for path in files:
        problem, error = _load(path)
        if problem is not None and problem.name.casefold() in seen:
            first = seen[problem.name.casefold()]
            error = (
                f"{path}: name: '{problem.name}' is also the name of {first} in this command; "
                "both would write the same folder (give one another name)"
            )
        if error:
            _error(error)
            bad = True
            continue
        seen[problem.name.casefold()] = path
        problems.append(problem)
    return problems, bad


def _outputs(problems, out: Path) -> tuple[list, bool]:
    """Create the output folder and check each problem's folder, before any solving."""
    from .io.output import OutputError, check_problem_directory, make_directory

    if not problems:
        return [], False
    try:
        make_directory(out)
    except OutputError as err:
        _error(f"--out {err}")
        return [], True
    usable, bad = [], False
    for problem in problems:
        try:
            check_problem_directory(out / problem.name)
            usable.append(problem)
        except OutputError as err:
            _error(f"{problem.source}: name: {err}")
            bad = True
    return usable, bad


def _write(solution, problem, outdir: Path, args) -> None:
    """Replace the problem's results: old ones go first, the JSON is written last."""
    from .io.output import clear, locked, make_directory
    from .results import write_solution

    make_directory(outdir)
    with locked(outdir):
        clear(outdir)  # no figure of an earlier run stays beside this one's status
        if solution.ok and (args.plot or args.animate):
            import matplotlib  # here, not at start-up: 0.2-0.4 s before the first progress line

            matplotlib.use("Agg")  # files, never a window
            from .plotting import animate, write_figures

            if args.plot:
                o = problem.spec.optimizer
                gamma_min = None if problem.planner == "closed_form" else o.gamma_min
                write_figures(solution, outdir, o.limits.torque, gamma_min)
            if args.animate and args.engine == "mujoco":
                _render(solution, outdir / "arm.gif")
            elif args.animate:
                animate(solution, outdir / "arm.gif")
        write_solution(solution, outdir)


def _render(solution, path: Path) -> None:
    """arm.gif from MuJoCo; where no OpenGL context can be made, a note instead (not a
    failure: the results are written all the same)."""
    from .mujoco_render import RenderUnavailableError
    from .solution import Solution

    try:
        Solution.of(solution).render(path)
    except RenderUnavailableError as err:
        print(f"{solution.name}: arm.gif skipped: {err}", file=sys.stderr, flush=True)


def _cmd_solve(args) -> int:
    from .isolate import solve_isolated
    from .runtime import progress

    out = Path(args.out)
    if args.engine == "mujoco" and args.animate:
        import importlib.util

        if importlib.util.find_spec("mujoco") is None:
            _error("--engine mujoco: MuJoCo is not installed: pip install 'cpopt[mujoco]'")
            return EXIT_BAD_INPUT
    problems, bad_files = _problems(args.files)
    problems, bad_outputs = _outputs(problems, out)
    if bad_outputs and not problems:
        return EXIT_BAD_INPUT
    reporter = progress.Progress(quiet=args.quiet, verbose=args.verbose)
    code = EXIT_BAD_INPUT if bad_files or bad_outputs else EXIT_OK
    for problem in problems:
        if args.verbose:
            problem = problem.with_print_level(5)
        if args.time_limit is not None:
            problem = problem.with_time_limit(args.time_limit)
        with progress.reporting(reporter, problem.name):
            solution = solve_isolated(problem)
            progress.stage("writing results")
            outdir = out / problem.name
            _write(solution, problem, outdir, args)
        print(_summary(solution, outdir), flush=True)
        if not solution.ok and code == EXIT_OK:
            code = EXIT_FAILED
    return code


def _cmd_export_urdf(args) -> int:
    from .io.output import OutputError, atomic_write, check_directory

    problem, error = _load(args.file)
    if error:
        _error(error)
        return EXIT_BAD_INPUT
    text = problem.to_urdf()
    if args.out is None:
        sys.stdout.write(text)
        return EXIT_OK
    out = Path(args.out)
    try:
        if out.is_dir():
            raise OutputError(f"{out}: is a folder; expected a file name")
        if not out.parent.is_dir():
            raise OutputError(f"{out}: {out.parent} is not an existing folder")
        check_directory(out.parent)
        atomic_write(out, lambda handle: handle.write(text))
    except OSError as err:
        _error(f"--out {err}")
        return EXIT_BAD_INPUT
    print(f"wrote {out} (joints joint1, joint2, joint3)")
    return EXIT_OK


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


_announced = threading.Lock()


def _interrupted() -> None:
    """The one line of a Ctrl-C (said once, by whichever of main and the watcher is first)."""
    from .io.output import remove_temporaries

    remove_temporaries()
    if _announced.acquire(blocking=False):
        print("cpopt: interrupted", file=sys.stderr, flush=True)


def _caused_by_interrupt(err: BaseException) -> bool:
    """True when a KeyboardInterrupt is in the exception's chain of causes and contexts."""
    seen = set()
    while err is not None and id(err) not in seen:
        if isinstance(err, KeyboardInterrupt):
            return True
        seen.add(id(err))
        err = err.__cause__ or err.__context__
    return False


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``cpopt`` command; returns the exit code."""
    from .runtime.budget import INTERRUPT_GRACE, hard_stop_on_interrupt

    words = sys.argv[1:] if argv is None else argv
    grace = SWEEP_GRACE if words[:1] == ["sweep"] else INTERRUPT_GRACE
    try:
        with hard_stop_on_interrupt(_interrupted, grace=grace, code=EXIT_INTERRUPTED):
            try:
                args = make_parser().parse_args(argv)
            except SystemExit as done:  # --help, --version or a bad option: argparse has spoken
                return done.code if isinstance(done.code, int) else EXIT_BAD_INPUT
            if args.command == "check":
                return _cmd_check(args.files)
            if args.command == "list":
                return _cmd_list()
            if args.command == "export-urdf":
                return _cmd_export_urdf(args)
            if args.command == "sweep":
                from .sweep.run import main as sweep_main

                return sweep_main(args)
            return _cmd_solve(args)
    except KeyboardInterrupt:
        _interrupted()
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # `cpopt list | head`: the reader left; so do we, quietly
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_FAILED
    except Exception as err:
        # a Ctrl-C inside an import or a descriptor hook reaches us wrapped in another
        # exception (e.g. RuntimeError from __set_name__); it is still the user's Ctrl-C
        if not _caused_by_interrupt(err):
            raise
        _interrupted()
        return EXIT_INTERRUPTED


def own_ctrl_c() -> None:
    """Make Ctrl-C mean "stop cleanly, exit 130" however the process was started.

    A process started as a background job of a non-interactive shell inherits SIGINT as
    ignored, and Python then installs no KeyboardInterrupt handler: the signal would never
    arrive. The command line installs Python's own handler at start-up (main thread only).
    """
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.default_int_handler)


def run() -> None:
    """The ``cpopt`` process: :func:`main`, then exit with its code.

    After Ctrl-C the process ends with ``os._exit(130)``: CPython may otherwise turn a
    KeyboardInterrupt that was caught inside an interrupted import into death by SIGINT at
    shutdown (exit status -2 instead of 130). Every command but ``sweep`` ends that way too,
    its output flushed: all its files are written and closed by then, and the interpreter's
    teardown (freeing CasADi's functions, Ipopt and the modules) took 0.05-0.1 s of every
    ``cpopt solve``. A sweep exits normally, so that Dask cleans up after its cluster.
    """
    own_ctrl_c()
    code = main()
    if code == EXIT_INTERRUPTED or sys.argv[1:2] != ["sweep"]:
        _exit_now(code)
    sys.exit(code)


def _exit_now(code: int) -> None:
    """Flush the output streams and the loggers, then end the process with ``code``."""
    for stream in (sys.stdout, sys.stderr):
        # a reader that left, a closed stream: nothing to keep
        with contextlib.suppress(OSError, ValueError):
            stream.flush()
    logging.shutdown()
    os._exit(code)


if __name__ == "__main__":
    run()
