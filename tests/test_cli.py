"""The command line: solving, the output contract, exit codes and bad input."""

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import yaml

from cpopt.cli import main
from cpopt.problem import bundled_problems, load_problem, parse_problem
from cpopt.results import CSV_COLUMNS

ROOT = Path(__file__).resolve().parent.parent

GOOD = textwrap.dedent("""\
    name: good
    arm:
      kind: RRR
      links:
        - {length: 1.5, mass: 10.0}
        - {length: 1.5, mass: 5.0}
        - {length: 1.0, mass: 1.0}
    motion:
      duration: 1.0
      start: {x: 0.75, y: 1.0, theta_deg: 90}
      via:
        - {t: 0.5, x: 1.25, y: 1.0, theta_deg: 90, xi: 0.5}
      goal: {x: 1.75, y: 1.0, theta_deg: 90}
    """)


OPT = GOOD + textwrap.dedent("""\
    planner: optimize
    optimizer:
      gamma_min: 2.0
      free:
        start.xi: [-40, 40]
    """)


def _write(tmp_path, text, name="p.yaml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_all_bundled_problems_validate():
    files = bundled_problems()
    names = {p.stem for p in files}
    assert {"paper_transfer", "paper_transfer_slow", "paper_swing_up"} <= names
    kinds = {load_problem(p).arm.kind for p in files}
    assert kinds == {"RRR", "RPR", "PRR", "PPR"}
    assert main(["check", *map(str, files)]) == 0


def test_solve_writes_the_output_contract(tmp_path, capsys):
    path = _write(tmp_path, GOOD)
    assert main(["solve", str(path), "--out", str(tmp_path / "out"), "--plot", "--animate"]) == 0
    line = capsys.readouterr().out
    assert line.startswith("good: solved")
    out = tmp_path / "out" / "good"
    doc = json.loads((out / "solution.json").read_text())
    assert set(doc) == {
        "name",
        "status",
        "planner",
        "duration_s",
        "metrics",
        "verification",
        "solver",
        "free_values",
        "cpopt_version",
    }
    assert doc["status"] == "solved" and doc["planner"] == "closed_form"
    assert doc["duration_s"] == 1.0
    assert {
        "torque_sq_integral",
        "abs_power_integral",
        "peak_torque",
        "min_abs_gamma",
        "theta_min_deg",
        "theta_max_deg",
        "max_torque_jump",
    } <= set(doc["metrics"])
    assert set(doc["metrics"]["torque_jumps"]) == {"via[0]", "start", "goal"}
    assert {"max_cp_error", "final_state_error", "passive_torque_residual"} <= set(
        doc["verification"]
    )
    assert doc["verification"]["max_cp_error"] < 1e-8
    assert {"iterations", "build_time_s", "solve_time_s", "message"} <= set(doc["solver"])
    header = (out / "trajectory.csv").read_text().splitlines()[0]
    assert tuple(header.split(",")) == CSV_COLUMNS
    table = np.loadtxt(out / "trajectory.csv", delimiter=",", skiprows=1)
    assert table.shape == (2 * 401, 20)
    np.testing.assert_allclose(table[[0, -1], 0], [0.0, 1.0])
    for png in ("third_link", "arm", "torques", "gamma"):
        assert (out / f"{png}.png").stat().st_size > 5000
    assert (out / "arm.gif").read_bytes()[:6] == b"GIF89a"
    assert not list(out.glob(".*tmp*"))


def test_failed_solve_exit_1_writes_status_and_no_trajectory(tmp_path, capsys):
    # the paper's remark: a one-phase swing-up with x_s = x_g runs into gamma = 0
    singular = GOOD.replace(
        """  via:
    - {t: 0.5, x: 1.25, y: 1.0, theta_deg: 90, xi: 0.5}
""",
        "",
    ).replace("x: 1.75, y: 1.0, theta_deg: 90}", "x: 0.75, y: 1.0, theta_deg: 90, xi: -20}")
    singular = singular.replace("theta_deg: 90}", "theta_deg: -90}", 1)
    path = _write(tmp_path, singular)
    out = tmp_path / "out"
    (out / "good").mkdir(parents=True)
    (out / "good" / "trajectory.csv").write_text("stale")
    assert main(["solve", str(path), "--out", str(out)]) == 1
    doc = json.loads((out / "good" / "solution.json").read_text())
    assert doc["status"] == "singular"
    assert "gamma vanishes" in doc["solver"]["message"]
    assert not (out / "good" / "trajectory.csv").exists()


def test_list_shows_bundled_problems(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    assert "paper_swing_up.yaml" in out and "PPR" in out


BAD = [
    # (case, edit of GOOD or full text, expected key path, expected words)
    (
        "wrong type",
        GOOD.replace("duration: 1.0", "duration: fast"),
        "motion.duration",
        "valid number",
    ),
    (
        "string number",
        GOOD.replace("mass: 5.0", "mass: '5.0'"),
        "arm.links[1].mass",
        "valid number",
    ),
    (
        "unknown key",
        GOOD.replace("theta_deg: 90}", "theta_dg: 90}", 1),
        "motion.start.theta_dg",
        "did you mean 'theta_deg'",
    ),
    ("unknown top key", GOOD + "planer: closed_form\n", "planer", "did you mean 'planner'"),
    ("missing key", GOOD.replace("  duration: 1.0\n", ""), "motion.duration", "missing"),
    (
        "negative mass",
        GOOD.replace("mass: 10.0", "mass: -10.0"),
        "arm.links[0].mass",
        "greater than 0",
    ),
    (
        "zero length",
        GOOD.replace("length: 1.0", "length: 0"),
        "arm.links[2].length",
        "greater than 0",
    ),
    ("two links", GOOD.replace("    - {length: 1.0, mass: 1.0}\n", ""), "arm.links", "at least 3"),
    ("bad kind", GOOD.replace("kind: RRR", "kind: RRP"), "arm.kind", "'RRR'"),
    (
        "bad branch",
        GOOD.replace("kind: RRR", "kind: RRR\n  branch: left"),
        "arm.branch",
        "elbow_up",
    ),
    ("unreachable", GOOD.replace("x: 1.75", "x: 3.5"), "motion.goal", "not reachable"),
    (
        "unreachable via",
        GOOD.replace("x: 1.25, y: 1.0", "x: 0.0, y: 0.0"),
        "motion.via[0]",
        "not reachable",
    ),
    ("gamma zero", GOOD.replace("theta_deg: 90}", "theta_deg: 0}", 1), "motion.start.xi", "gamma"),
    ("gamma sign change", GOOD.replace("xi: 0.5}", "xi: -20}"), "motion.via[0].xi", "changes sign"),
    (
        "gamma zero after a xi reset",
        GOOD.replace("xi: 0.5}", "xi: 0.5, xi_after: -9.81}"),
        "motion.via[0].xi_after",
        "singular",
    ),
    (
        "gamma sign change after a xi reset",
        GOOD.replace("xi: 0.5}", "xi: 0.5, xi_after: -20}"),
        "motion.via[0].xi_after",
        "xi_after >= -7.81",
    ),
    (
        "gamma sign against a fixed gamma",
        GOOD + "planner: optimize\noptimizer: {gamma_sign: [positive, negative]}\n",
        "optimizer.gamma_sign[1]",
        "fixes gamma = 10.3",
    ),
    (
        "no switches",
        GOOD.replace("x: 1.75, y: 1.0, theta_deg: 90}", "x: 1.75, y: 1.0, theta_deg: -90}")
        + "planner: optimize\noptimizer: {gamma_switches: 0}\n",
        "motion.goal.xi",
        "optimizer.gamma_switches",
    ),
    (
        "too few switches",
        GOOD.replace("theta_deg: 90, xi: 0.5}", "theta_deg: -90}")
        + "planner: optimize\noptimizer: {gamma_switches: 1}\n",
        "optimizer.gamma_switches",
        "change sign 2 times",
    ),
    (
        "switches with path_timing",
        GOOD + "planner: optimize\noptimizer: {gamma_switches: auto, curve: path_timing}\n",
        "optimizer.gamma_switches",
        "path_timing",
    ),
    (
        "switches with the closed form",
        GOOD + "optimizer: {gamma_switches: 1}\n",
        "optimizer.gamma_switches",
        "planner: optimize",
    ),
    (
        "switches not a count",
        GOOD + "planner: optimize\noptimizer: {gamma_switches: some}\n",
        "optimizer.gamma_switches",
        "'auto'",
    ),
    ("via time outside", GOOD.replace("t: 0.5", "t: 1.5"), "motion.via[0].t", "(0, 1)"),
    ("via time zero", GOOD.replace("t: 0.5", "t: 0.0"), "motion.via[0].t", "inside"),
    (
        "nan",
        GOOD.replace("y: 1.0, theta_deg: 90}", "y: .nan, theta_deg: 90}", 1),
        "motion.start.y",
        "finite",
    ),
    (
        "boolean number",
        GOOD.replace("duration: 1.0", "duration: true"),
        "motion.duration",
        "valid number",
    ),
    (
        "list not mapping",
        GOOD.replace("start: {x: 0.75, y: 1.0, theta_deg: 90}", "start: [0.75, 1.0, 90]"),
        "motion.start",
        "dictionary",
    ),
    (
        "bad poles",
        GOOD + "verification: {poles: [-1, -2, 3, -4]}\n",
        "verification.poles[2]",
        "less than 0",
    ),
    ("bad planner", GOOD + "planner: magic\n", "planner", "closed_form"),
    ("malformed yaml", GOOD.replace("kind: RRR", "kind: [RRR"), "", "malformed YAML at line"),
    # a name is one folder under --out, never a path
    ("name climbs out", GOOD.replace("name: good", "name: ../../escaped"), "name", "--out"),
    ("name absolute", GOOD.replace("name: good", "name: /tmp/escaped"), "name", "--out"),
    ("name dot-dot", GOOD.replace("name: good", "name: '..'"), "name", "no '/', '.' or '..'"),
    ("name with slash", GOOD.replace("name: good", "name: a/b"), "name", "--out"),
    # physics refused before any work
    (
        "gamma_min zero",
        OPT.replace("gamma_min: 2.0", "gamma_min: 0"),
        "optimizer.gamma_min",
        "singular",
    ),
    ("absurd mass", GOOD.replace("mass: 10.0", "mass: 1e9"), "arm.links[0].mass", "physical range"),
    ("absurd length", GOOD.replace("length: 1.0", "length: 2.0e4"), "arm.links[2].length", "range"),
    (
        "absurd duration",
        GOOD.replace("duration: 1.0", "duration: 1e-3").replace("t: 0.5", "t: 5e-4"),
        "motion.duration",
        "physical range",
    ),
    (
        "centre of percussion at infinity",
        GOOD.replace("{length: 1.0, mass: 1.0}", "{length: 1.0, mass: 1.0, com: 1.0e-6}"),
        "arm.links[2].com",
        "centre of percussion",
    ),
    # bounds in order, guesses inside them, limits that can hold the arm
    (
        "reversed joint limits",
        OPT.replace(
            "gamma_min: 2.0",
            "gamma_min: 2.0\n  limits: {joint_position: [[170, -170], null, null]}",
        ),
        "optimizer.limits.joint_position[0]",
        "exceeds upper bound",
    ),
    (
        "reversed free bounds",
        OPT.replace("start.xi: [-40, 40]", "start.xi: [40, -40]"),
        "optimizer.free.start.xi",
        "exceeds upper bound",
    ),
    (
        "guess outside its bounds",
        OPT.replace("start.xi: [-40, 40]", "start.xi: [1, 40]"),
        "optimizer.free.start.xi",
        "motion.start.xi = 0 lies outside",
    ),
    (
        "torque limit cannot hold the start",
        OPT.replace("gamma_min: 2.0", "gamma_min: 2.0\n  limits: {torque: [1, null]}"),
        "optimizer.limits.torque[0]",
        "cannot even hold the arm at rest at motion.start",
    ),
    # messages that point at the right key
    (
        "unit left out",
        GOOD.replace("theta_deg: 90}", "theta: 90}", 1),
        "motion.start.theta",
        "'theta_deg'",
    ),
    (
        "free name without unit",
        OPT.replace("start.xi: [-40, 40]", "start.theta: [-100, 100]"),
        "optimizer.free.start.theta",
        "did you mean 'start.theta_deg'",
    ),
    (
        "nan bound of a free value",
        OPT.replace("start.xi: [-40, 40]", "start.xi: [.nan, 40]"),
        "optimizer.free.start.xi[0]",
        "finite",
    ),
    (
        "gamma sign wrong at the start",
        GOOD.replace("theta_deg: 90}", "theta_deg: 90, xi: -20}", 1),
        "motion.start.xi",
        "changes sign",
    ),
    (
        "gamma sign wrong because of gravity",
        GOOD.replace("xi: 0.5}", "xi: -8}").replace("kind: RRR", "kind: RRR\n  gravity: 5"),
        "arm.gravity",
        "changes sign",
    ),
    (
        "branch none on a 3R arm",
        GOOD.replace("kind: RRR", "kind: RRR\n  branch: none"),
        "arm.branch",
        "elbow_up",
    ),
    (
        "degree too high",
        OPT.replace("gamma_min: 2.0", "gamma_min: 2.0\n  degree: 15"),
        "optimizer.degree",
        "16",
    ),
    (
        "duplicate key",
        GOOD.replace("  duration: 1.0", "  duration: 1.0\n  duration: 2.0"),
        "motion.duration",
        "duplicate key",
    ),
    ("long value", GOOD.replace("kind: RRR", "kind: " + "R" * 100_000), "arm.kind", "RRR..."),
    ("empty file", "", "", "empty document"),
    ("scalar document", "42\n", "", "expected a mapping"),
]


@pytest.mark.parametrize("case,text,key,words", BAD, ids=[b[0] for b in BAD])
def test_bad_input_exit_2_with_key_path(tmp_path, capsys, case, text, key, words):
    path = _write(tmp_path, text)
    for verb in ("check", "solve"):
        code = main(
            [verb, str(path), "--out", str(tmp_path / "o")]
            if verb == "solve"
            else [verb, str(path)]
        )
        err = capsys.readouterr().err
        assert code == 2, err
        assert f"{path}: {key}:" in err if key else f"{path}:" in err
        assert words in err, err
        assert "Traceback" not in err
        assert len(err) < 2000  # no megabytes of echoed input
    assert not (tmp_path / "o").exists()
    assert list(tmp_path.iterdir()) == [path]
    assert not (tmp_path.parent / "escaped").exists() and not Path("/tmp/escaped").exists()


def test_directory_and_missing_file(tmp_path, capsys):
    assert main(["check", str(tmp_path)]) == 2
    assert "is a directory" in capsys.readouterr().err
    assert main(["solve", str(tmp_path / "nope.yaml")]) == 2
    assert "no such file" in capsys.readouterr().err


def test_real_command_line_prints_no_traceback(tmp_path):
    path = _write(tmp_path, GOOD.replace("mass: 10.0", "mass: -1"))
    run = subprocess.run(
        [sys.executable, "-m", "cpopt.cli", "check", str(path)],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert run.returncode == 2
    assert "arm.links[0].mass" in run.stderr and "Traceback" not in run.stderr
    run = subprocess.run(
        [sys.executable, "-m", "cpopt.cli", "frobnicate"], capture_output=True, text=True, cwd=ROOT
    )
    assert run.returncode == 2 and "Traceback" not in run.stderr


def test_a_file_name_becomes_a_safe_problem_name(tmp_path, capsys):
    path = _write(tmp_path, GOOD.replace("name: good\n", ""), name="my problem (v2).yaml")
    assert main(["check", str(path)]) == 0
    assert "(my_problem__v2_: RRR arm" in capsys.readouterr().out
    unnamed = yaml.safe_load(GOOD.replace("name: good\n", ""))
    assert parse_problem(unnamed, name="../up").name == "_up"  # one folder, never a path


def test_a_xi_reset_makes_a_sign_change_between_phases_legal():
    """gamma +10.31 on arrival at the via state, -10.19 after its xi reset, -9.81 at the goal
    (theta = -90 deg): each phase keeps one sign, so the file is accepted."""
    text = GOOD.replace("xi: 0.5}", "xi: 0.5, xi_after: -20}").replace(
        "x: 1.75, y: 1.0, theta_deg: 90}", "x: 1.75, y: 1.0, theta_deg: -90}"
    )
    problem = parse_problem(yaml.safe_load(text))
    arrive, leave = problem.gamma_sides
    assert [round(s.gamma, 2) for s in arrive] == [9.81, 10.31, -9.81]
    assert leave[1].gamma == pytest.approx(-10.19) and leave[1].path == "motion.via[0].xi_after"


def test_a_freed_reset_without_a_file_value_starts_from_the_value_on_arrival(tmp_path, capsys):
    """``via[0].xi_after`` freed with no ``xi_after`` in the file: its guess is the via state's
    xi (found by review: the bounds check compared None with a number, a traceback)."""
    text = OPT.replace("start.xi: [-40, 40]", "via[0].xi_after: [-5, 5]")
    assert main(["check", str(_write(tmp_path, text))]) == 0, capsys.readouterr().err
    text = OPT.replace("start.xi: [-40, 40]", "via[0].xi_after: [1, 5]")
    assert main(["check", str(_write(tmp_path, text))]) == 2
    assert "the initial guess motion.via[0].xi_after = 0.5 lies outside" in capsys.readouterr().err
