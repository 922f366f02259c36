"""The Python API: load a problem, solve it, track its plan (re-exported by :mod:`cpopt`).

``cpopt.load`` → :class:`~cpopt.problem.Problem`, ``cpopt.solve`` →
:class:`~cpopt.solution.Solution`, ``cpopt.track`` → a tracking outcome; the same stages the
command line runs (:func:`cpopt.pipeline.solve`), without files unless asked
(:meth:`Solution.save <cpopt.solution.Solution.save>`).
"""

from __future__ import annotations

from pathlib import Path

from . import pipeline
from .closedform.plan import CPPlan
from .io.safe_yaml import echo
from .problem import Problem, ProblemError, read_problem
from .problem.build import check_seconds
from .runtime.progress import Progress, reporting
from .solution import Solution
from .tracking import TrackingOutcome, TrackingRefused, track_problem


def load(path_or_dict: str | Path | dict, **overrides) -> Problem:
    """A problem from a YAML file or problem data, with values changed by key path.

    Parameters
    ----------
    path_or_dict : str, Path or dict
        A problem file (``problems/paper_swing_up.yaml``), or its content as a dict (left
        unchanged).
    **overrides
        Values by key path, the syntax error messages use, set before validation:
        ``cpopt.load("problems/swing_up_min_torque.yaml", **{"motion.duration": 2.0})``;
        plain names as keywords (``planner="optimize"``). Units are the file's (degrees in
        ``theta_deg``). :meth:`Problem.replace <cpopt.problem.Problem.replace>` does the same
        on a loaded problem.

    Returns
    -------
    Problem

    Raises
    ------
    ProblemError
        For an unreadable file, a key path that cannot be set, two overrides of one value
        (``motion`` and ``motion.duration``), or content the file format refuses: the message
        names the file and the key path (``err.source``, ``err.path``); for a
        ``path_or_dict`` that is neither a file name nor a dict, it names that argument.
    """
    _check_source(path_or_dict, "path_or_dict", "cpopt.load")
    return read_problem(path_or_dict, overrides)


def _check_source(value, argument: str, function: str) -> None:
    """Refuse what is neither a problem file's name nor problem data, before reading it."""
    if isinstance(value, dict) or (isinstance(value, Path) and str(value) != "."):
        return
    if isinstance(value, str) and value.strip():
        return
    raise ProblemError(
        function,
        argument,
        "expected a problem file (str or Path) or a dict of problem data, got "
        f"{type(value).__name__} {echo(value)}",
    )


def solve(
    problem_or_path: Problem | str | Path | dict,
    *,
    planner: str | None = None,
    time_limit: float | None = None,
    progress: bool = False,
    start: Solution | None = None,
) -> Solution:
    """Plan, sample, verify (and track, with a ``tracking`` block) as ``cpopt solve`` does.

    Parameters
    ----------
    problem_or_path : Problem, str, Path or dict
        A loaded problem, or what :func:`load` takes.
    planner : str, optional
        ``closed_form``, ``optimize`` or ``collocation`` instead of the problem's ``planner``
        (validated again: an optimizer setting that needs ``optimize`` is checked then).
    time_limit : float, optional
        Wall-clock limit of planning and verification together [s] instead of the problem's
        ``optimizer.solver.max_time``. It is enforced in this process, between and inside the
        solver's iterations (the command line also kills a process that overruns it inside a
        native call that does not check the clock).
    progress : bool
        Write the stages and Ipopt iteration counts to stderr (``cpopt: <name>: <stage> [s]``).
    start : Solution, optional
        A solved plan of a neighbouring problem (another mass, duration or limit of the same
        file) to start the flat optimizer from: its pattern of signs of gamma is solved once
        from its plan, without the switch search, which runs only when that does not solve
        (``solver.search``). Continuation along a parameter study: ``transfer_switch`` with
        link 3 5 % heavier solves in 12 Ipopt iterations from the first plan instead of a
        search of about 180. ``planner: optimize`` only.

    Returns
    -------
    Solution
        Its ``status`` says whether it worked (``solved``); a failure is a status, never an
        exception. At the time limit the status is ``time_limit`` with what was done by then.

    Raises
    ------
    ProblemError
        For a problem that does not load, a planner the problem cannot use, a time limit
        that is not a finite number of seconds > 0 or a ``progress`` that is not True/False
        (the message names the argument); all before any work.
    ValueError
        For a ``start`` that is not a solution with a plan, or a planner other than
        ``optimize`` with one.
    KeyboardInterrupt
        On Ctrl-C.
    """
    problem = _problem(problem_or_path)
    if not isinstance(progress, bool):
        raise ProblemError(
            problem.source, "progress", f"expected True or False, got {echo(progress)}"
        )
    if planner is not None and planner != problem.planner:
        problem = problem.replace(planner=planner)
    plan = _start_plan(start, problem)
    if time_limit is not None:
        check_seconds(time_limit, problem.source, "time_limit")
        problem = problem.with_time_limit(time_limit)
    # shown on stderr when asked, terminal or not (a notebook's stderr is not a terminal)
    with reporting(Progress(quiet=not progress, verbose=progress), problem.name):
        record = pipeline.solve(problem, plan)
    return Solution.of(record, problem)


def _start_plan(start, problem: Problem):
    """The flat plan of a ``start`` solution (None without one), checked."""
    if start is None:
        return None
    plan = getattr(start, "plan", None)
    if not isinstance(plan, CPPlan):
        raise ValueError(
            "start must be a Solution of cpopt.solve holding a flat plan (planner optimize or "
            f"closed_form), got {type(start).__name__}"
        )
    if problem.planner != "optimize":
        raise ValueError(f"start applies to planner optimize, not {problem.planner!r}")
    return plan


def _problem(problem_or_path) -> Problem:
    if isinstance(problem_or_path, Problem):
        return problem_or_path
    _check_source(problem_or_path, "problem_or_path", "cpopt.solve")
    return read_problem(problem_or_path)


def track(
    solution: Solution,
    *,
    plant: dict | None = None,
    controller: str = "tvlqr",
    **tracking,
) -> TrackingOutcome | TrackingRefused:
    """Track a solved plan on a realistic plant, as a problem's ``tracking`` block does.

    Parameters
    ----------
    solution : Solution
        A solution of :func:`solve` with a plan (it knows its problem).
    plant : dict, optional
        The ``tracking.plant`` block: ``links`` (per link ``length``, ``mass``, ``com``,
        ``inertia`` overriding the arm's), ``friction`` {``viscous``, ``coulomb``},
        ``torque_limit`` [N m or N] (default: the problem's ``optimizer.limits.torque``).
        Default: the model arm.
    controller : str
        ``tvlqr``, ``tvlqr_timescaled`` (slows the reference to fit the plant's torque limits;
        the run may end after T), ``dfl``, or ``flat_mpc`` (TVLQR around a plan re-solved
        from the measured state every ``replan_period``, a flat plan of ``planner:
        optimize`` only).
    **tracking
        The block's other keys: ``rate_hz``, ``Q``, ``R``, ``Qf``, ``poles``, ``noise``,
        ``replan_period``, ``replan_delay``, ``replan_deadline``, ``replan_method`` (see
        docs/problems.md).

    Returns
    -------
    TrackingOutcome or TrackingRefused
        The tracked motion and its errors (``.summary()`` is ``solution.json``'s ``tracking``
        entry), or why the controller cannot follow the plan.

    Raises
    ------
    ProblemError
        For settings the ``tracking`` block refuses, naming the key path
        (``tracking.plant.links[2].mass``).
    ValueError
        For a ``solution`` that is not a Solution, or one without a plan or its problem.
    """
    if not isinstance(solution, Solution):
        raise ValueError(
            "solution must be a Solution of cpopt.solve, got "
            f"{type(solution).__name__} {echo(solution)}"
        )
    if solution.plan is None:
        raise ValueError(f"{solution.name}: no plan to track (status {solution.status})")
    if getattr(solution, "problem", None) is None:
        raise ValueError(f"{solution.name}: a solution of cpopt.solve is needed (its problem)")
    block = {"controller": controller, **tracking}
    if plant is not None:
        block["plant"] = plant
    problem = solution.problem.replace(tracking=block)
    return track_problem(problem, solution.plan)


__all__ = ["load", "solve", "track"]
