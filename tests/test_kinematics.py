"""Forward and inverse kinematics of the four arm kinds."""

import numpy as np
import pytest

from cpopt.model.kinematics import (
    BRANCH_MARGIN,
    ReachError,
    branch_margin,
    forward_pose,
    inverse_derivatives,
    inverse_position,
    kinematic_functions,
)
from cpopt.model.robot import Arm, Link

ARMS = {
    ("RRR", "elbow_up"): Arm(
        "RRR", (Link(1.5, 2), Link(1.2, 1), Link(1, 0.5)), (0.1, -0.2), branch="elbow_up"
    ),
    ("RRR", "elbow_down"): Arm(
        "RRR", (Link(1.5, 2), Link(1.2, 1), Link(1, 0.5)), branch="elbow_down"
    ),
    ("RPR", None): Arm("RPR", (Link(1.2, 2), Link(1.0, 1), Link(0.8, 0.5)), (0.3, 0.1)),
    ("PRR", "forward"): Arm("PRR", (Link(0.5, 2), Link(1.0, 1), Link(0.6, 0.3)), branch="forward"),
    ("PRR", "backward"): Arm(
        "PRR", (Link(0.5, 2), Link(1.0, 1), Link(0.6, 0.3)), branch="backward"
    ),
    ("PPR", None): Arm("PPR", (Link(0.5, 2), Link(0.5, 1), Link(1, 1))),
}


def _poses(arm, n=40):
    rng = np.random.default_rng(5)
    b = np.array(arm.base)
    if arm.kind == "RRR":
        r = rng.uniform(0.5, 2.5, n)
    elif arm.kind == "PRR":
        r = rng.uniform(0.1, 0.9, n)
    else:
        r = rng.uniform(0.3, 1.5, n)
    ang = rng.uniform(-np.pi, np.pi, n)
    pts = b + np.column_stack([r * np.cos(ang), r * np.sin(ang)])
    return pts, rng.uniform(-3, 3, n)


@pytest.mark.parametrize("key", list(ARMS), ids=lambda k: f"{k[0]}-{k[1]}")
def test_inverse_then_forward_is_identity(key):
    arm = ARMS[key]
    pts, theta = _poses(arm)
    for p, th in zip(pts, theta, strict=True):
        q = inverse_position(arm, p[0], p[1], th)
        np.testing.assert_allclose(forward_pose(arm, q[0]), [p[0], p[1], th], atol=1e-10)
        if arm.kind == "RRR":
            assert (np.sin(q[0, 1]) < 0) == (arm.branch == "elbow_up")
        if arm.kind == "PRR":
            assert (np.cos(q[0, 1]) > 0) == (arm.branch == "forward")


@pytest.mark.parametrize("key", list(ARMS), ids=lambda k: f"{k[0]}-{k[1]}")
def test_velocities_and_accelerations_match_finite_differences(key):
    arm = ARMS[key]
    t = np.linspace(0, 1, 2001)
    p0, _ = _poses(arm, 1)
    s = np.column_stack(
        [p0[0, 0] + 0.1 * np.sin(2 * t), p0[0, 1] + 0.05 * np.cos(3 * t), 0.3 + 2 * t**2]
    )
    sd = np.column_stack([0.2 * np.cos(2 * t), -0.15 * np.sin(3 * t), 4 * t])
    sdd = np.column_stack([-0.4 * np.sin(2 * t), -0.45 * np.cos(3 * t), 4 + 0 * t])
    q = inverse_position(arm, s[:, 0], s[:, 1], s[:, 2], t)
    qd, qdd = inverse_derivatives(arm, q, sd, sdd)
    h = t[1] - t[0]
    np.testing.assert_allclose(np.gradient(q, h, axis=0)[5:-5], qd[5:-5], atol=1e-5)
    np.testing.assert_allclose(np.gradient(qd, h, axis=0)[5:-5], qdd[5:-5], atol=1e-4)
    assert np.abs(np.diff(q, axis=0)).max() < 0.05  # continuous along the motion (no wraps)


def test_unreachable_point_names_time_and_point():
    arm = ARMS[("RRR", "elbow_up")]
    with pytest.raises(ReachError, match=r"t = 0\.5 s.*\(3\.2, 0\.1\)"):
        inverse_position(arm, [1.0, 3.2], [0.1, 0.1], [0.0, 0.0], t=[0.0, 0.5])


def test_prismatic_reach_errors():
    with pytest.raises(ReachError, match="base"):
        inverse_position(ARMS[("RPR", None)], 0.3, 0.1, 0.0)
    with pytest.raises(ReachError, match="PRR"):
        inverse_position(ARMS[("PRR", "forward")], 0.5, 1.5, 0.0)


def test_chain_points_end_at_link_tip():
    arm = ARMS[("RRR", "elbow_up")]
    q = np.array([0.3, -0.8, 1.1])
    pts = np.asarray(kinematic_functions(arm)["points"](q))
    pose = forward_pose(arm, q)
    np.testing.assert_allclose(pts[:, 2], pose[:2], atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(pts[:, 3] - pts[:, 2]), 1.0, atol=1e-12)


@pytest.mark.parametrize("key", [k for k in ARMS if k[0] != "PPR"], ids=lambda k: f"{k[0]}-{k[1]}")
def test_the_branch_margin_is_positive_exactly_on_the_arms_branch(key):
    """Every pose the inverse map gives lies on the branch (margin > 0 away from its edge);
    the same pose reached through the other branch (RRR: -q2; PRR: pi - q2; RPR: q1 + pi and
    -q2) has a negative margin, BRANCH_MARGIN below the edge's."""
    arm = ARMS[key]
    pts, theta = _poses(arm)
    q = inverse_position(arm, pts[:, 0], pts[:, 1], theta)
    on = np.asarray(branch_margin(arm, q.T)).ravel()
    assert (on > 0).all()
    other = q.copy()
    if arm.kind == "RRR":
        other[:, 1] = -q[:, 1]
    elif arm.kind == "PRR":
        other[:, 1] = np.pi - q[:, 1]
    else:
        other[:, 0], other[:, 1] = q[:, 0] + np.pi, -q[:, 1]
    off = np.asarray(branch_margin(arm, other.T)).ravel()
    assert off == pytest.approx(-on - 2 * BRANCH_MARGIN, abs=1e-12)
    assert branch_margin(ARMS[("PPR", None)], q.T) is None
