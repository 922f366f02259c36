"""The arm's limits, defined once (cpopt.model.limits), checked on the plan of every planner."""

import json
import textwrap
from pathlib import Path

import numpy as np
import pytest

from cpopt.cli import main
from cpopt.model.limits import Limit, arm_limits, violations
from cpopt.model.robot import paper_arm
from cpopt.problem import LimitsSpec, ProblemError, load_problem, read_problem

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


# --- torque headroom: the plan keeps (1 - h) of each motor's limit -------------------------

TORQUE_LIMITED = PROBLEMS / "swing_up_torque_limited.yaml"


def test_headroom_tightens_the_plans_torque_limits_only():
    arm = paper_arm((1.0, 1.0, 0.5))
    spec = LimitsSpec(torque=[120, 50], torque_headroom=0.2, joint_velocity=[None, None, 720])
    tau1, tau2, qd3 = arm_limits(spec, arm)
    assert (tau1.lower, tau1.upper, tau1.rated, tau1.headroom) == pytest.approx(
        (-96.0, 96.0, 120.0, 0.2)
    )
    assert tau2.upper == pytest.approx(40.0) and tau2.rated == pytest.approx(50.0)
    assert tau1.label == "|tau1| <= 96 (120 less 20 % headroom)"
    assert qd3.upper == pytest.approx(4 * np.pi)  # velocity limits keep no headroom
    # a pair per joint; a single value applies to the joints that have a limit
    pair = arm_limits(LimitsSpec(torque=[120, 50], torque_headroom=[0.1, 0.0]), arm)
    assert [lim.upper for lim in pair] == pytest.approx([108.0, 50.0])
    assert pair[1].label == "|tau2| <= 50"
    one = arm_limits(LimitsSpec(torque=[None, 50], torque_headroom=0.5), arm)
    assert [(lim.joint, lim.upper) for lim in one] == [(1, 25.0)]


@pytest.mark.parametrize(
    ("overrides", "key", "words"),
    [
        ({"optimizer.limits.torque_headroom": 1.0}, "optimizer.limits.torque_headroom",
         "not a fraction in [0, 1)"),
        ({"optimizer.limits.torque_headroom": "20 %"}, "optimizer.limits.torque_headroom",
         "expected a number h or a pair [h1, h2] (fractions 0 <= h < 1), got '20 %'"),
        ({"optimizer.limits.torque_headroom": [0.1, 0.1, 0.1]},
         "optimizer.limits.torque_headroom", "expected a number h or a pair [h1, h2]"),
        ({"optimizer.limits.torque_headroom": [0.2, -0.1]},
         "optimizer.limits.torque_headroom[1]", "not a fraction in [0, 1)"),
        ({"optimizer.limits.torque": [120, None], "optimizer.limits.torque_headroom": [0, 0.2]},
         "optimizer.limits.torque_headroom[1]", "optimizer.limits.torque[1] is given"),
        ({"optimizer.limits.torque": [None, None], "optimizer.limits.torque_headroom": 0.2},
         "optimizer.limits.torque_headroom", "no torque limit is given"),
    ],
)  # fmt: skip
def test_headroom_is_validated_with_its_key_path(overrides, key, words):
    with pytest.raises(ProblemError) as err:
        read_problem(TORQUE_LIMITED, overrides)
    assert err.value.path == key
    assert words in err.value.message


def test_headroom_must_leave_the_holding_torque():
    # the paper's swing-up hangs at rest at the start on 14.38 N m of joint 2 (no free values)
    limits = {"optimizer.limits.torque": [120, 50]}
    read_problem(
        PROBLEMS / "paper_swing_up.yaml", {**limits, "optimizer.limits.torque_headroom": 0.7}
    )
    with pytest.raises(ProblemError) as err:
        read_problem(
            PROBLEMS / "paper_swing_up.yaml",
            {**limits, "optimizer.limits.torque_headroom": [0, 0.75]},
        )
    assert err.value.path == "optimizer.limits.torque_headroom[1]"
    assert err.value.message == (
        "|tau2| <= 50 N m less 75 % headroom cannot even hold the arm at rest at motion.start: "
        "the static holding torque there is 14.38 N m"
    )


def test_a_bad_headroom_exits_2_naming_the_file_and_key(tmp_path, capsys):
    path = tmp_path / "limited.yaml"
    limited = "torque: [120, 50]"
    text = TORQUE_LIMITED.read_text().replace(limited, f"{limited}\n    torque_headroom: 1.5")
    path.write_text(text)
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert f"{path}: optimizer.limits.torque_headroom: 1.5 is not a fraction in [0, 1)" in err
    assert "Traceback" not in err


@pytest.fixture(scope="module")
def with_headroom():
    """The torque-limited swing-up planned with 20 % headroom, and tracked on a plant whose
    links 1 and 2 are 10 % heavier (motors at the full limits, 120 N m and 50 N m)."""
    from cpopt.pipeline import solve

    links = load_problem(TORQUE_LIMITED).spec.arm.links
    heavier = [{"mass": links[0].mass * 1.1}, {"mass": links[1].mass * 1.1}, None]
    problem = read_problem(
        TORQUE_LIMITED,
        {
            "optimizer.limits.torque_headroom": 0.2,
            "tracking": {"controller": "tvlqr", "plant": {"links": heavier}},
        },
    )
    return solve(problem)


def test_a_plan_with_headroom_keeps_it_and_costs_more(with_headroom):
    sol = with_headroom
    assert sol.status == "solved", sol.message
    m = sol.metrics
    # within 1e-4 of 0.8 x the limits (the flat optimizer keeps 2e-3 inside on its samples)
    assert m.peak_torque[0] <= 96.0 * (1 + 1e-4) and m.peak_torque[1] <= 40.0 * (1 + 1e-4)
    assert m.peak_torque == pytest.approx((96.0, 40.0), rel=3e-3)  # and it uses them
    assert m.torque_limit == (120.0, 50.0) and m.torque_headroom == (0.2, 0.2)
    assert m.torque_usage == pytest.approx((0.8, 0.8), rel=3e-3)
    doc = m.as_dict()
    assert doc["torque_headroom"] == [0.2, 0.2] and doc["torque_limit"] == [120.0, 50.0]
    # h = 0 costs 3173.3 N^2 m^2 s (tests/optimal_costs.json); 20 % headroom 13.4 % more
    assert m.torque_sq_integral == pytest.approx(3600.1, rel=2e-3)
    stored = json.loads((Path(__file__).parent / "optimal_costs.json").read_text())
    assert m.torque_sq_integral > 1.13 * stored["swing_up_torque_limited"]["torque_sq_integral"]


def test_the_tracking_plant_saturates_at_the_full_limit(with_headroom):
    tracked = with_headroom.tracking.summary()
    # on the heavier arm the feedback takes 108 N m, more than the plan's 96 N m and within
    # the motor's 120 N m: the plant is not limited to the plan's bound
    assert tracked["success"] and tracked["saturated_fraction"] == 0.0
    assert tracked["peak_torque"][0] == pytest.approx(108.2, abs=0.5)
    assert 96.0 < tracked["peak_torque"][0] < 120.0


def test_a_time_optimal_plan_pays_headroom_in_time():
    from cpopt.pipeline import solve

    sol = solve(read_problem(PROBLEMS / "swing_up_min_time.yaml",
                             {"optimizer.limits.torque_headroom": 0.2}))  # fmt: skip
    assert sol.status == "solved", sol.message
    assert max(sol.metrics.torque_usage) <= 0.8 * (1 + 1e-4)
    # 1.0704 s at h = 0 (tests/optimal_costs.json), 1.3437 s with 20 % headroom
    assert sol.plan.duration == pytest.approx(1.3437, rel=2e-3)


def test_the_torque_figure_draws_the_plans_bound(with_headroom):
    from cpopt.plotting import plot_torques

    fig = plot_torques(with_headroom, limits=[120, 50])
    levels = sorted({round(abs(line.get_ydata()[0]), 6) for line in fig.axes[0].lines[2:]})
    assert levels == [40.0, 50.0, 96.0, 120.0]  # the limits and 0.8 of them
