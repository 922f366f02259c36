"""Where the flat optimizer samples a phase: graded Gauss-Legendre points per B-spline piece."""

import numpy as np
import pytest

from cpopt.flatopt.quadrature import Grid, fine_rule, piece_counts


def test_piece_counts_are_graded_towards_the_ends():
    assert piece_counts(50, 6) == (15, 5, 5, 5, 5, 15)
    assert piece_counts(88, 18) == (12, *([4] * 16), 12)
    assert piece_counts(40, 6) == (12, 4, 4, 4, 4, 12)
    assert piece_counts(10, 1) == (12,)  # one piece is both end pieces
    assert sum(piece_counts(61, 6)) >= 61


def test_grid_integrates_piecewise_polynomials_exactly():
    grid = Grid((6, 2, 3, 6))
    samples = grid.samples()
    assert samples.weights.sum() == pytest.approx(1.0, abs=1e-15)
    assert np.all(np.diff(samples.s) > 0) and samples.s[0] > 0 and samples.s[-1] < 1
    assert samples.piece.tolist() == [0] * 6 + [1] * 2 + [2] * 3 + [3] * 6
    # a different cubic on each quarter: 2 points integrate degree 3 exactly
    coeffs = np.array([[1.0, -2.0, 3.0, 5.0], [0.5, 4.0, -1.0, 2.0], [2.0, 0.0, 1.0, -3.0],
                       [-1.0, 1.0, 1.0, 1.0]])  # fmt: skip

    def f(s):
        k = np.minimum((s * 4).astype(int), 3)
        return sum(coeffs[k, j] * s**j for j in range(4))

    exact = sum(
        sum(coeffs[k, j] * ((k + 1) ** (j + 1) - k ** (j + 1)) / (j + 1) / 4 ** (j + 1)
            for j in range(4))
        for k in range(4)
    )  # fmt: skip
    assert samples.weights @ f(samples.s) == pytest.approx(exact, rel=1e-14)
    s, w = fine_rule(0.25, 0.5)
    assert w.sum() == pytest.approx(0.25) and s.size == 64


def test_refined_grid_doubles_pieces_and_keeps_constraint_points():
    grid = Grid((15, 5, 5, 15)).refined({1}, {0.9, 0.1})
    assert grid.counts == (15, 10, 5, 15)
    assert grid.extra == (0.1, 0.9)
    samples = grid.refined(set(), {0.1}).samples()
    assert samples.quadrature == 45 and samples.s.size == 47
    assert samples.s[-2:].tolist() == [0.1, 0.9]
