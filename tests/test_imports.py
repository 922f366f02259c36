"""The import graph of cpopt has no cycle, goes one way through the layers, and no module is too
long to read.

Every ``import`` statement counts: at module level, inside functions (imported late for speed)
and under ``if TYPE_CHECKING:`` (a cycle a type checker sees is a cycle a reader follows too).
An edge goes to the module named, or to ``pkg.name`` when ``from pkg import name`` names a
submodule. The import of a submodule's parent package that Python performs first is not an
edge (a package's ``__init__`` re-exporting its modules would otherwise be a cycle with each).
"""

from __future__ import annotations

import ast
import importlib
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "cpopt"
MAX_LINES = 700


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _imports(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The cpopt modules that module ``name`` (file ``path``) imports anywhere in its code."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                target = f"{base}.{node.module}" if node.module else base
            else:
                target = node.module
            for alias in node.names:
                sub = f"{target}.{alias.name}"
                found.add(sub if sub in modules else target)
    return {m for m in found if m in modules and m != name}


def import_graph() -> dict[str, set[str]]:
    """Module name -> the cpopt modules it imports."""
    modules = _modules()
    return {name: _imports(name, path, modules) for name, path in modules.items()}


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of the graph as a list of modules (first == last), or None."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                return [*stack[stack.index(nxt) :], nxt]
            if nxt not in state and (cycle := visit(nxt)):
                return cycle
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (cycle := visit(node)):
            return cycle
    return None


LAYERS = (
    ("io", ("cpopt.io",)),
    ("runtime", ("cpopt.runtime",)),
    ("model", ("cpopt.model",)),
    ("urdf", ("cpopt.urdf",)),
    ("closedform", ("cpopt.closedform",)),
    # the per-sample functions and control laws that verification shares with the planners; they
    # live in the planners' packages (flatopt, tracking) but import only the layers below
    (
        "shared laws",
        (
            "cpopt.flatopt.samples",
            "cpopt.tracking.controller",
            "cpopt.tracking.dfl",
            "cpopt.tracking.reference",
            "cpopt.tracking.tvlqr",
        ),
    ),
    ("problem", ("cpopt.problem",)),
    ("verify", ("cpopt.verify",)),
    ("planners", ("cpopt.flatopt", "cpopt.collocation", "cpopt.tracking")),
    ("application", ("cpopt",)),
)
"""The layers from the bottom up, each named by module prefixes (the longest prefix decides). A
module may import its own layer and those below it, never one above."""

APPLICATION = {
    "cpopt",
    "cpopt.__main__",
    "cpopt.api",
    "cpopt.cli",
    "cpopt.isolate",
    "cpopt.mujoco_render",
    "cpopt.pipeline",
    "cpopt.plotting",
    "cpopt.replanning",
    "cpopt.results",
    "cpopt.solution",
}
"""The modules at the top level of cpopt that are not old paths kept for one release."""


def layer(name: str) -> int:
    """The index in :data:`LAYERS` of module ``name``'s layer."""
    best, found = -1, None
    for index, (_, prefixes) in enumerate(LAYERS):
        for prefix in prefixes:
            if (name == prefix or name.startswith(prefix + ".")) and len(prefix) > best:
                best, found = len(prefix), index
    assert found is not None, name
    return found


def moved_modules() -> dict[str, str]:
    """Old module path -> new one, for the deprecated modules kept at the old paths."""
    marker = "sys.modules[__name__] = importlib.import_module("
    moved = {}
    for path in PACKAGE.glob("*.py"):
        text = path.read_text()
        if marker in text:
            moved[_module_name(path)] = text.split(marker)[1].split('"')[1]
    return moved


def layer_violations(graph: dict[str, set[str]], old: set[str]) -> list[str]:
    """Each import of a module of a higher layer, or of an old path, as a sentence."""
    wrong = []
    for name, targets in sorted(graph.items()):
        if name in old:
            continue
        for target in sorted(targets):
            if target in old:
                wrong.append(f"{name} imports the old path {target}")
            elif layer(target) > layer(name):
                wrong.append(
                    f"{name} ({LAYERS[layer(name)][0]}) imports {target} "
                    f"({LAYERS[layer(target)][0]})"
                )
    return wrong


def test_the_graph_sees_the_imports_it_should():
    graph = import_graph()
    # module level, relative two levels up, and a submodule named by ``from pkg import name``
    assert "cpopt.problem" in graph["cpopt.flatopt.transcribe"]
    assert "cpopt.model.flat" in graph["cpopt.problem.gamma"]
    # inside a function (cli imports its stages late so that --version stays fast)
    assert "cpopt.isolate" in graph["cpopt.cli"]


def test_find_cycle_finds_one():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set()}) is None


def test_layer_violations_are_found():
    graph = {
        "cpopt.model.flat": {"cpopt.verify.simulate"},
        "cpopt.verify.simulate": {"cpopt.model.flat", "cpopt.flat"},
        "cpopt.tracking.dfl": {"cpopt.closedform.plan"},
        "cpopt.tracking.run": {"cpopt.problem"},
        "cpopt.problem": {"cpopt.tracking.dfl", "cpopt.tracking.run"},
        "cpopt.flat": {"cpopt.model.flat"},
    }
    assert layer_violations(graph, {"cpopt.flat"}) == [
        "cpopt.model.flat (model) imports cpopt.verify.simulate (verify)",
        "cpopt.problem (problem) imports cpopt.tracking.run (planners)",
        "cpopt.verify.simulate imports the old path cpopt.flat",
    ]


def test_imports_go_one_way_through_the_layers():
    violations = layer_violations(import_graph(), set(moved_modules()))
    assert not violations, "\n".join(violations)


def test_the_top_level_holds_the_application_and_old_paths_only():
    top = {
        name
        for name in _modules()
        if name.count(".") <= 1 and not (PACKAGE / name.split(".")[-1]).is_dir()
    }
    assert top - set(moved_modules()) == APPLICATION


@pytest.mark.parametrize("package", ["io", "runtime", "model", "closedform", "verify"])
def test_each_layer_package_says_what_it_owns_and_may_import(package):
    doc = importlib.import_module(f"cpopt.{package}").__doc__
    assert doc and "import" in doc


@pytest.mark.parametrize("old", sorted(moved_modules()))
def test_an_old_path_warns_and_is_the_new_module(old):
    new = moved_modules()[old]
    sys.modules.pop(old, None)  # imported as if for the first time: the old path warns again
    with pytest.warns(DeprecationWarning, match=f"{old} moved to {new}"):
        module = importlib.import_module(old)
    assert module is importlib.import_module(new)


def test_no_import_cycle_in_cpopt():
    cycle = find_cycle(import_graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


@pytest.mark.parametrize("name", sorted(_modules()))
def test_no_module_over_700_lines(name):
    lines = len(_modules()[name].read_text().splitlines())
    assert lines <= MAX_LINES, f"{name}: {lines} lines (split it: one job per module)"
