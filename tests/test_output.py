"""Output files: folders checked before solving, whole files with the usual permissions, stale
figures cleared, one folder per name, and two runs into one folder that do not collide."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from test_cli import GOOD

from cpopt.cli import main
from cpopt.io.output import atomic_path, atomic_write
from cpopt.results import Solution, write_solution

ROOT = Path(__file__).resolve().parent.parent

# fails at once (closed form singular: a one-phase swing-up with x_s = x_g), so cheap to "solve"
SINGULAR = (
    GOOD.replace("    - {t: 0.5, x: 1.25, y: 1.0, theta_deg: 90, xi: 0.5}\n", "")
    .replace("  via:\n", "")
    .replace("theta_deg: 90}", "theta_deg: -90}", 1)
    .replace("x: 1.75, y: 1.0, theta_deg: 90}", "x: 0.75, y: 1.0, theta_deg: 90, xi: -20}")
)


def _problem(tmp_path, text=GOOD, name="p.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _unwritable(tmp_path) -> Path:
    """A folder this process cannot write into (root ignores modes; /sys refuses even root)."""
    if os.geteuid() != 0:
        folder = tmp_path / "ro"
        folder.mkdir(mode=0o555)
        return folder
    if not Path("/sys").is_dir():
        pytest.skip("no read-only folder for root here")
    return Path("/sys")


@pytest.mark.parametrize("case", ["file", "under a file", "unwritable", "name is a file", "link"])
def test_output_folder_problems_exit_2_before_solving(tmp_path, capsys, case):
    problem = _problem(tmp_path)
    target = tmp_path / "t"
    target.mkdir()
    out = {
        "file": tmp_path / "p.yaml",
        "under a file": tmp_path / "p.yaml" / "sub",
        "unwritable": _unwritable(tmp_path),
        "name is a file": tmp_path / "out",
        "link": tmp_path / "out",
    }[case]
    if case == "name is a file":
        (out / "good").parent.mkdir()
        (out / "good").write_text("a file where the problem's folder goes")
    if case == "link":
        out.mkdir()
        (out / "good").symlink_to(target, target_is_directory=True)
    assert main(["solve", str(problem), "--out", str(out)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""  # nothing was solved
    assert "Traceback" not in captured.err
    expected = {"file": "not a directory", "under a file": "not a directory"}
    expected |= {"unwritable": "cannot write", "name is a file": "not a directory"}
    expected |= {"link": "symbolic link"}
    assert expected[case] in captured.err, captured.err
    assert list(target.iterdir()) == []


def test_results_get_the_usual_permissions(tmp_path):
    old = os.umask(0o022)
    try:
        written = write_solution(Solution("p", "singular", "closed_form"), tmp_path / "p")
        atomic_write(tmp_path / "x.bin", lambda h: h.write(b"x"), binary=True)
        os.umask(0o077)
        atomic_write(tmp_path / "y.txt", lambda h: h.write("y"))
    finally:
        os.umask(old)
    assert [p.name for p in written] == ["solution.json"]
    assert (written[0].stat().st_mode & 0o777) == 0o644
    assert ((tmp_path / "x.bin").stat().st_mode & 0o777) == 0o644
    assert ((tmp_path / "y.txt").stat().st_mode & 0o777) == 0o600  # the umask decides


def test_an_interrupted_write_leaves_the_old_file_and_no_temporary(tmp_path):
    path = tmp_path / "solution.json"
    path.write_text("old")
    with pytest.raises(KeyboardInterrupt), atomic_path(path) as tmp:
        tmp.write_text("half")
        raise KeyboardInterrupt
    assert path.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["solution.json"]


def test_a_new_run_clears_the_old_figures(tmp_path, capsys):
    out = tmp_path / "out" / "good"
    out.mkdir(parents=True)
    for name in ("trajectory.csv", "third_link.png", "arm.png", "torques.png", "gamma.png"):
        (out / name).write_text("from a successful run")
    (out / "arm.gif").write_text("from a successful run")
    (out / "notes.txt").write_text("the user's")
    assert main(["solve", str(_problem(tmp_path, SINGULAR)), "--out", str(tmp_path / "out")]) == 1
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt", "solution.json"]
    assert json.loads((out / "solution.json").read_text())["status"] == "singular"


def test_two_problems_of_one_name_do_not_overwrite_each_other(tmp_path, capsys):
    first = _problem(tmp_path, SINGULAR, "a.yaml")
    second = _problem(tmp_path, SINGULAR.replace("xi: -20", "xi: -21"), "b.yaml")
    assert main(["solve", str(first), str(second), "--out", str(tmp_path / "out")]) == 2
    captured = capsys.readouterr()
    assert f"{second}: name: 'good' is also the name of {first}" in captured.err
    assert captured.out.count("good: singular") == 1  # the first one only, refused before
    assert captured.out.count("\n") == 2  # its summary and message lines


def _solve_process(problem: Path, out: Path) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "cpopt", "solve", str(problem), "--out", str(out), "--plot"],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


@pytest.mark.slow
def test_two_concurrent_runs_into_one_folder(tmp_path):
    problem = _problem(tmp_path)
    out = tmp_path / "out"
    runs = [_solve_process(problem, out) for _ in range(2)]
    results = [run.communicate(timeout=300) for run in runs]
    for run, (stdout, stderr) in zip(runs, results, strict=True):
        assert run.returncode == 0, stderr
        assert stdout.startswith("good: solved") and "Traceback" not in stderr
    folder = out / "good"
    names = sorted(p.name for p in folder.iterdir())
    assert names == sorted(
        ["solution.json", "trajectory.csv", "third_link.png", "arm.png", "torques.png", "gamma.png"]
    )
    assert json.loads((folder / "solution.json").read_text())["status"] == "solved"
    assert (folder / "trajectory.csv").read_text().count("\n") == 2 * 401 + 1
    for png in folder.glob("*.png"):
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
