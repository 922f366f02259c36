"""Every argument of the public Python API, given each value of a family of bad values: a
:class:`cpopt.ProblemError` or ``ValueError`` naming the argument, before any work.

The public callables are found from ``cpopt.__all__`` and the public methods of its classes,
and each parameter gets the family of its annotation (or of its name where it has none), so a
function or parameter added later is tried too; one without a family fails
:func:`test_every_argument_has_a_family_of_bad_values`.
"""

from __future__ import annotations

import inspect
import math
from dataclasses import dataclass
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pytest
from conftest import PROBLEMS, forbid

import cpopt

CLOSED_FORM = PROBLEMS / "paper_transfer.yaml"
"""A problem that solves in well under a second (the closed form)."""

# --- families of bad values ------------------------------------------------------------------

NOT_FINITE = (math.nan, math.inf, -math.inf)
NOT_POSITIVE = (0, 0.0, -1, -1e-9)
WRONG_TYPES = ("abc", "1", True, [1.0], {"a": 1}, object())


@dataclass(frozen=True)
class Bad:
    """A bad value; ``names`` are the words of which the message must hold one."""

    label: str
    value: object
    names: tuple[str, ...] = ()


def _seconds(optional: bool) -> list[Bad]:
    values = [*NOT_FINITE, *NOT_POSITIVE, *WRONG_TYPES]
    return [Bad(repr(v), v) for v in values] + ([] if optional else [Bad("None", None)])


def _level() -> list[Bad]:
    values = [-1, 13, 2.5, math.nan, "3", True, None, [0]]
    return [Bad(repr(v), v) for v in values]


def _choice(optional: bool) -> list[Bad]:
    values = ["", "not-a-choice", "OPTIMIZE", 3, ["optimize"], math.nan, True]
    return [Bad(repr(v), v) for v in values] + ([] if optional else [Bad("None", None)])


def _flag() -> list[Bad]:
    return [Bad(repr(v), v) for v in ("yes", 1, 0.0, None, "")]


def _source(tmp: Path) -> list[Bad]:
    """Neither a problem file nor problem data; a path is named by the message itself."""
    values = [42, None, "", "   ", [], b"p.yaml", 1.5]
    files = ["nope.yaml", "folder", "file/p.yaml", "empty.yaml", "list.yaml", "broken.yaml"]
    return [Bad(repr(v), v) for v in values] + [
        Bad(f, str(tmp / f), (f.split("/")[0],)) for f in files
    ]


def _folder(tmp: Path) -> list[Bad]:
    """Not a place a folder of results can be."""
    values = ["", "   ", 42, None, b"out"]
    return [Bad(repr(v), v) for v in values] + [
        Bad(f, str(tmp / f)) for f in ("file", "file/out", "file/a/b")
    ]


def _solution(optional: bool, problem) -> list[Bad]:
    values = ["plan.json", 3, {}, problem, [problem]]
    return [Bad(repr(v)[:30], v) for v in values] + ([] if optional else [Bad("None", None)])


def _problem(solution) -> list[Bad]:
    return [Bad(repr(v)[:30], v) for v in ("p.yaml", 3, {}, solution)]


def _mapping() -> list[Bad]:
    values = [
        "links",
        3,
        [1],
        {"links": "x"},
        {"nope": 1},
        {"links": [None, None, {"mass": -1}]},
        {"friction": {"viscous": [math.nan, 0, 0]}},
        {"torque_limit": [math.inf, 1]},
    ]
    return [Bad(repr(v), v) for v in values]


def _times() -> list[Bad]:
    values = [
        "abc", None, math.nan, math.inf, -math.inf, [0.0, math.nan], -1.0, 1e9, [[0.0, 0.1]],
        np.zeros((2, 2)), ["a"], True, {}, object(), [], np.array([]),
    ]  # fmt: skip
    return [Bad(repr(v)[:30], v) for v in values]


def _axes() -> list[Bad]:
    values = ["ax", 3, [1, 2], [], object(), np.zeros(2), plt.subplots(1, 3)[1]]  # 3 for 1 phase
    return [Bad(repr(v)[:30], v) for v in values]


def _key_values() -> list[Bad]:
    """Overrides by key path: each message names the key path at fault."""
    cases = [
        {"motion..duration": 1.0},
        {"motion.duraton": 1.0},
        {"motion.duration.x": 1.0},
        {"arm.links[9].mass": 1.0},
        {"": 1.0},
        {"motion": {"duration": 1.0}, "motion.duration": 2.0},  # one inside the other
        {"motion.duration": 1.0, " motion.duration": 2.0},  # one key twice
        {"planner": "newton"},
    ]
    cases += [{"motion.duration": v} for v in (*NOT_FINITE, *NOT_POSITIVE, "abc", None, [1.0])]
    # the message names each key path given (an empty one is "a key path")
    return [Bad(repr(c), c, tuple(k.strip() or "key path" for k in c)) for c in cases]


def _tracking_keys() -> list[Bad]:
    """The ``tracking`` block's other keys: each message names the key."""
    cases = [{"rate_hz": v} for v in (*NOT_FINITE, *NOT_POSITIVE, "fast", None)]
    cases += [{"Q": "abc"}, {"Q": [1.0, 2.0]}, {"R": [-1.0, 1.0]}, {"nope": 1}]
    cases += [{"noise": {"seed": -1}}, {"poles": [1.0, 1.0, 1.0, 1.0]}]
    cases += [{"replan_period": 0}, {"replan_delay": -1.0}, {"replan_deadline": "soon"}]
    cases += [{"replan_method": "acados"}]
    return [Bad(repr(c), c, tuple(c)) for c in cases]


def _image_files(tmp: Path) -> list[Bad]:
    """Not a picture cpopt can write."""
    values = ["", "   ", 42, None, b"arm.gif"]
    files = ["folder", "arm.jpg", "arm", "file/arm.gif", "missing/arm.gif"]
    return [Bad(repr(v), v) for v in values] + [Bad(f, str(tmp / f)) for f in files]


def _plan_times() -> list[Bad]:
    """Not a time within the plan (it lasts a few seconds)."""
    values = [*NOT_FINITE, -1, -1e-9, 1e6, "abc", True, None, [0.5]]
    return [Bad(repr(v), v) for v in values]


def _joint_states() -> list[Bad]:
    """Not 3 finite numbers (one per joint)."""
    values = ["abc", None, [0.0, 1.0], [0.0, math.nan, 0.0], [math.inf, 0, 0], np.zeros((2, 3)),
              True, {}, object(), []]  # fmt: skip
    return [Bad(repr(v)[:30], v) for v in values]


def _plans(problem) -> list[Bad]:
    return [Bad(repr(v)[:30], v) for v in ("plan.json", 3, {}, problem)]


def _multipliers() -> list[Bad]:
    return [Bad(repr(v)[:30], v) for v in ("warm", 3, {}, [1.0], object())]


def families(tmp: Path, problem, solution) -> dict[str, list[Bad]]:
    """Bad values by parameter annotation (or ``name:`` for a parameter without one)."""
    source = _source(tmp)
    return {
        "str | Path | dict": source,
        "Problem | str | Path | dict": source,
        "str | None": _choice(optional=True),
        "str": _choice(optional=False),
        "float | None": _seconds(optional=True),
        "float": _seconds(optional=False),
        "int": _level(),
        "bool": _flag(),
        "Solution | None": _solution(True, problem),
        "Solution": _solution(False, problem),
        "results.Solution": _solution(False, problem),
        "Problem | None": _problem(solution),
        "dict | None": _mapping(),
        "str | Path": _folder(tmp),
        "name:t": _times(),
        "name:ax": _axes(),
        "**overrides": _key_values(),
        "**tracking": _tracking_keys(),
        "ImageFile": _image_files(tmp),
        "Time": _plan_times(),
        "name:q": _joint_states(),
        "name:qd": _joint_states(),
        "CPPlan | None": _plans(problem),
        "Multipliers | None": _multipliers(),
    }


def _family_key(parameter: inspect.Parameter) -> str:
    if parameter.kind is inspect.Parameter.VAR_KEYWORD:
        return f"**{parameter.name}"
    if parameter.annotation is inspect.Parameter.empty:
        return f"name:{parameter.name}"
    return str(parameter.annotation)


# --- the public callables --------------------------------------------------------------------


def public_callables() -> dict[str, object]:
    """``cpopt.<name>`` functions and ``cpopt.<Class>.<method>`` public methods."""
    found = {}
    for name in cpopt.__all__:
        value = getattr(cpopt, name)
        if inspect.isfunction(value):
            found[f"cpopt.{name}"] = value
        elif inspect.isclass(value) and not issubclass(value, BaseException):
            for method, member in inspect.getmembers(value, callable):
                if not method.startswith("_") and not inspect.isclass(member):
                    found[f"cpopt.{name}.{method}"] = member
    return found


def parameters(function) -> list[inspect.Parameter]:
    """The parameters a caller gives (not ``self`` nor ``cls``)."""
    return [p for p in inspect.signature(function).parameters.values() if p.name != "self"]


def good_calls(problem, solution) -> dict[str, tuple]:
    """A good call of each public callable: the callable (bound), and its arguments."""
    return {
        "cpopt.load": (cpopt.load, {"path_or_dict": str(CLOSED_FORM)}),
        "cpopt.solve": (cpopt.solve, {"problem_or_path": problem}),
        "cpopt.track": (cpopt.track, {"solution": solution}),
        "cpopt.replan": (
            cpopt.replan,
            {"solution": solution, "t": 0.5, "q": [0.0, 0.0, 0.0], "qd": [0.0, 0.0, 0.0]},
        ),
        "cpopt.Problem.replace": (problem.replace, {}),
        "cpopt.Problem.with_print_level": (problem.with_print_level, {"level": 5}),
        "cpopt.Problem.with_time_limit": (problem.with_time_limit, {"seconds": 10.0}),
        "cpopt.Problem.to_urdf": (problem.to_urdf, {}),
        "cpopt.Solution.as_dict": (solution.as_dict, {}),
        "cpopt.Solution.of": (cpopt.Solution.of, {"record": solution, "problem": problem}),
        "cpopt.Solution.plot": (solution.plot, {"kind": "third_link"}),
        "cpopt.Solution.render": (solution.render, {"path": "{tmp}/arm.gif"}),
        "cpopt.Solution.sample": (solution.sample, {"t": 0.5}),
        "cpopt.Solution.save": (solution.save, {"directory": "{tmp}/saved"}),
        "cpopt.Solution.summary": (solution.summary, {}),
        "cpopt.Solution.to_dict": (solution.to_dict, {}),
    }


@pytest.fixture(scope="module")
def solved():
    problem = cpopt.load(CLOSED_FORM)
    solution = cpopt.solve(problem)
    assert solution.status == "solved" and solution.plan is not None
    return problem, solution


def test_every_argument_has_a_family_of_bad_values(solved, tmp_path):
    problem, solution = solved
    calls = good_calls(problem, solution)
    callables = public_callables()
    assert set(calls) == set(callables), "give each public callable a good call in good_calls"
    known = families(tmp_path, problem, solution)
    missing = [
        f"{name}({p.name}: {_family_key(p)})"
        for name, function in callables.items()
        for p in parameters(function)
        if _family_key(p) not in known
    ]
    assert not missing, f"no family of bad values for: {missing}; add one to families()"


def _setup(tmp: Path) -> None:
    (tmp / "folder").mkdir()
    (tmp / "file").write_text("not a folder\n")
    (tmp / "empty.yaml").write_text("")
    (tmp / "list.yaml").write_text("- 1\n")
    (tmp / "broken.yaml").write_text("arm: {kind: RRR\n")


def _tree(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*"))


@pytest.fixture
def no_work(monkeypatch):
    """Fail a call that plans or tracks (refusal comes first)."""
    forbid(monkeypatch, "cpopt.pipeline.solve", "cpopt.api.track_problem")


def _call(function, good: dict, parameter: inspect.Parameter, value, tmp: Path):
    arguments = {
        k: v.replace("{tmp}", str(tmp)) if isinstance(v, str) else v for k, v in good.items()
    }
    if parameter.kind is inspect.Parameter.VAR_KEYWORD:
        return function(**arguments, **value)
    arguments[parameter.name] = value
    positional = [p.name for p in parameters(function)][:1]
    first = [arguments.pop(n) for n in positional if n in arguments]
    return function(*first, **arguments)


@pytest.mark.parametrize("name", list(public_callables()))
def test_each_bad_argument_is_refused_naming_it(name, solved, tmp_path, no_work):
    """Each parameter of ``name`` gets every value of its family, one call each."""
    problem, solution = solved
    function, good = good_calls(problem, solution)[name]
    _setup(tmp_path)
    before = _tree(tmp_path)
    known = families(tmp_path, problem, solution)
    tried = 0
    for parameter in parameters(function):
        for bad in known[_family_key(parameter)]:
            with pytest.raises(ValueError) as caught:
                _call(function, good, parameter, bad.value, tmp_path)
            text = str(caught.value)
            names = bad.names or (parameter.name,)
            assert any(n in text for n in names), (name, parameter.name, bad.label, text)
            assert "\n" not in text, text  # one line
            tried += 1
        plt.close("all")
    assert _tree(tmp_path) == before  # nothing written
    if parameters(function):
        assert tried >= 5 * len(parameters(function))
    else:  # nothing to give: the good call works
        assert function(**good) is not None


def test_a_problem_error_keeps_the_argument_as_its_path(solved):
    problem, _ = solved
    with pytest.raises(cpopt.ProblemError) as caught:
        cpopt.solve(problem, time_limit=math.nan)
    assert (caught.value.source, caught.value.path) == (str(CLOSED_FORM), "time_limit")
    assert caught.value.message == "expected a finite number of seconds > 0, got nan"
    with pytest.raises(cpopt.ProblemError) as caught:
        cpopt.load(42)
    assert (caught.value.source, caught.value.path) == ("cpopt.load", "path_or_dict")
    with pytest.raises(cpopt.ProblemError, match=r"motion: also given as motion\.duration"):
        cpopt.load(CLOSED_FORM, motion={"duration": 1.0}, **{"motion.duration": 2.0})


def test_good_arguments_still_work(solved, tmp_path):
    """The checks refuse only what is bad: NumPy numbers, arrays of times, Paths, axes."""
    problem, solution = solved
    assert problem.with_time_limit(np.float64(2.5)).max_time == 2.5
    assert problem.with_print_level(np.int64(3)).spec.optimizer.solver.print_level == 3
    t = np.linspace(0.0, solution.plan.duration, 5)
    assert solution.sample(t).t.shape == (5,)
    assert solution.sample(np.float32(0.5)).t.shape == (1,)
    fig, axes = plt.subplots(1, 2)
    try:
        assert solution.plot("third_link", ax=axes[:1]) is fig  # one phase, one panel
        assert solution.plot("torques", ax=axes[1]) is fig
        with pytest.raises(ValueError, match="ax must be 1 matplotlib Axes here, got 2"):
            solution.plot("third_link", ax=axes)
    finally:
        plt.close(fig)
    written = solution.save(tmp_path / "new" / "folder")
    assert [p.name for p in written] == ["solution.json", "trajectory.csv"]
