"""The README and the documentation pages run as written; public functions are documented."""

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
PAGES = sorted(str(p.relative_to(ROOT)) for p in (ROOT / "docs").glob("*.md"))
"""The documentation site's pages (the README's sections moved there run as they did)."""


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
        # the document's own path: a URDF named in a block is relative to it
        parse_problem(yaml.safe_load(block), str(ROOT / doc))


@pytest.mark.parametrize("doc", PAGES)
def test_yaml_examples_of_the_pages_validate(doc):
    for block in _blocks(ROOT / doc, "yaml"):
        # a page's examples are written from the repository's root, as a user there types them
        parse_problem(yaml.safe_load(block), str(ROOT / Path(doc).name))


def test_readme_commands_name_real_things():
    text = (ROOT / "README.md").read_text()
    (install_run, install_test) = _blocks(ROOT / "README.md", "bash")[:2]
    assert "cpopt solve problems/paper_swing_up.yaml" in install_run
    assert (ROOT / "problems" / "paper_swing_up.yaml").exists()
    ci = (ROOT / ".ci" / "run").read_text()
    assert install_test.strip() in ci  # CI runs exactly the README's test command
    assert "docs/problems.md" in text


def _public_functions():
    for info in pkgutil.walk_packages(cpopt.__path__, prefix="cpopt."):
        module = importlib.import_module(info.name)
        for name, obj in vars(module).items():
            if name.startswith("_") or getattr(obj, "__module__", None) != module.__name__:
                continue
            if inspect.isfunction(obj) or inspect.isclass(obj):
                yield f"{module.__name__}.{name}", obj
                if inspect.isclass(obj):
                    for mname, meth in vars(obj).items():
                        if inspect.isfunction(meth) and not mname.startswith("_"):
                            yield f"{module.__name__}.{name}.{mname}", meth


@pytest.mark.slow
@pytest.mark.parametrize("doc", [d for d in PAGES if _blocks(ROOT / d, "python")])
def test_python_examples_of_the_pages_run(doc, monkeypatch, capsys):
    monkeypatch.chdir(ROOT)
    for code in _blocks(ROOT / doc, "python"):
        exec(compile(code, doc, "exec"), {})
    assert capsys.readouterr().out.split()[0] == "solved"


def test_every_public_function_has_a_docstring():
    missing = [name for name, obj in _public_functions() if not inspect.getdoc(obj)]
    assert not missing, f"no docstring: {missing}"


def _commands():
    """Each command of the README's and the pages' bash blocks, once, without the installs (CI
    runs the test one)."""
    test_command = _blocks(ROOT / "README.md", "bash")[1].strip()
    seen = set()
    for doc in ["README.md", *PAGES]:
        for block in _blocks(ROOT / doc, "bash"):
            if block.strip() == test_command:
                continue
            for part in block.strip().split("&&"):
                part = part.strip()
                if not part.startswith("python -m pip install") and part not in seen:
                    seen.add(part)
                    yield part


def _check_lines(stdout: str, word: str, pattern: str) -> None:
    """One line starting with ``word`` per benchmark problem, each matching ``pattern``."""
    lines = [line for line in stdout.splitlines() if line.startswith(word + " ")]
    assert [line.split()[1] for line in lines] == ["transfer", "swing_up"]
    for line in lines:
        assert re.fullmatch(pattern, line), line


@pytest.mark.slow
@pytest.mark.parametrize("command", list(_commands()))
def test_readme_commands_run(command, tmp_path):
    """Run in a scratch folder that sees the repository's problems and benchmarks."""
    import shlex
    import subprocess
    import sys

    for name in ("problems", "benchmarks"):
        (tmp_path / name).symlink_to(ROOT / name)
    argv = shlex.split(command)
    if argv[0] == "python":
        argv[0] = sys.executable
    done = subprocess.run(argv, cwd=tmp_path, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-2000:]
    if "vs_collocation.py" in command:
        _check_lines(
            done.stdout,
            "RATIO",
            r"RATIO \w+ solve_time_collocation_gamma_N10/flat=[0-9.]+ "
            r"cost_flat/collocation_gamma_N20=[0-9.]+",
        )
        _check_lines(
            done.stdout,
            "RATIO_SWITCH",
            r"RATIO_SWITCH \w+ cost_flat_switch/collocation_N20=[0-9.]+ "
            r"solve_time_collocation_N10/flat_switch=[0-9.]+",
        )
        _check_lines(
            done.stdout,
            "SPEED",
            r"SPEED \w+ flat_solve=[0-9.]+ flat_cold=[0-9.]+ "
            r"collocation_gamma_N10_solve=[0-9.]+ fatrop_gamma_N10_solve=[0-9.]+",
        )
    if "end_to_end.py" in command:
        number = r"[0-9.]+"
        stages = " ".join(rf"{k}={number}" for k in ("startup", "plan", "verify", "write"))
        lines = done.stdout.splitlines()
        assert re.fullmatch(rf"E2E paper_transfer wall={number} {stages} status=solved", lines[0])
        assert re.fullmatch(rf"E2E_MEDIAN wall={number}", lines[-1])
    if "path_timing.py" in command:
        wander = [line for line in done.stdout.splitlines() if line.startswith("WANDER ")]
        assert [w.split()[1] for w in wander] == ["transfer", "swing_up"]
        number = r"[0-9.]+"
        for line in wander:
            assert re.fullmatch(
                rf"WANDER \w+ length_ratio path_timing={number} bspline={number} "
                rf"excursion_m path_timing={number} bspline={number} "
                rf"phase_excursion_m path_timing={number} bspline={number} "
                rf"cost_path_timing/bspline={number}",
                line,
            )
        # the straight line does not wander; the free B-splines leave it (0.26 m, issue 14)
        fields = dict(f.split("=") for f in wander[0].split()[3:5])
        assert float(fields["path_timing"]) == 1.0 < float(fields["bspline"])
    if "cpopt solve" in command:
        assert (tmp_path / "out").is_dir()
        assert "solved" in done.stdout
