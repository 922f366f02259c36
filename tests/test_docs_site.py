"""The documentation site builds from the repository with warnings as errors (as CI builds it).

``sphinx-build -W --keep-going -b html docs <dir>``: the problem-file reference is generated from
the pydantic schema and the API reference from the docstrings, so a key or a module added
without documentation, a broken cross-reference or a malformed docstring fails here.
"""

import subprocess
import sys
from pathlib import Path

import pytest

from cpopt.problem.schema import ProblemSpec

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("site")
    argv = [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html"]
    done = subprocess.run(
        [*argv, "docs", str(out)], cwd=ROOT, capture_output=True, text=True, timeout=600
    )
    assert done.returncode == 0, (done.stdout + done.stderr)[-4000:]
    return out


def test_the_site_builds_without_warnings(site):
    for page in ("index", "getting_started", "method", "benchmarks", "problems", "sweeps"):
        assert (site / f"{page}.html").is_file(), page


def test_the_problem_reference_has_every_key_of_the_schema(site):
    text = (site / "problem_reference.html").read_text()
    for key in ProblemSpec.model_fields:
        assert f">{key}<" in text, key


def test_the_api_reference_documents_the_public_api(site):
    text = (site / "api" / "cpopt.html").read_text()
    for name in ("cpopt.api.load", "cpopt.api.solve", "cpopt.api.track", "cpopt.solution.Solution"):
        assert f'id="{name}"' in text, name


def test_the_notebooks_are_rendered(site):
    books = sorted(p.stem for p in (ROOT / "notebooks").glob("*.ipynb"))
    assert books
    for book in books:
        assert (site / "notebooks" / f"{book}.html").is_file(), book
