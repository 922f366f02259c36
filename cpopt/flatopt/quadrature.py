"""Where the flat optimizer samples a phase, and the quadrature weights of its objective.

A phase's samples are the quadrature points of the objective, followed by the points that
refinement added for the constraints alone. Sample times are normalised to the phase, s in
[0, 1]; the weights of the quadrature points sum to 1 (multiply by the phase's duration).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PhaseSamples:
    """The samples of one phase.

    Attributes
    ----------
    s : numpy.ndarray
        Normalised times: the quadrature points first, then the constraint-only points.
    weights : numpy.ndarray
        Quadrature weights of the first ``len(weights)`` points (sum 1).
    """

    s: np.ndarray
    weights: np.ndarray

    @property
    def quadrature(self) -> int:
        """Number of quadrature points (the first ones of ``s``)."""
        return int(self.weights.size)

    def with_extra(self, extra) -> PhaseSamples:
        """The same quadrature with constraint-only points ``extra`` (normalised times) added."""
        s = np.r_[self.s[: self.quadrature], np.asarray(extra, float)]
        return PhaseSamples(s, self.weights)


def simpson(samples: int) -> PhaseSamples:
    """Simpson's rule on equally spaced points (``samples`` rounded up to an odd number)."""
    m = samples + (1 - samples % 2)
    w = np.ones(m)
    w[1:-1:2], w[2:-1:2] = 4, 2
    return PhaseSamples(np.linspace(0.0, 1.0, m), w / (3 * (m - 1)))
