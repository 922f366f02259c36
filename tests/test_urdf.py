"""Arms from URDF files and back (``arm: {urdf: ...}``, ``cpopt export-urdf``): the round trip
gives the same plan, a CAD-style file gives the paper's arm, and every file that is not a
planar cpopt arm is refused naming the joint or link, with exit code 2 from the command line."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import PROBLEMS

import cpopt
from cpopt.cli import main
from cpopt.problem import ProblemError, load_problem, parse_problem
from cpopt.urdf import JOINTS, UrdfError, arm_urdf, parse_urdf, urdf_arm

KINDS = {
    "RRR": "paper_swing_up",
    "RPR": "rpr_transfer",
    "PRR": "prr_swing_up",
    "PPR": "ppr_transfer",
}
"""A bundled problem of each arm kind."""


def _times(solution, n: int = 201) -> np.ndarray:
    return np.linspace(0.0, solution.plan.duration, n)


def _through_urdf(problem, tmp_path):
    """The problem with its arm written as URDF and read back (limits kept as the file's)."""
    path = tmp_path / f"{problem.name}.urdf"
    path.write_text(problem.to_urdf())
    data = yaml.safe_load(Path(problem.source).read_text())
    arm = data["arm"]
    data["arm"] = {"urdf": path.name, "joints": list(JOINTS)}
    data["arm"].update({k: arm[k] for k in ("gravity", "branch") if k in arm})
    copy = tmp_path / f"{problem.name}.yaml"
    copy.write_text(yaml.safe_dump(data))
    return load_problem(copy)


@pytest.mark.parametrize("kind", list(KINDS))
def test_round_trip_gives_the_same_arm_and_plan(kind, tmp_path):
    problem = load_problem(PROBLEMS / f"{KINDS[kind]}.yaml")
    back = _through_urdf(problem, tmp_path)
    assert back.arm.kind == kind
    for a, b in zip(problem.arm.links, back.arm.links, strict=True):
        assert [a.length, a.mass, a.d, a.I] == pytest.approx(
            [b.length, b.mass, b.d, b.I], abs=1e-15
        )
    first, second = cpopt.solve(problem), cpopt.solve(back)
    assert first.ok and second.ok
    t = _times(first)
    x, y = first.sample(t), second.sample(t)
    assert np.max(np.abs(x.q - y.q)) < 1e-9
    assert np.max(np.abs(x.tau - y.tau)) < 1e-9


@pytest.mark.slow
def test_round_trip_of_an_optimized_plan_with_torque_limits(tmp_path):
    problem = load_problem(PROBLEMS / "swing_up_torque_limited.yaml")
    back = _through_urdf(problem, tmp_path)
    assert back.limits == problem.limits  # the file's own limits; the efforts say the same
    first, second = cpopt.solve(problem), cpopt.solve(back)
    assert first.ok and second.ok
    t = _times(first)
    assert np.max(np.abs(first.sample(t).tau - second.sample(t).tau)) < 1e-9


def test_a_cad_style_file_is_the_papers_arm():
    """Links hanging at q = 0, a pitched frame, a reversed elbow axis, fixed mount and tool
    frames: the bundled urdf_swing_up.yaml plans exactly what paper_swing_up.yaml plans."""
    via_urdf = load_problem(PROBLEMS / "urdf_swing_up.yaml")
    paper = load_problem(PROBLEMS / "paper_swing_up.yaml")
    for a, b in zip(via_urdf.arm.links, paper.arm.links, strict=True):
        assert [a.length, a.mass, a.d, a.I] == pytest.approx(
            [b.length, b.mass, b.d, b.I], abs=1e-15
        )
    assert [lim.upper for lim in via_urdf.limits] == [400.0, 200.0]  # the efforts
    found = urdf_arm(parse_urdf((PROBLEMS / "arms/rrr_hanging.urdf").read_text()))
    assert found.sign == (1.0, -1.0, 1.0)
    assert found.offset == pytest.approx((-math.pi / 2, 0.0, 0.0), abs=1e-15)
    first, second = cpopt.solve(via_urdf), cpopt.solve(paper)
    t = _times(first)
    assert np.max(np.abs(first.sample(t).tau - second.sample(t).tau)) < 1e-9


# --- variants of one exported file, each refused naming what is wrong ------------------------


def _paper_urdf(torque=(None, None)) -> ET.Element:
    text = arm_urdf(load_problem(PROBLEMS / "paper_swing_up.yaml").arm, torque)
    return ET.fromstring(text)


def _find(root: ET.Element, tag: str, name: str) -> ET.Element:
    (element,) = [e for e in root.findall(tag) if e.get("name") == name]
    return element


def _set_origin(joint: ET.Element, xyz: str | None = None, rpy: str | None = None) -> None:
    origin = joint.find("origin")
    if xyz is not None:
        origin.set("xyz", xyz)
    if rpy is not None:
        origin.set("rpy", rpy)


def _arm(root: ET.Element, joints=JOINTS):
    return urdf_arm(parse_urdf(ET.tostring(root, encoding="unicode"), "arm.urdf"), joints)


def test_cad_pi_is_within_tolerance_and_an_antiparallel_axis_keeps_its_sign():
    root = _paper_urdf()
    # roll by 3.1416 about x turns the frame upside down: the elbow's axis 0 -1 0 is now +y
    _set_origin(_find(root, "joint", "joint2"), rpy="3.1416 0 0")
    joint3 = _find(root, "joint", "joint3")
    joint3.find("axis").set("xyz", "0 1 0")  # in the flipped frame: -y in the world
    found = _arm(root)
    assert found.sign == (1.0, -1.0, 1.0)
    assert found.links[1]["length"] == pytest.approx(1.5, abs=1e-9)


def _tilted(root):
    """The elbow's frame rolled by 0.01 rad, its axis written 0 -1 0 all the same (the wrist's
    frame rolled back, so the plane's normal stays horizontal)."""
    _set_origin(_find(root, "joint", "joint2"), rpy="0.01 0 0")
    _set_origin(_find(root, "joint", "joint3"), rpy="-0.01 0 0")


def _fourth(root):
    _find(root, "joint", "joint3").set("name", "joint3")
    extra = ET.SubElement(root, "link", name="link4")
    joint = ET.SubElement(root, "joint", name="joint4", type="revolute")
    ET.SubElement(joint, "parent", link="link3")
    ET.SubElement(joint, "child", link="link4")
    ET.SubElement(joint, "axis", xyz="0 -1 0")
    return extra


def _floating(root):
    _find(root, "joint", "joint1").set("type", "floating")


def _mimic(root):
    ET.SubElement(_find(root, "joint", "joint2"), "mimic", joint="joint1")


def _branch(root):
    ET.SubElement(root, "link", name="camera")
    joint = ET.SubElement(root, "joint", name="camera_mount", type="fixed")
    ET.SubElement(joint, "parent", link="link1")
    ET.SubElement(joint, "child", link="camera")


def _no_inertial(root):
    link = _find(root, "link", "link2")
    link.remove(link.find("inertial"))


def _zero_mass(root):
    _find(root, "link", "link3").find("inertial/mass").set("value", "0")


def _zero_inertia(root):
    _find(root, "link", "link1").find("inertial/inertia").set("iyy", "0")


def _no_passive(root):
    transmission = ET.SubElement(root, "transmission", name="t3")
    ET.SubElement(transmission, "joint", name="joint3")


def _wrong_passive(root):
    root.remove(_find(root, "transmission", "joint1_transmission"))


def _zero_effort(root):
    ET.SubElement(_find(root, "joint", "joint2"), "limit", effort="0", velocity="1")


def _normal_along_gravity(root):
    for name in JOINTS:
        _find(root, "joint", name).find("axis").set("xyz", "0 0 1")


def _com_off_the_line(root):
    _find(root, "link", "link2").find("inertial/origin").set("xyz", "0.75 0 0.01")


def _slide_out_of_plane(root):
    joint = _find(root, "joint", "joint2")
    joint.set("type", "prismatic")
    joint.find("axis").set("xyz", "0 1 0")
    ET.SubElement(joint, "limit", effort="10", velocity="1")


REFUSALS = {
    "a tilted axis": (_tilted, "joint 'joint2' turns about"),
    "a fourth moving joint": (_fourth, "joint 'joint4' is a fourth moving joint"),
    "a floating joint": (_floating, "joint 'joint1' is floating"),
    "a mimic joint": (_mimic, "joint 'joint2' mimics another joint"),
    "a branch": (_branch, "link 'link1' is a branch"),
    "a missing inertial": (_no_inertial, "link 'link2' has no <inertial>"),
    "mass 0": (_zero_mass, "link 'link3' has mass 0 kg"),
    "inertia 0": (_zero_inertia, "link 'link1' has mass 1 kg and inertia"),
    "no passive joint": (_no_passive, "joint 'joint3' is actuated"),
    "the wrong passive joint": (_wrong_passive, "joint 'joint1' is passive (no <transmission>"),
    "effort 0 on an actuated joint": (_zero_effort, "joint 'joint2' is passive (its effort"),
    "the plane not vertical": (_normal_along_gravity, "perpendicular to gravity"),
    "a centre of mass off the link": (_com_off_the_line, "link 'link2' has its centre of mass"),
    "a slide out of the plane": (_slide_out_of_plane, "joint 'joint2' slides along"),
}


@pytest.mark.parametrize("case", list(REFUSALS))
def test_what_is_not_a_planar_cpopt_arm_is_refused_by_name(case):
    change, said = REFUSALS[case]
    root = _paper_urdf()
    change(root)
    with pytest.raises(UrdfError) as err:
        _arm(root)
    assert said in str(err.value)
    assert str(err.value).startswith("arm.urdf: ")


def test_joints_in_another_order_or_missing_are_refused():
    root = _paper_urdf()
    with pytest.raises(
        UrdfError, match=r"passes the moving joints \['joint1', 'joint2', 'joint3'\]"
    ):
        _arm(root, ["joint2", "joint1", "joint3"])
    with pytest.raises(UrdfError, match="no joint named 'elbow'"):
        _arm(root, ["joint1", "elbow", "joint3"])


# --- through problem files and the command line ----------------------------------------------


def _problem(tmp_path, arm: str, extra: str = "") -> str:
    text = (PROBLEMS / "paper_swing_up.yaml").read_text()
    start, end = text.index("arm:"), text.index("motion:")
    path = tmp_path / "p.yaml"
    path.write_text(text[:start] + arm + text[end:] + extra)
    return str(path)


def test_a_bad_urdf_exits_2_naming_file_key_and_joint(tmp_path, capsys):
    root = _paper_urdf()
    _tilted(root)
    (tmp_path / "arms").mkdir()
    (tmp_path / "arms/bad.urdf").write_text(ET.tostring(root, encoding="unicode"))
    path = _problem(tmp_path, "arm: {urdf: arms/bad.urdf, joints: [joint1, joint2, joint3]}\n")
    assert main(["check", path]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert err.startswith(f"error: {path}: arm.urdf: ")
    assert "joint 'joint2' turns about" in err and "bad.urdf" in err


@pytest.mark.parametrize(
    ("arm", "key", "said"),
    [
        ("arm: {urdf: nope.urdf}\n", "arm.urdf", "cannot read the URDF"),
        ("arm: {urdf: a.urdf, kind: RRR}\n", "arm.kind", "which gives its kind"),
        ("arm: {urdf: a.urdf, mass: 3}\n", "arm.mass", "unknown key beside urdf"),
        ("arm: {urdf: a.urdf, joints: [a, b]}\n", "arm.joints", "at least 3 items"),
        ("arm: {urdf: 3}\n", "arm.urdf", "valid string"),
    ],
)
def test_bad_urdf_keys_name_their_key_path(tmp_path, arm, key, said):
    with pytest.raises(ProblemError) as err:
        load_problem(_problem(tmp_path, arm))
    assert err.value.path == key
    assert said in err.value.message


def test_export_urdf_writes_a_file_the_problem_reads_back(tmp_path, capsys):
    out = tmp_path / "arm.urdf"
    assert (
        main(["export-urdf", str(PROBLEMS / "swing_up_torque_limited.yaml"), "--out", str(out)])
        == 0
    )
    assert "wrote" in capsys.readouterr().out
    problem = load_problem(_problem(tmp_path, f"arm: {{urdf: {out.name}, branch: elbow_up}}\n"))
    assert [lim.upper for lim in problem.limits] == [120.0, 50.0]  # the efforts, no limits given
    assert main(["export-urdf", str(PROBLEMS / "paper_swing_up.yaml")]) == 0
    assert capsys.readouterr().out.startswith('<?xml version="1.0"?>')


def test_the_problems_own_torque_limits_win_over_efforts(tmp_path):
    out = tmp_path / "arm.urdf"
    out.write_text(arm_urdf(load_problem(PROBLEMS / "paper_swing_up.yaml").arm, (120.0, 50.0)))
    extra = "optimizer:\n  limits:\n    torque: [300, null]\n"
    problem = load_problem(_problem(tmp_path, "arm: {urdf: arm.urdf}\n", extra))
    assert [lim.upper for lim in problem.limits] == [300.0]


def test_load_takes_the_urdf_by_key_path(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "arm.urdf").write_text(load_problem(PROBLEMS / "rpr_transfer.yaml").to_urdf())
    data = yaml.safe_load((PROBLEMS / "rpr_transfer.yaml").read_text())
    data["arm"] = {"urdf": "nothing.urdf"}
    problem = cpopt.load(data, **{"arm.urdf": "arm.urdf"})  # relative to the working folder
    assert problem.arm == load_problem(PROBLEMS / "rpr_transfer.yaml").arm.__class__(
        **{**problem.arm.__dict__}
    )
    assert problem.arm.kind == "RPR"
    assert problem.replace(**{"motion.duration": 2.0}).arm == problem.arm


def test_a_sweep_over_a_urdf_problem_finds_the_file_from_any_folder(tmp_path, monkeypatch):
    from cpopt.sweep.spec import build_points, parse_vary

    folder = tmp_path / "study"
    (folder / "arms").mkdir(parents=True)
    (folder / "arms/arm.urdf").write_text(
        (PROBLEMS / "arms/rrr_hanging.urdf").read_text(encoding="utf-8")
    )
    base = folder / "base.yaml"
    base.write_text((PROBLEMS / "urdf_swing_up.yaml").read_text().replace(
        "arms/rrr_hanging.urdf", "arms/arm.urdf"
    ))  # fmt: skip
    monkeypatch.chdir(tmp_path)  # not the problem's folder
    points = build_points(str(base.relative_to(tmp_path)), [parse_vary("motion.duration=1.6,1.7")])
    assert [p.data["arm"]["urdf"] for p in points] == [str(folder / "arms/arm.urdf")] * 2
    monkeypatch.chdir(PROBLEMS)  # wherever a worker runs
    assert parse_problem(points[1].data, "point").arm.links[1].length == pytest.approx(1.5)


@pytest.mark.parametrize("kind", list(KINDS))
def test_any_base_centre_of_mass_and_inertia_survive_the_round_trip(kind):
    from dataclasses import replace

    from cpopt.model.robot import Link

    arm = load_problem(PROBLEMS / f"{KINDS[kind]}.yaml").arm
    links = (Link(1.3, 2.5, 0.4, 0.21), Link(0.9, 1.5, 0.7, 0.08), Link(0.8, 0.4, 0.35, 0.011))
    arm = replace(arm, base=(0.3, -0.2), links=links)
    found = urdf_arm(parse_urdf(arm_urdf(arm)))
    assert found.kind == kind
    assert found.base == pytest.approx((0.3, -0.2), abs=1e-15)
    for a, b in zip(arm.links, found.links, strict=True):
        assert [a.length, a.mass, a.d, a.I] == pytest.approx(
            [b["length"], b["mass"], b["com"], b["inertia"]], abs=1e-15
        )
    assert found.sign == (1.0, 1.0, 1.0)
    assert found.offset == pytest.approx((0.0, 0.0, 0.0), abs=1e-15)
