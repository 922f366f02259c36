"""The per-sample function of the flat optimizer: from the CP derivatives of one sample to the
arm's torques, joint motion and reach margin (flat inverse map -> inverse kinematics -> inverse
dynamics), one small CasADi function mapped over every sample of a phase.
"""

from __future__ import annotations

from functools import lru_cache

import casadi as ca

from .. import flat
from ..dynamics import arm_dynamics
from ..kinematics import inverse_position_symbolic, kinematic_functions, reach_margin
from ..robot import Arm


@lru_cache(maxsize=16)
def sample_function(arm: Arm, jit: bool = False) -> ca.Function:
    """``(P, sigma) -> (tau, q, qd, reach)`` for one sample.

    Parameters
    ----------
    arm : Arm
        The arm.
    jit : bool
        Compile the function (and CasADi its derivatives) to C with the system compiler.

    Returns
    -------
    casadi.Function
        Inputs: P (2 x 5), the CP derivatives 0..4 [m/s^k]; sigma, the sign of gamma. Outputs:
        tau (2) [N m or N], q (3) and qd (3) joint positions and velocities, reach (the
        distance from the workspace boundary [m], positive inside).
    """
    P = ca.SX.sym("P", 2, 5)
    sigma = ca.SX.sym("sigma")
    fl = flat.flat_functions(arm.K, arm.gravity)
    z = fl["inverse"](P[:, :4], sigma)
    _, zdot, _ = fl["compensator"](z, P[:, 4])
    q = inverse_position_symbolic(arm, z[0], z[1], z[2])
    kin = kinematic_functions(arm)
    J = kin["jacobian"](q)
    qd = ca.solve(J, z[3:6])
    qdd = ca.solve(J, zdot[3:6] - kin["jdot_qdot"](q, qd))
    tau = arm_dynamics(arm)["inverse"](q, qd, qdd)[:2]
    opts = {"jit": True, "compiler": "shell", "jit_options": {"flags": ["-O2"]}} if jit else {}
    return ca.Function("sample", [P, sigma], [tau, q, qd, reach_margin(arm, z[0], z[1])], opts)
