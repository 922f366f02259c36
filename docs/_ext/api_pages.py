"""The Python API reference pages, written from the package itself when the site is built.

One page per layer (``docs/api/<layer>.rst``, not kept in git), each module documented by
autodoc from its numpydoc docstrings, so a module added later is in the reference without
anyone listing it. The old module paths kept for one release are left out.
"""

from __future__ import annotations

import importlib
import pkgutil
from pathlib import Path

LAYERS = (
    (
        "cpopt",
        "The Python API and the application",
        "What ``import cpopt`` gives (``load``, ``solve``, ``track``, ``replan``, ``Problem``, "
        "``Solution``) and the application on top: the planner registry, results, files, "
        "figures, the command line.",
        (
            "cpopt",
            "cpopt.api",
            "cpopt.solution",
            "cpopt.replanning",
            "cpopt.results",
            "cpopt.pipeline",
            "cpopt.isolate",
            "cpopt.plotting",
            "cpopt.mujoco_render",
            "cpopt.cli",
        ),
    ),
    ("problem", "Problem files", None, ()),
    ("model", "The arm model", None, ()),
    ("closedform", "Plans and the closed form", None, ()),
    ("verify", "Verification", None, ()),
    ("flatopt", "The flat optimizer", None, ()),
    ("collocation", "Direct collocation", None, ()),
    ("tracking", "Tracking", None, ()),
    ("sweep", "Sweeps", None, ()),
    ("urdf", "URDF", None, ()),
    ("io", "Input and output", None, ()),
    ("runtime", "Run-time support", None, ()),
)


def _moved(name: str) -> bool:
    """An old path kept for one release (it replaces itself by the new module)."""
    spec = importlib.util.find_spec(name)
    text = Path(spec.origin).read_text()
    return "sys.modules[__name__] = importlib.import_module(" in text


def _modules(package: str) -> list[str]:
    module = importlib.import_module(package)
    names = [package]
    for info in pkgutil.walk_packages(module.__path__, prefix=package + "."):
        if info.name.endswith("__main__"):
            continue
        names.append(info.name)
    return names


def _page(key: str, title: str, intro: str | None, modules: tuple[str, ...]) -> str:
    if not modules:
        modules = tuple(_modules(f"cpopt.{key}"))
        intro = f":mod:`cpopt.{key}`: see the package's own description below."
    lines = [title, "=" * len(title), "", intro or "", ""]
    for name in modules:
        lines += [name, "-" * len(name), "", f".. automodule:: {name}"]
        # cpopt's names are documented where they are defined (cpopt.api, cpopt.solution, ...)
        lines += ["   :no-members:", ""] if name == "cpopt" else [""]
    return "\n".join(lines)


def write(docs: Path) -> None:
    """Write ``docs/api/index.rst`` and one page per layer, only where the text changed."""
    out = docs / "api"
    out.mkdir(exist_ok=True)
    pages = {"index": _index()}
    for key, title, intro, modules in LAYERS:
        pages[key] = _page(key, title, intro, modules)
    for name, text in pages.items():
        path = out / f"{name}.rst"
        if not path.exists() or path.read_text() != text:
            path.write_text(text)


def _index() -> str:
    lines = [
        "Python API reference",
        "====================",
        "",
        "Generated from the numpydoc docstrings, one page per package, from the application "
        "down to the layers it builds on (see :doc:`../layout`).",
        "",
        ".. toctree::",
        "   :maxdepth: 1",
        "",
    ]
    lines += [f"   {key}" for key, *_ in LAYERS]
    return "\n".join(lines) + "\n"
