"""Where the flat optimizer samples a phase, and the quadrature weights of its objective.

The objective's integrals use Gauss-Legendre points on each polynomial piece of the B-spline,
graded: the first and last piece of a phase get :data:`END_FACTOR` times the points of an inner
piece (free compensator values at the ends let the optimizer put fast motion there, and a plain
rule aliases: torque spikes hide between its points). ``optimizer.samples`` asks for about that
many points per phase: each inner piece gets ``ceil(samples / (pieces + 2 (END_FACTOR - 1)))``.
After a solve the quadrature of every piece is compared with a fine integral of the plan and
pieces that differ get twice the points (:mod:`cpopt.flatopt.refine`).

A phase's samples are its quadrature points followed by the points refinement added for the
constraints alone. Times are normalised to the phase, s in [0, 1]; the quadrature weights sum
to 1 (multiply by the phase's duration).
"""

from __future__ import annotations

from dataclasses import dataclass
from math import ceil

import numpy as np

END_FACTOR = 3
"""Points on a phase's first and last piece relative to an inner piece."""
FINE_POINTS = (8, 8)
"""The fine integral of a piece: 8 Gauss-Legendre points on each of 8 equal parts."""


@dataclass(frozen=True)
class PhaseSamples:
    """The samples of one phase.

    Attributes
    ----------
    s : numpy.ndarray
        Normalised times: the quadrature points first, then the constraint-only points.
    weights : numpy.ndarray
        Quadrature weights of the first ``len(weights)`` points (sum 1).
    piece : numpy.ndarray
        The B-spline piece of each quadrature point.
    """

    s: np.ndarray
    weights: np.ndarray
    piece: np.ndarray

    @property
    def quadrature(self) -> int:
        """Number of quadrature points (the first ones of ``s``)."""
        return int(self.weights.size)


@dataclass(frozen=True)
class Grid:
    """How a phase is sampled: Gauss-Legendre points per piece, and constraint-only points.

    Attributes
    ----------
    counts : tuple of int
        Quadrature points on each polynomial piece.
    extra : tuple of float
        Normalised times of constraint-only samples (added by refinement).
    """

    counts: tuple[int, ...]
    extra: tuple[float, ...] = ()

    def samples(self) -> PhaseSamples:
        """The points and weights (the pieces split [0, 1] equally)."""
        breaks = np.linspace(0.0, 1.0, len(self.counts) + 1)
        s, w, piece = gauss_legendre(breaks, self.counts)
        return PhaseSamples(np.r_[s, np.asarray(self.extra, float)], w, piece)

    def refined(self, pieces: set[int], extra: set[float]) -> Grid:
        """Twice the points on ``pieces``, and the constraint-only points ``extra`` added."""
        counts = tuple(2 * c if i in pieces else c for i, c in enumerate(self.counts))
        return Grid(counts, tuple(sorted(set(self.extra) | set(extra))))


def piece_counts(samples: int, pieces: int) -> tuple[int, ...]:
    """Quadrature points per piece for about ``samples`` points per phase (see the module
    docstring); a single piece gets ``END_FACTOR`` times the inner count."""
    grade = [END_FACTOR if i in (0, pieces - 1) else 1 for i in range(pieces)]
    inner = ceil(samples / sum(grade))
    return tuple(g * inner for g in grade)


def gauss_legendre(breaks: np.ndarray, counts) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gauss-Legendre points and weights on each interval [breaks[i], breaks[i + 1]].

    Returns
    -------
    s, weights, piece : numpy.ndarray
        Points, weights (summing to the length of the whole interval) and interval indices.
    """
    s, w, piece = [], [], []
    for i, (a, b, k) in enumerate(zip(breaks[:-1], breaks[1:], counts, strict=True)):
        x, wx = np.polynomial.legendre.leggauss(k)
        s.append(a + (x + 1) * (b - a) / 2)
        w.append(wx * (b - a) / 2)
        piece.append(np.full(k, i))
    return np.concatenate(s), np.concatenate(w), np.concatenate(piece)


def fine_rule(a: float, b: float) -> tuple[np.ndarray, np.ndarray]:
    """Points and weights of the fine integral over [a, b] (:data:`FINE_POINTS`)."""
    parts, k = FINE_POINTS
    s, w, _ = gauss_legendre(np.linspace(a, b, parts + 1), [k] * parts)
    return s, w
