"""Every option of every ``cpopt`` verb, given each value of a family of bad values: exit code
2, one error line naming the option and the value, no traceback, nothing written, nothing
solved.

The options are found by walking the command line's parser (:func:`cpopt.cli.make_parser`), so
an option added later is tried too; one whose kind (its ``metavar``) has no family of bad
values here fails :func:`test_every_option_has_a_family_of_bad_values`. The bad values of
``--vary KEY=SPEC`` are made from the keys of the base file, one per kind of value the schema
gives them (:func:`cpopt.problem.keytypes.key_type`).
"""

from __future__ import annotations

import argparse
import math
import socket
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest
from conftest import PROBLEMS, ROOT, forbid

from cpopt.cli import MAX_WORKERS, main, make_parser
from cpopt.io.keypath import leaves
from cpopt.io.safe_yaml import key_path, read_yaml
from cpopt.problem.keytypes import BOOLEAN, NUMBER, WORD, key_type

BASE = PROBLEMS / "swing_up_min_torque.yaml"
GOOD_SPEC = "motion.duration=1.5,2"
PLACEHOLDERS = ("{tmp}", "{port}")
"""Written in bad values, replaced in each test by its folder and a port nobody listens on."""

# --- families of bad values ------------------------------------------------------------------

NOT_NUMBERS = ("abc", "1s", "1,5", "0x10", "true", "[1]", "")
NOT_FINITE = ("nan", "-nan", "inf", "-inf", "1e999")
NOT_POSITIVE = ("0", "-0", "-1", "-1e-9")
NOT_WHOLE = ("1.5", "1e3", "2.0")


def _seconds() -> list[str]:
    """Where a positive finite number is expected."""
    return [*NOT_NUMBERS, *NOT_FINITE, *NOT_POSITIVE]


def _workers() -> list[str]:
    """Where a whole number 1..MAX_WORKERS is expected."""
    return [*NOT_NUMBERS, *NOT_FINITE, *NOT_POSITIVE, *NOT_WHOLE, str(MAX_WORKERS + 1)]


def _files() -> list[str]:
    """Where a readable YAML problem file is expected."""
    return [
        "",
        "   ",
        "{tmp}/nope.yaml",  # missing
        "{tmp}/folder",  # a directory
        "{tmp}/file/p.yaml",  # under a file
        "{tmp}/empty.yaml",
        "{tmp}/binary.yaml",  # not UTF-8
        "{tmp}/list.yaml",  # a YAML list, not a mapping
        "{tmp}/broken.yaml",  # malformed YAML
    ]


def _folders() -> list[str]:
    """Where a folder to write results into is expected."""
    return ["", "   ", "{tmp}/file", "{tmp}/file/out", "{tmp}/file/a/b"]


def _out_files() -> list[str]:
    """Where a file to write is expected: not a name, a folder, a missing folder's file."""
    return ["", "   ", "{tmp}/folder", "{tmp}/file/arm.urdf", "{tmp}/missing/arm.urdf"]


def _addresses() -> list[str]:
    """Where a Dask scheduler's address is expected: malformed, then refused."""
    hosts = ["127.0.0.1", "[::1", "host name", "-host", "tcp://"]
    ports = ["", ":", ":0", ":65536", ":abc", ":-1", ":8786:1", ":1.5"]
    malformed = [f"{h}{p}" for h in hosts[:1] for p in ports]
    malformed += [f"{h}:8786" for h in hosts[1:]]
    malformed += ["", "not-an-address", "udp://127.0.0.1:8786", "tcp://127.0.0.1:8786/path"]
    return [*malformed, "127.0.0.1:{port}", "tcp://127.0.0.1:{port}"]


def sample_keys() -> dict[str, tuple[str, object]]:
    """One key of the base file per kind of value (number, choice, text, boolean), with its
    value there."""
    found = {}
    for parts, value in leaves(read_yaml(BASE)):
        path = key_path(parts)
        kind = key_type(path)
        if kind is None or len(kind.kinds) != 1 or path == "name":
            continue
        if isinstance(value, str) and any(c in value for c in ",: "):  # prose, not a value
            continue
        (only,) = kind.kinds
        label = "choice" if only == WORD and kind.words else {WORD: "text"}.get(only, only)
        found.setdefault(label, (path, value))
    return found


def _bad_specs(label: str, good) -> list[str]:
    """SPECs a key of this kind does not take (``good`` is its value in the base file)."""
    empty = ["", ",", f"{good},", f",{good}", f"{good},,{good}", f"{good},{good}"]
    if label == NUMBER:
        other = good * 1.1 + 0.1
        words = [w for w in NOT_NUMBERS if w not in ("", "1,5")]
        listed = [*words, *NOT_FINITE, *(f"{good},{w}" for w in [*words, *NOT_FINITE])]
        ranges = [f"{w}:{other}:3" for w in [*NOT_FINITE, *words]]
        ranges += [f"{good}:{other}:{n}" for n in [*NOT_POSITIVE, *NOT_WHOLE, "10000000"]]
        ranges += [f"{good}:{other}", f"{good}:{other}:3:4", "random:1:2:3"]
        ranges += [f"random:1:2:3:{seed}" for seed in ("-1", "1.5", "abc")]
        return [*empty, *listed, *ranges]
    if label == "choice":
        return [*empty, "not-a-choice", "1", f"{good},1", f"{good},not-a-choice", "1:3:3"]
    if label == BOOLEAN:
        return [*empty, "yes", "1", f"{str(good).lower()},abc", "0:1:2", "random:0:1:2:0"]
    return [*empty, "1:3:3", "random:0:1:2:0"]  # text


def _bad_keys(path: str) -> list[str]:
    """Key paths made wrong from a good one, each with a good SPEC."""
    parts = path.split(".")
    return [
        path,  # no '='
        "=1,2",
        f"{path}.=1",
        f"{path}..x=1",
        f"{parts[0]}..{'.'.join(parts[1:])}=1,2",
        f"[0].{path}=1",
        f"{path[:-1]}=1,2",  # a typo: an unknown key
        f"{path}.x=1,2",  # a key into a number
        "arm.links[9].mass=1,2",  # past the end of a list
        "arm.links=1,2",  # a mapping's place
        "name=a,b",  # the sweep names the points
    ]


def _specs() -> list[str]:
    """Where ``KEY=SPEC`` is expected: bad keys, then bad SPECs for a key of each kind."""
    keys = sample_keys()
    assert set(keys) == {NUMBER, "choice", "text", BOOLEAN}, keys
    out = _bad_keys(keys[NUMBER][0])
    for label, (path, good) in keys.items():
        out += [f"{path}={spec}" for spec in _bad_specs(label, good)]
    return list(dict.fromkeys(out))


FAMILIES = {
    "SECONDS": _seconds,
    "N": _workers,
    "FILE": _files,
    "BASE.yaml": _files,
    "DIR": _folders,
    "OUT.urdf": _out_files,
    "ENGINE": lambda: ["", "opengl", "MuJoCo", "mujoco,matplotlib"],
    "ADDRESS": _addresses,
    "KEY=SPEC": _specs,
}
"""Bad values by the metavar of an option that takes a value."""
FLAG_VALUES = ("yes", "1", "")
"""Values given to an option that takes none (``--plot=yes``)."""

# --- the parser's verbs and options ----------------------------------------------------------

GOOD_ARGS = {
    "": {},
    "solve": {"files": str(BASE), "--out": "{tmp}/out"},
    "check": {"files": str(BASE)},
    "sweep": {"base": str(BASE), "--vary": GOOD_SPEC, "--out": "{tmp}/out"},
    "list": {},
    "export-urdf": {"file": str(BASE), "--out": "{tmp}/arm.urdf"},
}
"""A good command line of each verb (positionals by their dest, options by their flag)."""


def verbs() -> dict[str, argparse.ArgumentParser]:
    """Each verb's parser; ``""`` is the top level (``--version``)."""
    parser = make_parser()
    (sub,) = (a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {"": parser, **sub.choices}


def options(parser: argparse.ArgumentParser) -> list[argparse.Action]:
    """The options and positionals a user gives values to (not ``--help`` nor the verb)."""
    skip = (argparse._HelpAction, argparse._SubParsersAction)
    return [a for a in parser._actions if not isinstance(a, skip)]


def _name(action: argparse.Action) -> str:
    return action.option_strings[-1] if action.option_strings else action.dest


def _argv(verb: str, parser, target: argparse.Action, value: str) -> list[str]:
    """The verb's good command line with ``value`` given to ``target``."""
    good = GOOD_ARGS[verb]
    argv = [verb] if verb else []
    for action in options(parser):
        if not action.option_strings:
            argv.append(value if action is target else good[action.dest])
    for flag, given in good.items():
        if flag.startswith("-"):
            argv.append(f"{flag}={given}")
    if target.option_strings:  # after the good one: the last value of an option counts
        flag = target.option_strings[-1]
        argv.append(f"{flag}={value}" if target.nargs != 0 or value else f"{flag}=")
    return argv


@dataclass(frozen=True)
class Case:
    """One bad value given to one option."""

    verb: str
    option: str
    value: str
    argv: tuple[str, ...]


def cases() -> list[Case]:
    out = []
    for verb, parser in verbs().items():
        for action in options(parser):
            family = FLAG_VALUES if action.nargs == 0 else FAMILIES.get(action.metavar, list)()
            for value in family:
                argv = _argv(verb, parser, action, value)
                out.append(Case(verb, _name(action), value, tuple(argv)))
    return out


CASES = cases()


def test_every_option_has_a_family_of_bad_values():
    missing = [
        f"cpopt {verb} {_name(a)} (metavar {a.metavar!r})"
        for verb, parser in verbs().items()
        for a in options(parser)
        if a.nargs != 0 and a.metavar not in FAMILIES
    ]
    assert not missing, f"no family of bad values for: {missing}; add one to FAMILIES"
    assert set(GOOD_ARGS) == set(verbs()), "give each verb a good command line in GOOD_ARGS"
    tried = {(c.verb, c.option) for c in CASES}
    every = {(v, _name(a)) for v, p in verbs().items() for a in options(p)}
    assert tried == every
    assert len(CASES) > 150  # the families are not empty


# --- running a case --------------------------------------------------------------------------


def _free_port() -> int:
    """A loopback port nobody listens on (bound, then released)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _setup(tmp_path: Path) -> None:
    """The files bad values name: a folder, a plain file, files that are not problems."""
    (tmp_path / "folder").mkdir()
    (tmp_path / "file").write_text("not a folder\n")
    (tmp_path / "empty.yaml").write_text("")
    (tmp_path / "binary.yaml").write_bytes(b"\xff\xfe\x00\x01")
    (tmp_path / "list.yaml").write_text("- 1\n- 2\n")
    (tmp_path / "broken.yaml").write_text("arm: {kind: RRR\n")


def _tree(root: Path) -> dict[str, bytes | None]:
    return {
        str(p.relative_to(root)): p.read_bytes() if p.is_file() else None
        for p in sorted(root.rglob("*"))
    }


@pytest.fixture
def no_work(monkeypatch):
    """Fail a test that starts a cluster or solves a problem (refusal comes first)."""
    forbid(monkeypatch, "cpopt.sweep.engine.connect", "cpopt.isolate.solve_isolated")


def error_line(err: str) -> str:
    """The one error line of stderr: alone, or after argparse's usage lines."""
    assert "Traceback" not in err, err
    lines = err.rstrip("\n").split("\n")
    assert lines[-1].strip(), err
    errors = [line for line in lines if "error:" in line]
    assert errors == [lines[-1]], err
    if len(lines) > 1:  # argparse: its usage, then "cpopt <verb>: error: ..."
        assert lines[0].startswith("usage: cpopt"), err
        assert lines[-1].startswith("cpopt"), err
    else:
        assert lines[0].startswith("error: "), err
    return lines[-1]


def _named(line: str, case: Case, value: str) -> None:
    """The error line names the option (or, for a key path, the key) and the value."""
    key = value.partition("=")[0].strip()
    option = case.option if case.option.startswith("-") else None
    names = {n for n in (option, key if case.option == "--vary" else None) if n}
    if case.option in ("files", "base", "file"):
        names = {"FILE", "BASE.yaml", value.strip() or "''"}
    assert any(n in line for n in names) or "argument" in line, (names, line)
    shown = value.strip() if case.option != "--vary" else value.partition("=")[2].strip()
    if shown and case.option not in ("files", "base", "file") and "expected a key path" not in line:
        # any of the listed values (a sweep refuses the first point that fails), looked for
        # after the file's path, whose folder names may hold digits
        fragments = [item.split(":")[-1] or item for item in shown.split(",")] or [shown]
        said = line.rsplit(".yaml", 1)[-1]
        assert any(f in said for f in fragments) or "argument" in line, (fragments, line)


@pytest.mark.parametrize(
    "case", CASES, ids=[f"{c.verb or 'cpopt'} {c.option} {c.value}" for c in CASES]
)
def test_a_bad_value_exits_2_with_one_line_before_any_work(case, tmp_path, capsys, no_work):
    _setup(tmp_path)
    before = _tree(tmp_path)
    port = str(_free_port())
    argv = [a.replace("{tmp}", str(tmp_path)).replace("{port}", port) for a in case.argv]
    value = case.value.replace("{tmp}", str(tmp_path)).replace("{port}", port)
    code = main(argv)
    captured = capsys.readouterr()
    assert code == 2, (argv, captured.out, captured.err)
    line = error_line(captured.err)
    _named(line, case, value)
    assert captured.out == ""  # no summary, no point
    assert _tree(tmp_path) == before  # nothing written, no output folder made


# --- options that contradict each other ------------------------------------------------------

CONTRADICTIONS = {
    "a key varied twice": ["--vary", "motion.duration=1.5", "--vary", "motion.duration=2"],
    "a key spelt twice": ["--vary", "motion.duration=1.5", "--vary", " motion.duration =2"],
    "a key inside a varied one": ["--vary", "arm.links[2]=1", "--vary", "arm.links[2].mass=1,2"],
    "--time-limit and its key": ["--time-limit", "5", "--vary", "optimizer.solver.max_time=1,2"],
    "--workers and --scheduler": ["--workers", "2", "--scheduler", "127.0.0.1:8786"],
}


@pytest.mark.parametrize("words", CONTRADICTIONS.values(), ids=list(CONTRADICTIONS))
def test_options_that_contradict_each_other_exit_2(words, tmp_path, capsys, no_work):
    code = main(["sweep", str(BASE), "--vary", GOOD_SPEC, *words, "--out", str(tmp_path / "o")])
    line = error_line(capsys.readouterr().err)
    assert code == 2
    flags = {w.partition("=")[0].strip() for w in words if w.startswith("--")}
    keys = {w.partition("=")[0].strip() for w in words if "=" in w and not w.startswith("-")}
    assert all(f in line for f in flags if f != "--vary") and any(k in line for k in keys | flags)
    assert not (tmp_path / "o").exists()


# --- the scheduler's connection --------------------------------------------------------------


def _blackhole() -> tuple[socket.socket, list[socket.socket]]:
    """A loopback port whose listen queue is full: a connection to it is never answered."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(0)
    held = []
    for _ in range(4):  # Linux queues backlog + 1 connections; the next SYN is dropped
        client = socket.socket()
        client.settimeout(0.2)
        try:
            client.connect(server.getsockname())
        except TimeoutError:
            client.close()
            return server, held
        held.append(client)
    server.close()
    for client in held:
        client.close()
    pytest.skip("this system answers every connection to a full listen queue")


def test_a_scheduler_that_does_not_answer_is_refused_after_the_timeout():
    from cpopt.sweep.address import check_scheduler
    from cpopt.sweep.spec import SweepError

    server, held = _blackhole()
    try:
        address = f"127.0.0.1:{server.getsockname()[1]}"
        with pytest.raises(SweepError, match=r"no answer within 0\.3 s") as caught:
            check_scheduler(address, timeout=0.3)
        assert str(caught.value).startswith(f"--scheduler '{address}': ")
    finally:
        for client in held:
            client.close()
        server.close()


def test_a_listening_scheduler_passes_the_check():
    from cpopt.sweep.address import SCHEDULER_TIMEOUT, check_scheduler, parse_scheduler

    assert 1 <= SCHEDULER_TIMEOUT <= 10  # a few seconds
    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen(1)
        port = server.getsockname()[1]
        assert check_scheduler(f"127.0.0.1:{port}").url == f"tcp://127.0.0.1:{port}"
    assert parse_scheduler(" tcp://[::1]:8786 ").url == "tcp://[::1]:8786"
    assert parse_scheduler("localhost:1").url == "tcp://localhost:1"


# --- the real command line -------------------------------------------------------------------


@pytest.mark.parametrize(
    "option, words",
    [
        (["--scheduler", "not-an-address"], "no port number"),
        (["--vary", "motion.goal.x=0.1,abc"], "'abc' is not a finite number"),
    ],
)
def test_the_issues_two_commands_exit_2_with_one_line(option, words, tmp_path):
    """The two commands of issue #32, as a user types them."""
    argv = ["sweep", str(BASE), "--vary", GOOD_SPEC, *option, "--out", str(tmp_path / "o")]
    run = subprocess.run(
        [sys.executable, "-m", "cpopt", *argv], capture_output=True, text=True, cwd=ROOT
    )
    assert run.returncode == 2, run.stderr
    assert run.stderr.count("\n") == 1 and run.stderr.startswith(f"error: {option[0]} ")
    assert words in run.stderr and run.stdout == ""
    assert list(tmp_path.iterdir()) == []


def test_families_hold_what_they_say():
    """The families' values are bad for the reason given (a family that holds a good value
    would make a case that cannot fail for the right reason)."""
    for text in _seconds():
        try:
            value = float(text)
        except ValueError:
            continue
        assert not (math.isfinite(value) and value > 0), text
    assert all(not t.strip().isdigit() or not 1 <= int(t) <= MAX_WORKERS for t in _workers())
