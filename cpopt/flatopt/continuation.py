"""Continuation in gamma_min: a seeded solve starts where the flat plan can follow its seed.

A seed's gamma (the unconstrained optimum's) crosses zero at each switch and stays small near
it; a phase that must keep |gamma| >= gamma_min there starts far from the seed, and Ipopt was
measured to wander from such a start into a far worse local optimum (issue 30: fits at 5-40
times the seed's objective, hundreds of iterations). With continuation the first round keeps
only a fraction of the margin, so the fit stays next to the seed, and the following rounds raise
it to gamma_min, each warm started from the previous round's solution and multipliers.

The margin's rows are ``|gamma|^2 - g^2 >= 0`` on the sample grid, ``sign gamma - g >= 0`` at
the nodes and ``sign gamma - g = 0`` on both sides of a smooth-torque switch, with
``g = gamma_min (1 + GAMMA_SAFETY)`` (:mod:`cpopt.flatopt.transcribe`): a fraction c of the
margin is a shift of those rows' bounds, so every round runs the same compiled solver.
"""

from __future__ import annotations

import numpy as np

from ..objectives import weights
from .transcribe import GAMMA_SAFETY, FlatNLP

GRID_ROWS = "|gamma| >= gamma_min"
NODE_ROWS = "sign(gamma) at node"
SWITCH_ROWS = "|gamma| = gamma_min"


def relaxed_bounds(nlp: FlatNLP, gamma_min: float, fraction: float) -> tuple:
    """(lbg, ubg) of ``nlp`` with the margin rows asking |gamma| >= ``fraction`` gamma_min
    instead of gamma_min [m/s^2]."""
    g = gamma_min * (1 + GAMMA_SAFETY)
    lbg, ubg = np.array(nlp.lbg, float), np.array(nlp.ubg, float)
    names = [name for name, _ in nlp.rows]
    grid = np.array([n.startswith(GRID_ROWS) for n in names], bool)
    node = np.array([n.startswith(NODE_ROWS) for n in names], bool)
    switch = np.array([SWITCH_ROWS in n for n in names], bool)
    lbg[grid] = (fraction**2 - 1) * g**2
    lbg[node] = (fraction - 1) * g
    lbg[switch] = ubg[switch] = (fraction - 1) * g
    return lbg, ubg


def applies(problem) -> bool:
    """True when the margin is gamma_min itself (not the ``gamma_margin`` objective's
    variable, whose rows another bound holds)."""
    return "gamma_margin" not in weights(problem.spec.optimizer.objective)


__all__ = ["applies", "relaxed_bounds"]
