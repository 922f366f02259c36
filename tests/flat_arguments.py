"""A flat NLP and nlpsol's arguments for it, started from the closed form: what the tests of
the feasible start and of restoration step and solve."""

import numpy as np

from cpopt.flatopt.transcribe import FlatNLP, build, initial_grids
from cpopt.flatopt.warm_start import initial_guess
from cpopt.problem import Problem


def closed_form_nlp(problem: Problem, signs: tuple[int, ...]) -> tuple[FlatNLP, dict]:
    """(nlp, arguments): the NLP for ``signs`` on the first grid, and ``x0`` (the closed form
    through the nodes), ``p``, ``lbx``/``ubx`` (the lifted samples unbounded) and
    ``lbg``/``ubg``."""
    nlp = build(problem, signs, initial_grids(problem), False, False, None, False)
    lo, hi = nlp.layout.bounds(problem.free)
    lifted = nlp.solver.size_in(0)[0] - nlp.layout.size
    return nlp, {
        "x0": initial_guess(nlp, problem, signs),
        "p": nlp.parameters(problem.values),
        "lbx": np.r_[lo, [-np.inf] * lifted],
        "ubx": np.r_[hi, [np.inf] * lifted],
        "lbg": nlp.lbg,
        "ubg": nlp.ubg,
    }
