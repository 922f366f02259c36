"""The path_timing curve family: the paper's transfer on a straight line (minimum torque and
minimum time under torque limits), a B-spline path, and the validation of the path block.

The costs of the bundled problems are in ``tests/optimal_costs.json`` (``tests/test_optimize.py``
checks them, their verification and their certificate).
"""

import copy
from pathlib import Path

import numpy as np
import pytest
import yaml

from cpopt.cli import main
from cpopt.closedform.bspline import SplineBasis
from cpopt.closedform.trajectory import sample
from cpopt.model import flat
from cpopt.pipeline import solve
from cpopt.problem import ProblemError, load_problem, parse_problem

PROBLEMS = Path(__file__).resolve().parent.parent / "problems"
CP_HEIGHT = 1.0 + 2.0 / 3.0  # the transfer's CP: y + K with K = 2 l3 / 3 = 2/3 m


@pytest.fixture(scope="module")
def straight():
    return solve(load_problem(PROBLEMS / "transfer_straight_line.yaml"))


@pytest.fixture(scope="module")
def min_time():
    return solve(load_problem(PROBLEMS / "transfer_min_time_on_path.yaml"))


def _on_the_line(sol) -> None:
    traj = sample(sol.plan, per_phase=2001)
    assert np.abs(traj.cp[:, 1, 0] - CP_HEIGHT).max() < 1e-9
    assert np.abs(traj.cp[:, 1, 1:]).max() < 1e-8  # and so are its derivatives
    assert np.diff(traj.cp[:, 0, 0]).min() > -1e-12  # forward only: s' >= 0
    curve = sol.plan.phases[0].curve
    rate = curve.timing_law(np.linspace(curve.t0, curve.t1, 2001), 1)[:, 1]
    assert rate.min() > -1e-9


def test_straight_line_transfer_keeps_the_cp_on_the_line(straight, paper_solutions):
    assert straight.status == "solved", straight.message
    _on_the_line(straight)
    # the line pins the freed xi and eta at 0: they would tilt y'' and y''' off it
    for name, value in straight.plan.free_values.items():
        assert abs(value) < 1e-6, name
    # the paper's closed form runs the same line with a 7th-degree polynomial: 114075
    assert straight.metrics.torque_sq_integral < 0.95 * (
        paper_solutions["paper_transfer"].metrics.torque_sq_integral
    )
    # on a horizontal line gamma^2 = (L s'')^2 + g0^2: certified exactly, g0 at rest
    assert straight.solver.details.certified_min_abs_gamma == pytest.approx(9.81, abs=1e-9)


def test_minimum_time_on_the_line_rides_the_torque_limits(min_time):
    assert min_time.status == "solved", min_time.message
    _on_the_line(min_time)
    tau = np.abs(sample(min_time.plan, per_phase=4001).tau).max(axis=0)
    assert np.all(tau <= np.array([400.0, 100.0]) * (1 + 1e-4))
    assert tau[0] > 0.99 * 400.0 and tau[1] > 0.99 * 100.0  # both limits are reached
    # the paper's 1 s closed form needs 729 N m; 400 N m run the same line in 1.008 s
    assert 0.95 < min_time.plan.duration < 1.05


def test_a_b_spline_path_on_the_same_line():
    """A degree-4 B-spline path with 6 control points (2 pieces: the piece is chosen by s, and
    the plan is cut where s(t) crosses the knot) at the Greville abscissae of the line: it is
    the line with the same parametrisation as the Bezier one, so the optimum is the same
    (both solved on 21 samples, to be quick)."""
    data = load_problem(PROBLEMS / "transfer_straight_line.yaml").spec.model_dump()
    data["optimizer"].update(samples=21, free={})
    line = solve(parse_problem(data))
    knots = SplineBasis(4, 6).knots
    greville = [knots[i + 1 : i + 5].mean() for i in range(6)]
    data["optimizer"]["path"][0].update(
        degree=4, control_points=[[0.75 + float(g), CP_HEIGHT] for g in greville]
    )
    sol = solve(parse_problem(data))
    assert sol.status == "solved", sol.message
    _on_the_line(sol)
    assert sol.plan.phases[0].curve.breaks.size - 1 == 12  # 11 timing pieces, one cut
    assert sol.solver.objective == pytest.approx(line.solver.objective, rel=1e-6)


BASE = yaml.safe_load((PROBLEMS / "transfer_straight_line.yaml").read_text())


def _variant(change) -> dict:
    data = copy.deepcopy(BASE)
    change(data)
    return data


@pytest.mark.parametrize(
    ("change", "key", "words"),
    [
        (lambda d: d["optimizer"].pop("path"), "optimizer.path", "needs a path per phase"),
        (lambda d: d["optimizer"].update(curve="bspline"), "optimizer.path", "path_timing"),
        (
            lambda d: d["optimizer"]["path"][0]["control_points"].__setitem__(0, [0.75, 1.7]),
            "optimizer.path[0].control_points[0]",
            "start's CP is at (0.75, 1.666667) m",
        ),
        (
            lambda d: d["optimizer"]["path"][0]["control_points"].insert(1, {"x": 1, "z": 2}),
            "optimizer.path[0].control_points[1].z",
            "allowed here: x, y, bounds",
        ),
        (
            lambda d: d["optimizer"]["path"][0].update(
                degree=3, control_points=[[0.75, CP_HEIGHT]] * 2 + [[1.75, CP_HEIGHT]] * 3
            ),
            "optimizer.path[0].degree",
            "degree >= 4",
        ),
        (
            lambda d: d["optimizer"]["path"][0]["timing"].update(coefficients=9),
            "optimizer.path[0].timing.coefficients",
            "need >= 10",
        ),
        (
            lambda d: d["optimizer"]["path"][0].update(
                degree=2,
                control_points=[
                    [0.75, CP_HEIGHT],
                    {"x": 1.0, "y": CP_HEIGHT, "bounds": [[2.0, 0.0], [None, None]]},
                    [1.75, CP_HEIGHT],
                ],
            ),
            "optimizer.path[0].control_points[1].bounds[0]",
            "lower bound 2 exceeds upper bound 0",
        ),
        (
            lambda d: d["optimizer"]["path"][0].update(
                degree=2,
                control_points=[
                    [0.75, CP_HEIGHT],
                    {"x": 5.0, "y": CP_HEIGHT, "bounds": [[0.0, 2.0], [None, None]]},
                    [1.75, CP_HEIGHT],
                ],
            ),
            "optimizer.path[0].control_points[1].x",
            "the initial guess x = 5 m lies outside the bounds [0, 2]",
        ),
        (
            lambda d: d["motion"]["start"].update(ydot=0.5),
            "optimizer.path[0].control_points[1]",
            "start: the CP's first nonzero derivative there is its velocity y' = (0, 0.5), so "
            "the path must leave along (0, 1); its tangent points along (1, 0)",
        ),
    ],
)
def test_path_block_is_validated_with_key_paths(change, key, words):
    with pytest.raises(ProblemError) as err:
        parse_problem(_variant(change), "t.yaml")
    assert err.value.path == key
    assert words in err.value.message


def test_a_path_that_cannot_meet_a_node_exits_2(tmp_path, capsys):
    """xi = 2 at the inverted start tilts its acceleration to (0, 2): the CP must leave
    upwards, the line leaves along +x."""
    data = _variant(lambda d: d["motion"]["start"].update(xi=2.0))
    data["optimizer"]["free"] = {}
    path = tmp_path / "tilted.yaml"
    path.write_text(yaml.safe_dump(data))
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert "optimizer.path[0].control_points[1]: start:" in err
    assert "acceleration y'' = (0, 2), so the path must leave along (0, 1)" in err
    assert "tangent points along (1, 0)" in err
    assert "Traceback" not in err
    # docs/problems.md shows this very message
    docs = (PROBLEMS.parent / "docs" / "problems.md").read_text()
    message = err.strip().split("control_points[1]: ", 1)[1]
    assert " ".join(message.split()) in " ".join(docs.split())


def test_node_values_meet_the_plan_exactly(straight):
    """The eliminated timing coefficients hold the node conditions: the composed plan's CP
    derivatives 0..3 at the ends are the nodes' (the fourth too: the holding torque)."""
    plan = straight.plan
    for node, t in ((plan.nodes[0], plan.t0), (plan.nodes[-1], plan.t0 + plan.duration)):
        got = plan.phases[0].curve.derivatives(np.array([t]), 4)[0]
        assert np.allclose(got[:, :4], flat.output(node.state(), 2 / 3, 9.81), atol=1e-9)
        assert np.allclose(got[:, 4], 0.0, atol=1e-6)  # y'''' = alpha1 e_y, pinned at 0


def test_freed_fields_after_a_via_state_follow_its_resets():
    """After a via state, xi and eta are the values after its resets where it has them, and
    the values on arrival where it has none (found by review: a freed xi_after was taken for a
    fixed value, and a freed xi counted after a fixed reset)."""
    from cpopt.closedform.nodes import freed_fields
    from cpopt.closedform.plan import Node

    still = dict(t=1.0, x=0.75, y=1.0, theta=0.0, xdot=0.0, ydot=0.0, thetadot=0.0, eta=0.0)
    reset = Node(**still, xi=-12.0, xi_after=0.0)
    plain = Node(**still, xi=-12.0)
    assert freed_fields("via[0]", {"via[0].xi": (-40, -10)}, reset, after=True) == set()
    assert freed_fields("via[0]", {"via[0].xi": (-40, -10)}, reset) == {"xi"}
    assert freed_fields("via[0]", {"via[0].xi_after": (-5, 5)}, reset, after=True) == {"xi"}
    assert freed_fields("via[0]", {"via[0].xi": (-40, -10)}, plain, after=True) == {"xi"}
    assert freed_fields("via[0]", {"via[0].eta": (-9, 9)}, plain, after=True) == {"eta"}


def test_lower_inverse_is_scipys_with_exact_zeros_above_the_diagonal():
    from scipy.linalg import solve_triangular

    from cpopt.flatopt.path_timing import lower_inverse

    L = np.tril(np.random.default_rng(3).uniform(0.5, 2.0, (5, 5)))
    inverse = lower_inverse(L)
    assert np.allclose(inverse, solve_triangular(L, np.eye(5), lower=True), rtol=1e-14, atol=0)
    assert np.all(np.triu(inverse, 1) == 0)
    assert np.allclose(inverse @ L, np.eye(5), atol=1e-14)
