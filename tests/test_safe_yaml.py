"""Hostile files: devices, FIFOs, huge files, alias bombs, deep nesting, duplicate keys.

Each is refused by ``cpopt check`` with exit 2, one message naming the file (and the key path
where there is one), no traceback; the subprocess timeout guards against a hang.
"""

import os
import subprocess
import sys
from pathlib import Path

import pytest
from test_cli import GOOD

from cpopt.cli import main
from cpopt.io.safe_yaml import MAX_BYTES, YamlInputError, parse_yaml
from cpopt.problem import load_problem

ROOT = Path(__file__).resolve().parent.parent

BOMB = "a: &a [x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"{k}: &{k} [{', '.join([f'*{p}'] * 9)}]\n" for p, k in zip("abcdefgh", "bcdefghi", strict=True)
)


def _check(path) -> subprocess.CompletedProcess:
    """``cpopt check`` in a fresh interpreter, as a user runs it."""
    return subprocess.run(
        [sys.executable, "-m", "cpopt.cli", "check", str(path)],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=60,
    )


def _refused(run, words: str, key: str = "") -> None:
    assert run.returncode == 2, run.stderr
    assert words in run.stderr, run.stderr
    assert f": {key}: " in run.stderr if key else True, run.stderr
    assert "Traceback" not in run.stderr
    assert len(run.stderr) < 1000 and run.stdout == ""


def test_device_is_refused_without_reading():
    _refused(_check("/dev/zero"), "not a regular file")


def test_fifo_without_writer_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "p.yaml"
    os.mkfifo(fifo)
    _refused(_check(fifo), "not a regular file")


def test_file_over_the_size_cap_is_refused(tmp_path):
    path = tmp_path / "huge.yaml"
    path.write_text(GOOD + "#" * MAX_BYTES)
    _refused(_check(path), "limit for problem files")


@pytest.mark.parametrize(
    "text, key, words",
    [
        (GOOD + BOMB, "f[0]", "with aliases expanded"),
        (GOOD + "deep: " + "[" * 100_000, "deep" + "[0]" * 20, "nested deeper than 20"),
        (GOOD.replace("mass: 5.0", "mass: 5.0, mass: 6.0"), "arm.links[1].mass", "duplicate key"),
        (GOOD + "loop: &l [1, *l]\n", "loop[1]", "names no complete anchor"),
        (GOOD + "x: " + "9" * 5000 + "\n", "", "malformed YAML"),
        (GOOD + "x: !!python/object:os.system ls\n", "", "malformed YAML"),
        ("a: 1\n---\nb: 2\n", "", "one YAML document"),
        ("a: \x01\n", "", "malformed YAML"),
    ],
    ids=["alias bomb", "deep nesting", "duplicate key", "recursive alias", "huge integer",
         "python tag", "two documents", "control characters"],
)  # fmt: skip
def test_hostile_content_is_refused_with_key_path(tmp_path, capsys, text, key, words):
    path = tmp_path / "p.yaml"
    path.write_text(text, encoding="utf-8")
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert words in err and "Traceback" not in err, err
    assert f"{path}: {key}: " in err if key else f"{path}: " in err
    assert len(err) < 1000


def test_non_utf8_file_is_refused(tmp_path, capsys):
    path = tmp_path / "p.yaml"
    path.write_bytes(GOOD.encode() + b"\xff\xfe")
    assert main(["check", str(path)]) == 2
    assert "not UTF-8" in capsys.readouterr().err


def test_numbers_without_a_dot_are_numbers():
    data = parse_yaml("a: 1e-8\nb: 1e9\nc: -2E+3\nd: .5e1\ne: 12\nf: '1e9'\ng: 1e9x\n")
    assert data == {"a": 1e-8, "b": 1e9, "c": -2000.0, "d": 5.0, "e": 12, "f": "1e9", "g": "1e9x"}
    assert isinstance(data["e"], int)


def test_scientific_notation_and_branch_none_are_accepted(tmp_path):
    text = (ROOT / "problems" / "rpr_transfer.yaml").read_text()
    text = text.replace("kind: RPR", "kind: RPR\n  branch: none").replace("mass: 4.0", "mass: 4e0")
    path = tmp_path / "p.yaml"
    path.write_text(text + "optimizer:\n  solver: {tol: 1e-9, max_iter: 1e2}\n")
    problem = load_problem(path)
    assert problem.spec.optimizer.solver.tol == 1e-9
    assert problem.spec.optimizer.solver.max_iter == 100  # a whole float where a count goes
    assert problem.arm.links[0].mass == 4.0 and problem.arm.branch is None


def test_anchors_and_merge_keys_still_work():
    data = parse_yaml("base: &b {x: 1, y: 2}\nother:\n  <<: *b\n  x: 3\nlist: [*b, *b]\n")
    assert data["other"] == {"x": 3, "y": 2} and data["list"] == [{"x": 1, "y": 2}] * 2


def test_parse_errors_carry_their_key_path():
    with pytest.raises(YamlInputError) as err:
        parse_yaml("motion:\n  via:\n    - {t: 1, t: 2}\n")
    assert err.value.path == "motion.via[0].t"
    assert "first at line 3" in err.value.message
