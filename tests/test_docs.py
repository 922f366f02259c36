"""The README and docs/problems.md run as written; public functions are documented."""

import importlib
import inspect
import pkgutil
import re
from pathlib import Path

import pytest
import yaml

import cpopt
from cpopt.problem import parse_problem

ROOT = Path(__file__).resolve().parent.parent


def _blocks(path: Path, lang: str) -> list[str]:
    return re.findall(rf"```{lang}\n(.*?)```", path.read_text(), re.S)


def test_readme_python_example_runs(capsys):
    (code,) = _blocks(ROOT / "README.md", "python")
    exec(compile(code, "README.md", "exec"), {})
    out = capsys.readouterr().out.split()
    assert out[0] == "solved"
    assert float(out[1]) == pytest.approx(12953.3, rel=1e-4)
    assert float(out[2]) < 1e-8


@pytest.mark.parametrize("doc", ["README.md", "docs/problems.md"])
def test_yaml_examples_validate(doc):
    blocks = _blocks(ROOT / doc, "yaml")
    assert blocks
    for block in blocks:
        parse_problem(yaml.safe_load(block), doc)


def test_readme_commands_name_real_things():
    text = (ROOT / "README.md").read_text()
    (install_run, install_test) = _blocks(ROOT / "README.md", "bash")[:2]
    assert "cpopt solve problems/paper_swing_up.yaml" in install_run
    assert (ROOT / "problems" / "paper_swing_up.yaml").exists()
    ci = (ROOT / ".ci" / "run").read_text()
    assert install_test.strip() in ci  # CI runs exactly the README's test command
    assert "docs/problems.md" in text


def _public_functions():
    for info in pkgutil.iter_modules(cpopt.__path__):
        module = importlib.import_module(f"cpopt.{info.name}")
        for name, obj in vars(module).items():
            if name.startswith("_") or getattr(obj, "__module__", None) != module.__name__:
                continue
            if inspect.isfunction(obj) or inspect.isclass(obj):
                yield f"{module.__name__}.{name}", obj
                if inspect.isclass(obj):
                    for mname, meth in vars(obj).items():
                        if inspect.isfunction(meth) and not mname.startswith("_"):
                            yield f"{module.__name__}.{name}.{mname}", meth


def test_every_public_function_has_a_docstring():
    missing = [name for name, obj in _public_functions() if not inspect.getdoc(obj)]
    assert not missing, f"no docstring: {missing}"
