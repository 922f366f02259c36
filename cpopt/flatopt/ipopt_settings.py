"""The flat NLP's Ipopt settings by how a solve starts: from the closed form, from a seed
trajectory (a collocation seed or an exact plan), or resumed from a previous round with its
multipliers; and the points per phase where |gamma| >= gamma_min is a row, which set the
NLP's size (:func:`cpopt.flatopt.transcribe.build`)."""

from __future__ import annotations

GAMMA_GRID = 241
"""Points per phase where |gamma| >= gamma_min is a constraint (then certified exactly; a dip
between the points adds points there, :func:`cpopt.flatopt.refine.between_samples`)."""
WARM_GAMMA_GRID = 61
"""The same for a solve started from a seed trajectory (the switch search's). Measured on
random zoo draws: 241 points cost a four-switch RRR transfer 40 ms an Ipopt iteration under
load, 61 about 20; a three-switch RPR swing-down solved to the same plan in 4.6 s against
7.9 s. From the closed form 61 points were worse on the bundled problems (transfer_switch's
greedy search no longer found its switch; swing_up_path_timing stopped at an acceptable
point 5 % above its optimum)."""
WARM_MU_INIT = 1e-3
"""Ipopt's initial barrier parameter for a solve started from a seed trajectory: the start is
close, and Ipopt's default 0.1 first pushes it away (measured on the benchmark transfer's
seeded switch pattern with mu_strategy monotone: 623 iterations at 0.1, 434 at 1e-2, 259 at
1e-3, 287 at 1e-4; the adaptive strategy's problems unchanged)."""


def warm_options(settings, from_plan: bool = False) -> dict:
    """Ipopt's options for a solve started from a seed trajectory: :data:`WARM_MU_INIT`, and
    the monotone barrier update for a collocation seed unless the file chose one
    (``optimizer.solver.mu_strategy``). The adaptive update ignores mu_init and, at a start
    near the optimum, raised mu to 10 and threw the start away (a random RRR transfer's
    patterned start at objective 6.8e3 went to 1e7 and ended at 5e7; monotone from the same
    start: 2862 by iteration 34). From an exact plan (``from_plan``: a continuation, a
    polish) it keeps the file's (swing_up_switches with link 3 5 % heavier from the bundled
    plan: 23 iterations adaptive, 87 monotone)."""
    options = {"mu_init": WARM_MU_INIT}
    if settings.mu_strategy is None and not from_plan:
        options["mu_strategy"] = "monotone"
    return options


RESUME_OPTIONS = {
    "warm_start_init_point": "yes",
    **{
        f"warm_start_{name}": 1e-5
        for name in ("bound_push", "bound_frac", "slack_bound_push", "slack_bound_frac")
    },
    "warm_start_mult_bound_push": 1e-5,
}
"""Ipopt's options for a refinement round, started from the previous round's solution and its
multipliers (:func:`cpopt.flatopt.resumed_multipliers`). Measured, the refinement rounds'
iterations: swing_up_min_time 35 + 32 cold, 12 + 10 resumed; transfer_min_time_on_path
21 + 23, 9 + 8; swing_up_holding 10, 8; swing_up_torque_limited 17, 14. Pushing the start
only 1e-9 inside its bounds was worse on two (33 and 31: the added samples' rows start with
zero multipliers), 1e-3 worse on one; Ipopt's adaptive barrier ignores ``mu_init``."""


__all__ = ["GAMMA_GRID", "RESUME_OPTIONS", "WARM_GAMMA_GRID", "WARM_MU_INIT", "warm_options"]
