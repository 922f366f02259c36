"""``cpopt sweep``: SPEC parsing, the grid and its validation, and sweeps on a real Dask
LocalCluster of two workers (started once for the module, used through ``--scheduler``)."""

import json
import math
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import PROBLEMS, ROOT

from cpopt.cli import main
from cpopt.io.keypath import with_values
from cpopt.io.safe_yaml import read_yaml
from cpopt.pipeline import solve
from cpopt.problem import parse_problem
from cpopt.sweep.bar import SweepBar, clock
from cpopt.sweep.plot import cost_column, write_plot
from cpopt.sweep.spec import SweepError, Vary, build_points, parse_spec, parse_vary, point_names
from cpopt.sweep.table import COLUMNS, RECORD, TABLE, read_table

TRANSFER = str(PROBLEMS / "paper_transfer.yaml")
ONE_PHASE = str(PROBLEMS / "swing_up_one_phase.yaml")


# --- SPEC parsing ---------------------------------------------------------------------------


def test_linear_spec_gives_n_evenly_spaced_values():
    assert parse_spec("1.2:2.0:5") == pytest.approx((1.2, 1.4, 1.6, 1.8, 2.0), abs=1e-15)
    assert parse_spec("0.5:0.5:1") == (0.5,)


def test_linear_spec_of_integers_with_a_whole_step_gives_integers():
    values = parse_spec("10:14:3")
    assert values == (10, 12, 14)
    assert all(isinstance(v, int) for v in values)
    assert all(isinstance(v, float) for v in parse_spec("10:14:4"))  # step 4/3


def test_list_spec_reads_yaml_scalars():
    assert parse_spec("1,2.5,1e-3") == (1, 2.5, 0.001)
    assert parse_spec("torque,duration") == ("torque", "duration")
    assert parse_spec("1.6") == (1.6,)


def test_random_spec_is_reproducible_and_in_range():
    values = parse_spec("random:1:2:50:7")
    assert values == parse_spec("random:1:2:50:7")
    assert values != parse_spec("random:1:2:50:8")
    assert len(values) == 50 and all(1 <= v < 2 for v in values)
    assert values == tuple(np.random.default_rng(7).uniform(1, 2, 50))


@pytest.mark.parametrize(
    "spec, words",
    [
        ("1:2", "a:b:n"),
        ("1:2:0", "n must be a whole number >= 1"),
        ("1:2:2.5", "n must be a whole number >= 1"),
        ("1:2:1000000000000", "n must be at most 100000"),
        ("1:x:3", "b must be a finite number"),
        ("nan:1:3", "a must be a finite number"),
        ("random:1:2:3", "random:a:b:n:seed"),
        ("random:1:2:3:-1", "seed must be a whole number >= 0"),
        ("1,,2", "separated by commas"),
        ("1,[2]", "separated by commas"),
        ("1,.inf", "not a finite number"),
    ],
)
def test_bad_spec_says_what_was_expected(spec, words):
    with pytest.raises(SweepError, match=words.replace("[", r"\[")):
        parse_spec(spec)


@pytest.mark.parametrize(
    "text, words",
    [
        ("motion.goal.x=0.1,abc", "motion.goal.x=0.1,abc: 'abc' is not a finite number"),
        ("motion.duration=true,false", "'true' is not a finite number"),
        ("motion.duration=0x10", "'0x10' is not a finite number"),
        ("motion.duration=1,nan", "each value must be a finite number, got 'nan'"),
        ("planner=optimize,1", "'1' is not one of closed_form, optimize, collocation"),
        ("planner=1:3:3", "a range gives numbers; the key takes one of closed_form, optimize"),
        ("optimizer.smooth_torque=yes", "'yes' is not true or false"),
        ("optimizer.gamma_switches=auto,2", "values of mixed kinds (numbers and words)"),
        ("nope=1,abc", "values of mixed kinds (numbers and words)"),
        ("name=a,b", "the sweep names each point after its values"),
    ],
)
def test_vary_values_are_read_as_the_key_takes_them(text, words):
    with pytest.raises(SweepError, match=re.escape(words)):
        parse_vary(text)


def test_vary_reads_numbers_choices_and_booleans_by_the_keys_type():
    assert parse_vary("optimizer.smooth_torque=True,false").values == (True, False)
    assert parse_vary("planner=optimize,collocation").values == ("optimize", "collocation")
    assert parse_vary("optimizer.gamma_switches=0:2:3").values == (0, 1, 2)
    assert parse_vary("arm.branch=elbow_up,1").values == ("elbow_up", "1")  # text stays text
    varies = [parse_vary("arm.links[2]=1"), parse_vary("arm.links[2].mass=1,2")]
    with pytest.raises(SweepError, match=r"arm.links\[2\]: also given as arm.links\[2\].mass"):
        build_points(TRANSFER, varies)
    with pytest.raises(SweepError, match=r"--time-limit 5 both set each point's optimizer\.solver"):
        build_points(TRANSFER, [parse_vary("optimizer.solver.max_time=1,2")], time_limit=5.0)


def test_vary_needs_a_key_path_an_equals_sign_and_distinct_values():
    assert parse_vary("arm.links[2].mass=1,2") == Vary("arm.links[2].mass", (1, 2))
    for text, words in [
        ("motion.duration", "expected KEY=SPEC"),
        ("[0].x=1", "key path"),
        ("motion..duration=1", "key path"),
        ("motion.duration=1,1.0", "given twice"),
    ]:
        with pytest.raises(SweepError, match=words):
            parse_vary(text)


def test_point_names_are_safe_unique_folder_names():
    varies = [Vary("arm.links[2].mass", (1, 2)), Vary("motion.goal.x", (-0.5, 1.25))]
    combos = [(1, -0.5), (1, 1.25), (2, -0.5), (2, 1.25)]
    names = point_names("t", varies, combos)
    assert names[0] == "t__arm.links_2.mass_1__motion.goal.x_-0.5"
    assert len(set(names)) == 4
    # values that agree to 6 digits are told apart by more digits
    close = Vary("motion.duration", (1.0000001, 1.0000002))
    assert point_names("t", [close], [(1.0000001,), (1.0000002,)]) == [
        "t__motion.duration_1.0000001",
        "t__motion.duration_1.0000002",
    ]
    # too long for a folder name: numbered instead
    long = Vary("a" * 120, (1, 2))
    assert point_names("t", [long], [(1,), (2,)]) == ["t__point_1", "t__point_2"]


def test_grid_is_the_full_product_first_vary_outermost():
    varies = [parse_vary("motion.duration=0.9,1.1"), parse_vary("arm.links[2].mass=1:3:3")]
    points = build_points(TRANSFER, varies)
    assert [tuple(p.values.values()) for p in points] == [
        (0.9, 1), (0.9, 2), (0.9, 3), (1.1, 1), (1.1, 2), (1.1, 3),
    ]  # fmt: skip
    assert points[4].data["arm"]["links"][2]["mass"] == 2
    assert points[4].data["motion"]["duration"] == 1.1
    assert points[4].data["name"] == points[4].name
    assert len({p.digest for p in points}) == 6
    timed = build_points(TRANSFER, varies[:1], time_limit=12.0)
    assert timed[0].data["optimizer"]["solver"]["max_time"] == 12.0


def test_a_bad_point_names_the_base_file_the_point_and_the_key_path():
    with pytest.raises(SweepError) as err:
        build_points(TRANSFER, [parse_vary("motion.duration=1,-1")])
    text = str(err.value)
    assert "paper_transfer.yaml [point 2/2: motion.duration=-1]" in text
    assert "motion.duration: input should be greater than 0" in text
    with pytest.raises(SweepError, match=r"arm.links has 3 item\(s\); no item \[3\]"):
        build_points(TRANSFER, [parse_vary("arm.links[3].mass=1,2")])


# --- progress bar and plot ------------------------------------------------------------------


def test_progress_bar_counts_and_estimates(tmp_path):
    log = tmp_path / "log.txt"
    with open(log, "w") as stream:
        bar = SweepBar(10, skipped=2, stream=stream)
        bar.begin(2)
        assert bar.eta() is None and bar.running() == 2
        bar.advance("p1", "solved")
        bar.advance("p2", "infeasible")
        assert (bar.finished, bar.failed) == (4, 1)
        assert bar.eta() >= 0
    lines = log.read_text().splitlines()
    assert len(lines) == 3  # the start, then one per point (not a terminal)
    assert "4/10 done, 1 failed, 2 running" in lines[-1] and "(p2: infeasible)" in lines[-1]
    assert (clock(17.2), clock(123), clock(3723)) == ("17 s", "2:03", "1:02:03")
    quiet = tmp_path / "quiet.txt"
    with open(quiet, "w") as stream:
        bar = SweepBar(3, stream=stream, quiet=True)
        bar.begin(1)
        bar.advance("p", "solved")
    assert quiet.read_text() == ""


def _rows(keys, grid, failed=()):
    rows = []
    for i, values in enumerate(grid):
        row = dict(zip(keys, map(str, values), strict=True), point=f"p{i}")
        row.update(status="infeasible" if i in failed else "solved", objective="")
        row.update(torque_sq_integral=str(10.0 + i), duration_s=str(1.0 + 0.1 * i))
        rows.append(row)
    return rows


@pytest.mark.parametrize("keys", [["a"], ["a", "b"], ["a", "b", "c"]])
def test_plot_is_written_for_one_two_and_more_keys(tmp_path, keys):
    grid = [tuple(range(i, i + len(keys))) for i in range(4)]
    rows = _rows(keys, grid, failed={1})
    assert cost_column(rows) == "torque_sq_integral"
    path = write_plot(tmp_path / "sweep.png", keys, rows, "t", time_optimal=len(keys) == 1)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert [p.name for p in tmp_path.iterdir()] == ["sweep.png"]  # no temporary left


# --- sweeps on a real cluster -----------------------------------------------------------------


@pytest.fixture(scope="module")
def scheduler():
    """A LocalCluster of two single-threaded workers, as ``cpopt sweep`` starts one."""
    from cpopt.sweep.engine import connect

    with connect(workers=2) as client:
        assert len(client.nthreads()) == 2
        yield client.scheduler.address


def _sweep(tmp_path, scheduler, *args, out="out"):
    argv = ["sweep", *args, "--out", str(tmp_path / out), "--quiet"]
    return main([*argv, "--scheduler", scheduler] if scheduler else argv)


def _by_point(out):
    return {row["point"]: row for row in read_table(out / TABLE)}


def test_small_grid_writes_folders_and_table(tmp_path, scheduler, capsys):
    code = _sweep(
        tmp_path, scheduler, TRANSFER, "--vary", "motion.duration=0.9,1.1",
        "--vary", "arm.links[2].mass=1,2",
    )  # fmt: skip
    out = capsys.readouterr().out
    assert code == 0, out
    assert "sweep: 4 points: 4 solved, 0 failed" in out
    rows = read_table(tmp_path / "out" / TABLE)
    header = list(rows[0])
    assert header == ["point", "motion.duration", "arm.links[2].mass", *COLUMNS[1:]]
    assert [(r["motion.duration"], r["arm.links[2].mass"]) for r in rows] == [
        ("0.9", "1"), ("0.9", "2"), ("1.1", "1"), ("1.1", "2"),
    ]  # fmt: skip
    for row in rows:
        folder = tmp_path / "out" / row["point"]
        assert row["status"] == "solved" and float(row["duration_s"]) == float(
            row["motion.duration"]
        )
        assert {p.name for p in folder.iterdir()} == {
            "problem.yaml", "solution.json", "trajectory.csv", RECORD,
        }  # fmt: skip
        document = json.loads((folder / "solution.json").read_text())
        assert document["name"] == row["point"]
        assert float(row["torque_sq_integral"]) == document["metrics"]["torque_sq_integral"]
        assert float(row["wall_time_s"]) > 0 and row["worker"]
    # a heavier third link costs more torque, a longer transfer less
    cost = {(r["motion.duration"], r["arm.links[2].mass"]): r["torque_sq_integral"] for r in rows}
    cost = {key: float(value) for key, value in cost.items()}
    assert cost[("0.9", "2")] > cost[("0.9", "1")] > cost[("1.1", "1")]
    # the point's problem file runs alone and gives the same figures
    again = parse_problem(read_yaml(tmp_path / "out" / rows[3]["point"] / "problem.yaml"))
    assert again.name == rows[3]["point"]


def test_a_row_equals_solving_that_point_alone(tmp_path, scheduler):
    assert _sweep(tmp_path, scheduler, ONE_PHASE, "--vary", "motion.duration=1.5,1.7") == 0
    data = read_yaml(ONE_PHASE)
    for row in read_table(tmp_path / "out" / TABLE):
        point = with_values(data, {"motion.duration": float(row["motion.duration"])})
        alone = solve(parse_problem(point))
        assert row["status"] == alone.status == "solved"
        assert float(row["objective"]) == pytest.approx(alone.solver.objective, rel=1e-9)
        assert float(row["torque_sq_integral"]) == pytest.approx(
            alone.metrics.torque_sq_integral, rel=1e-9
        )
        assert int(row["iterations"]) == alone.solver.iterations
        assert float(row["duration_s"]) == alone.plan.duration  # numbers as Python writes them


def test_a_failed_point_is_a_row_not_the_end_of_the_sweep(tmp_path, scheduler, capsys):
    data = read_yaml(TRANSFER)
    data["optimizer"] = {"limits": {"torque": [2000, 500]}}
    base = tmp_path / "limited.yaml"
    base.write_text(yaml.safe_dump(data))
    # the closed-form transfer needs 729 N m at joint 1: a limit of 100 N m is violated
    code = _sweep(tmp_path, scheduler, str(base), "--vary", "optimizer.limits.torque[0]=100,2000")
    assert code == 1
    assert "2 points: 1 solved, 1 failed" in capsys.readouterr().out
    rows = _by_point(tmp_path / "out")
    failed = rows["paper_transfer__optimizer.limits.torque_0_100"]
    assert failed["status"] == "limits_violated"
    assert "tau1" in failed["message"] or "torque" in failed["message"]
    assert rows["paper_transfer__optimizer.limits.torque_0_2000"]["status"] == "solved"
    folder = tmp_path / "out" / failed["point"]
    assert json.loads((folder / "solution.json").read_text())["status"] == "limits_violated"
    assert not (folder / "trajectory.csv").exists()


def test_resume_solves_only_the_missing_points(tmp_path, scheduler, capsys):
    args = [TRANSFER, "--vary", "motion.duration=0.9:1.2:4"]
    assert _sweep(tmp_path, scheduler, *args) == 0
    out = tmp_path / "out"
    before = _by_point(out)
    assert len(before) == 4
    lost = "paper_transfer__motion.duration_1"
    (out / lost / RECORD).unlink()  # as if killed before the record was written
    stamps = {name: (out / name / RECORD).stat().st_mtime_ns for name in before if name != lost}
    capsys.readouterr()
    assert _sweep(tmp_path, scheduler, *args, "--resume") == 0
    printed = capsys.readouterr().out
    assert "4 points (3 taken from earlier results): 4 solved" in printed
    assert [line.split(":")[0] for line in printed.splitlines()[:-1]] == [lost]
    assert {name: (out / name / RECORD).stat().st_mtime_ns for name in stamps} == stamps
    after = _by_point(out)
    assert list(after) == list(before)  # grid order
    for name, row in before.items():
        assert after[name]["torque_sq_integral"] == row["torque_sq_integral"]
    # the same folder for another problem (a changed base value): everything runs again
    data = read_yaml(TRANSFER)
    data["arm"]["links"][2]["mass"] = 2.0
    (tmp_path / "paper_transfer.yaml").write_text(yaml.safe_dump(data))
    other = [str(tmp_path / "paper_transfer.yaml"), *args[1:]]
    assert _sweep(tmp_path, scheduler, *other, "--resume") == 0
    assert "4 points: 4 solved" in capsys.readouterr().out
    changed = _by_point(out)
    assert all(changed[n]["problem_sha256"] != before[n]["problem_sha256"] for n in before)


def test_bad_key_path_and_bad_point_exit_2_before_any_work(tmp_path, capsys):
    # no scheduler at all: nothing may start
    code = _sweep(tmp_path, None, TRANSFER, "--vary", "motion.duraton=1,2")
    err = capsys.readouterr().err
    assert code == 2
    assert "motion.duraton: unknown key; did you mean 'duration'?" in err
    assert "Traceback" not in err and not (tmp_path / "out").exists()
    code = _sweep(tmp_path, None, TRANSFER, "--vary", "arm.links[2].mass=1,0")
    err = capsys.readouterr().err
    assert code == 2
    assert "[point 2/2: arm.links[2].mass=0]: arm.links[2].mass: input should be greater" in err
    assert _sweep(tmp_path, None, TRANSFER, "--vary", "motion.duration=1:2") == 2
    assert "expected a:b:n" in capsys.readouterr().err
    code = _sweep(tmp_path, "tcp://x", TRANSFER, "--vary", "motion.duration=1", "--workers", "2")
    assert code == 2
    assert "--scheduler uses a running one" in capsys.readouterr().err


def test_default_local_cluster_and_plot(tmp_path, capsys):
    code = _sweep(
        tmp_path, None, TRANSFER, "--vary", "motion.duration=0.9,1.1", "--workers", "2", "--plot"
    )
    assert code == 0, capsys.readouterr().err
    out = tmp_path / "out"
    assert (out / "sweep.png").read_bytes()[:4] == b"\x89PNG"
    rows = read_table(out / TABLE)
    assert [r["status"] for r in rows] == ["solved", "solved"]
    assert all(math.isfinite(float(r["max_cp_error"])) for r in rows)


def test_a_lost_workers_point_is_run_again(scheduler):
    """A worker killed while it holds the point: the scheduler runs the task on another."""
    from dask.distributed import Client

    from cpopt.sweep import engine

    points = build_points(ONE_PHASE, [parse_vary("motion.duration=1.55")])
    results = []
    with Client(scheduler) as client:
        pids = client.run(os.getpid)
        worker = threading.Thread(
            target=engine.run,
            args=(client, points, ONE_PHASE, lambda *result: results.append(result)),
        )
        worker.start()
        deadline = time.monotonic() + 30
        while not any(client.processing().values()) and time.monotonic() < deadline:
            time.sleep(0.02)
        victim = next(w for w, keys in client.processing().items() if keys)
        os.kill(pids[victim], signal.SIGKILL)
        worker.join(timeout=180)
    ((point, outcome, lost),) = results
    assert point == points[0] and lost == "" and outcome.solution.status == "solved"
    assert outcome.worker.split(":")[1] != str(pids[victim])


def _group(pgid: int) -> list[str]:
    """The live processes (not zombies waiting to be reaped) of a process group (Linux)."""
    live = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[2]) == pgid and fields[0] != "Z":
            live.append(stat.parent.name)
    return live


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_ctrl_c_keeps_finished_points_and_resume_solves_only_the_rest(tmp_path):
    """A terminal's Ctrl-C signals the whole process group (the command, its workers, their
    solver children): exit 130 with one line, the cluster gone, finished points on disk; the
    same sweep with --resume then solves only the points that had not finished."""
    command = [sys.executable, "-m", "cpopt", "sweep", ONE_PHASE, "--workers", "2"]
    command += ["--vary", "motion.duration=1.4:1.7:4", "--out", str(tmp_path / "out")]
    run = subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True
    )
    for line in run.stderr:  # not a terminal: one progress line per finished point
        if " 1/4 done" in line:
            break
    os.killpg(run.pid, signal.SIGINT)
    _, err = run.communicate(timeout=60)
    assert run.returncode == 130, err
    assert err.strip().splitlines()[-1] == "cpopt: interrupted" and "Traceback" not in err
    deadline = time.monotonic() + 10  # no worker or solver process left in the group
    while _group(run.pid) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert _group(run.pid) == []
    kept = [row["point"] for row in read_table(tmp_path / "out" / TABLE)]
    assert 1 <= len(kept) < 4
    again = subprocess.run([*command, "--resume"], capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr
    solved_now = [line.split(":")[0] for line in again.stdout.splitlines()[:-1]]
    assert len(solved_now) == 4 - len(kept) and not set(solved_now) & set(kept)
    assert f"({len(kept)} taken from earlier results): 4 solved" in again.stdout


def _table(stdout: str) -> list[str]:
    """The benchmark's table rows and ROBUST lines, without the wall times."""
    lines = stdout.split("\nplan ")[-1].splitlines()[1:]
    return [re.sub(r"\s+[0-9.]+$", "", line) for line in lines if line and "s in all" not in line]


@pytest.mark.slow
def test_robustness_benchmark_on_two_workers_gives_the_serial_figures():
    script = [sys.executable, str(ROOT / "benchmarks" / "robustness.py"), "--quick"]
    serial, dask = (
        subprocess.run(command, capture_output=True, text=True, timeout=300)
        for command in (script, [*script, "--workers", "2"])
    )
    assert serial.returncode == dask.returncode == 0, dask.stderr[-2000:]
    assert _table(dask.stdout) == _table(serial.stdout)
    assert (
        sum(line.startswith("ROBUST paper_transfer ") for line in _table(dask.stdout)) == 3
    )  # tvlqr, tvlqr_timescaled, dfl


def test_dask_is_imported_only_by_the_sweep():
    code = (
        "import sys\n"
        "from cpopt.cli import main\n"
        "main(['check', sys.argv[1]])\n"
        "print(sorted(m for m in ('dask', 'distributed') if m in sys.modules))\n"
    )
    done = subprocess.run([sys.executable, "-c", code, TRANSFER], capture_output=True, text=True)
    assert done.stdout.splitlines()[-1] == "[]", done.stderr


def test_a_signal_below_a_finalizer_counts_as_inside_it():
    """Ctrl-C landing a few calls below a ``__del__`` (asyncio's ``_write_to_self`` under
    Dask's ``Future.__del__``) is only noted, as in the ``__del__`` itself; elsewhere it is
    raised."""
    import gc

    from cpopt.sweep.engine import inside_finalizer

    seen = []

    def deep():
        seen.append(inside_finalizer(sys._getframe()))

    class Finalized:
        def __del__(self):
            deep()

    Finalized()
    gc.collect()
    deep()
    assert seen == [True, False]
