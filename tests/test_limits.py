"""The arm's limits, defined once (cpopt.limits), checked on the plan of every planner."""

import json
import textwrap
from pathlib import Path

import numpy as np
import pytest

from cpopt.cli import main
from cpopt.limits import Limit, arm_limits, violations
from cpopt.problem import LimitsSpec, load_problem
from cpopt.robot import paper_arm

PROBLEMS = Path(__file__).resolve().parent.parent / "problems"


def test_limits_are_converted_to_si_once_in_the_nlp_order():
    spec = LimitsSpec(torque=[120, None], joint_position=[None, [-170, 170], None],
                      joint_velocity=[None, None, 720])  # fmt: skip
    limits = arm_limits(spec, paper_arm((1.0, 1.0, 0.5)))
    assert [(lim.quantity, lim.joint) for lim in limits] == [("tau", 0), ("q", 1), ("qd", 2)]
    assert limits[1].upper == pytest.approx(np.radians(170))
    assert limits[2].upper == pytest.approx(4 * np.pi)
    # magnitude limits are tightened by a safety margin, position ranges are not
    assert limits[0].bounds(0.01) == pytest.approx((-118.8, 118.8))
    assert limits[1].bounds(0.01) == pytest.approx(np.radians([-170, 170]))


class _Samples:
    t = np.linspace(0.0, 1.0, 5)
    tau = np.array([[0.0, 0], [50, 0], [130, 0], [60, 0], [0, 0]])
    q = np.zeros((5, 3))
    qd = np.zeros((5, 3))


def test_a_violation_names_its_worst_place():
    limit = Limit("tau", 0, -120.0, 120.0, "|tau1| <= 120", True)
    found = violations((limit,), _Samples())
    assert len(found) == 1
    assert (found[0].t, found[0].value) == (0.5, 130.0)
    assert "|tau1| <= 120 violated at t = 0.5 s" in found[0].message()
    within = Limit("tau", 0, -130.0 * (1 - 5e-5), 130.0 * (1 - 5e-5), "|tau1| <= 130", True)
    assert violations((within,), _Samples()) == []  # 5e-5 over: within the 1e-4 tolerance


def test_a_closed_form_plan_over_its_limits_is_not_solved(tmp_path):
    text = (PROBLEMS / "paper_swing_up.yaml").read_text()
    text += textwrap.dedent("""\
        optimizer:
          limits: {torque: [120, 50]}
        """)
    path = tmp_path / "limited.yaml"
    path.write_text(text)
    problem = load_problem(path)
    assert problem.planner == "closed_form"
    assert main(["solve", str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 1
    doc = json.loads((tmp_path / "out" / problem.name / "solution.json").read_text())
    assert doc["status"] == "limits_violated"
    # the paper's swing-up peaks at 377 N m and 176 N m (three times the limits)
    assert "|tau1| <= 120 violated at t = " in doc["solver"]["message"]
    assert "|tau2| <= 50 violated at t = " in doc["solver"]["message"]
    assert doc["metrics"]["peak_torque"][0] == pytest.approx(377.1, abs=0.5)
