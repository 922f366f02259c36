"""The wheel: bundled problems are package data, so ``cpopt list`` works from an install."""

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from cpopt.problem import bundled_problems

ROOT = Path(__file__).resolve().parent.parent


def test_bundled_problems_are_found_through_the_package():
    files = bundled_problems()
    assert [p.name for p in files] == sorted(p.name for p in (ROOT / "problems").glob("*.yaml"))
    assert files[0].parent == ROOT / "cpopt" / "problems"  # the package's link to problems/
    assert (ROOT / "cpopt" / "problems").resolve() == (ROOT / "problems").resolve()


@pytest.mark.slow
def test_cpopt_list_from_a_wheel(tmp_path):
    build = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", str(ROOT), "--no-deps", "-q", "-w", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert build.returncode == 0, build.stderr[-2000:]
    (wheel,) = tmp_path.glob("cpopt-*.whl")
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    names = sorted(p.name for p in (site / "cpopt" / "problems").glob("*.yaml"))
    assert names == sorted(p.name for p in (ROOT / "problems").glob("*.yaml"))
    listed = subprocess.run(
        [sys.executable, "-m", "cpopt", "list"],
        capture_output=True,
        text=True,
        cwd=tmp_path,  # away from the checkout
        env={"PYTHONPATH": str(site), "PATH": "/usr/bin:/bin"},
        timeout=120,
    )
    assert listed.returncode == 0, listed.stderr
    assert "paper_swing_up.yaml" in listed.stdout and "invalid" not in listed.stdout
    assert len(listed.stdout.splitlines()) == len(names)
