"""cpopt beside the field's engines: the figures docs/robots.md quotes (issue 33).

* Pinocchio: mass matrix, bias, gravity and RNEA of Pinocchio's model of the URDF export against
  cpopt's at random states (all four kinds), and the passive joint's torque by Pinocchio's RNEA
  along every bundled plan;
* MuJoCo: ``mj_fullM``, ``qfrc_bias`` and ``mj_inverse`` at random states, the final CP error of
  tracked plans on both engines, and the wall clock of a tracking run on each (the simulation
  alone, the controller built once; best of five);
* ``--frame PATH``: docs/robots.md's picture, the swing-up tracked by ``dfl`` on a MuJoCo plant
  whose links are 10 % heavier, with viscous friction, drawn at t = 0.95 s: the plan
  translucent, the tracked arm falling behind it (the run diverges at 1.2 s).

Run: ``python benchmarks/engines.py [--frame docs/mujoco_frame.png]`` (needs ``.[test]``).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin

import cpopt
from cpopt.model.dynamics import arm_dynamics
from cpopt.model.mujoco_arm import arm_model, arm_state, mass_matrix
from cpopt.problem import bundled_problems, load_problem
from cpopt.tracking import Plant, make_controller, track
from cpopt.tracking.mujoco_plant import simulate_mujoco
from cpopt.tracking.reference import reference
from cpopt.tracking.simulation import simulate_batch

ROOT = Path(__file__).resolve().parent.parent
KINDS = ("paper_swing_up", "rpr_transfer", "prr_swing_up", "ppr_transfer")


def configuration(model, q) -> np.ndarray:
    """Pinocchio's configuration: a continuous joint is (cos q, sin q)."""
    return np.concatenate(
        [
            [np.cos(v), np.sin(v)] if j.nq == 2 else [v]
            for j, v in zip(list(model.joints)[1:], q, strict=True)
        ]
    )


def flat(value) -> np.ndarray:
    """A CasADi result as a flat numpy array."""
    return np.asarray(value, float).ravel()


def states(kind: str, count: int = 200):
    rng = np.random.default_rng(0)
    for _ in range(count):
        q, qd, qdd = rng.normal(scale=2.0, size=(3, 3))
        if kind == "RPR":
            q[1] = 0.3 + abs(q[1])
        yield q, qd, qdd


def pinocchio_figures() -> None:
    worst = 0.0
    for name in KINDS:
        problem = load_problem(ROOT / "problems" / f"{name}.yaml")
        model = pin.buildModelFromXML(problem.to_urdf())
        model.gravity.linear = np.array([0.0, 0.0, -problem.arm.gravity])
        data, dyn = model.createData(), arm_dynamics(problem.arm)
        for q, qd, qdd in states(problem.arm.kind):
            c = configuration(model, q)
            M = pin.crba(model, data, c)
            M = np.triu(M) + np.triu(M, 1).T
            worst = max(
                worst,
                np.abs(M - np.asarray(dyn["B"](q))).max(),
                np.abs(pin.nonLinearEffects(model, data, c, qd) - flat(dyn["n"](q, qd))).max(),
                np.abs(pin.computeGeneralizedGravity(model, data, c) - flat(dyn["g"](q))).max(),
                np.abs(pin.rnea(model, data, c, qd, qdd) - flat(dyn["inverse"](q, qd, qdd))).max(),
            )
    print(f"Pinocchio, random states (4 kinds x 200): largest difference {worst:.1e}")
    passive = relative = 0.0
    for path in bundled_problems():
        problem = load_problem(path)
        solution = cpopt.solve(problem)
        model = pin.buildModelFromXML(problem.to_urdf())
        model.gravity.linear = np.array([0.0, 0.0, -problem.arm.gravity])
        data = model.createData()
        s = solution.sample(np.linspace(0.0, solution.plan.duration, 501))
        tau = np.array([pin.rnea(model, data, configuration(model, q), v, a)
                        for q, v, a in zip(s.q, s.qd, s.qdd, strict=True)])  # fmt: skip
        passive = max(passive, np.abs(tau[:, 2]).max())
        relative = max(relative, np.abs(tau[:, :2] - s.tau).max() / np.abs(s.tau).max())
    print(f"Pinocchio, {len(bundled_problems())} bundled plans: passive torque <= {passive:.1e} "
          f"N m, actuated torques agree to {relative:.1e} of the peak")  # fmt: skip


def mujoco_figures() -> None:
    worst = 0.0
    for name in KINDS:
        arm = load_problem(ROOT / "problems" / f"{name}.yaml").arm
        dyn, model = arm_dynamics(arm), arm_model(arm)
        data = mujoco.MjData(model)
        for q, qd, qdd in states(arm.kind):
            arm_state(model, data, q, qd)
            mujoco.mj_forward(model, data)
            bias = data.qfrc_bias.copy()
            M = mass_matrix(model, data)
            data.qacc[:] = qdd
            mujoco.mj_inverse(model, data)
            inverse = flat(dyn["inverse"](q, qd, qdd))
            worst = max(worst, np.abs(M - np.asarray(dyn["B"](q))).max(),
                        np.abs(bias - flat(dyn["n"](q, qd))).max(),
                        np.abs(data.qfrc_inverse - inverse).max())  # fmt: skip
    print(f"MuJoCo, random states (4 kinds x 200): largest difference {worst:.1e}")
    for name in ("paper_swing_up", "swing_up_min_torque", "prr_swing_up", "transfer_min_torque"):
        plan = cpopt.solve(load_problem(ROOT / "problems" / f"{name}.yaml")).plan
        controller = make_controller("tvlqr", reference(plan, 1000.0))
        plant = Plant(plan.arm)
        a, b = track(plan, controller), track(plan, controller, engine="mujoco")
        builtin, on_mujoco = [], []
        for _ in range(5):
            t0 = time.perf_counter()
            simulate_batch(controller, plant.parameters()[None, :], log=True)
            t1 = time.perf_counter()
            simulate_mujoco(controller, plant)
            builtin.append(t1 - t0)
            on_mujoco.append(time.perf_counter() - t1)
        print(f"{name:22s} tvlqr, {controller.horizon} periods: final CP error "
              f"{a.final.cp[0]:.3e} m "
              f"(built-in) vs {b.final.cp[0]:.3e} m (MuJoCo), states agree to "
              f"{np.abs(a.x - b.x).max():.1e}; run {min(builtin) * 1e3:.0f} ms built-in, "
              f"{min(on_mujoco) * 1e3:.0f} ms MuJoCo")  # fmt: skip


def frame(path: Path) -> None:
    text = (ROOT / "problems" / "paper_swing_up.yaml").read_text()
    text += (
        "tracking:\n  controller: dfl\n  plant:\n    engine: mujoco\n"
        "    links: [{mass: 1.1}, {mass: 1.1}, {mass: 0.55}]\n"
        "    friction: {viscous: [1, 1, 0.02]}\n"
    )
    source = Path("/tmp/cpopt_engines_frame.yaml")
    source.write_text(text)
    solution = cpopt.solve(source)
    outcome = solution.tracking
    print(f"frame: CP error {np.interp(0.95, outcome.t[:-1], outcome.cp_error[:-1]):.3g} m at "
          f"0.95 s, diverged at {outcome.diverged_at} s")  # fmt: skip
    print(f"frame: {solution.render(path, at=0.95)} -> {path}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frame", type=Path, help="also write docs/robots.md's picture here")
    args = parser.parse_args()
    pinocchio_figures()
    mujoco_figures()
    if args.frame:
        frame(args.frame)
