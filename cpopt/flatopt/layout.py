"""The flat optimizer's decision variables as named blocks.

The core variables come first, in the order they were added: freed node values, compensator
inputs at pinned nodes, the margin of a ``gamma_margin`` objective, and each phase's free
B-spline coefficients (with ``curve: path_timing``: its free control points and timing
coefficients). The lifted samples (see :mod:`cpopt.flatopt.transcribe`) follow them;
they are functions of the core variables and get no bounds.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np

KINDS = ("value", "alpha", "margin", "coefficients", "control_points", "timing")


@dataclass(frozen=True)
class Block:
    """A named block of decision variables.

    Attributes
    ----------
    name : str
        A freed value's name (``via[0].xi``, see :mod:`cpopt.nodes`), ``alpha[i]`` for node
        i's compensator inputs, ``margin``, or ``phase[k].coefficients[lo:hi]``.
    kind : str
        One of :data:`KINDS`.
    symbol : casadi.MX
        The variables (a matrix for coefficients: one column per CP coordinate).
    phase : int
        The phase of a coefficient block (-1 otherwise).
    rows : tuple of int
        The rows [lo, hi) of the phase's coefficient matrix that a coefficient block holds.
    bounds : tuple of numpy.ndarray or None
        Lower and upper bounds per variable (a free control point's), or None for the default.
    """

    name: str
    kind: str
    symbol: ca.MX
    phase: int = -1
    rows: tuple[int, int] = (0, 0)
    bounds: tuple[np.ndarray, np.ndarray] | None = None

    @property
    def size(self) -> int:
        """Number of scalar variables."""
        return int(self.symbol.numel())


@dataclass
class Layout:
    """The core decision variables, block by block."""

    blocks: list[Block] = field(default_factory=list)

    def add(self, name: str, kind: str, symbol: ca.MX, **where) -> ca.MX:
        """Append a block and return its symbol."""
        if kind not in KINDS:
            raise ValueError(f"unknown block kind {kind!r}")
        self.blocks.append(Block(name, kind, symbol, **where))
        return symbol

    def vector(self) -> ca.MX:
        """All core variables as one column."""
        return ca.vertcat(*[ca.vec(b.symbol) for b in self.blocks])

    @property
    def size(self) -> int:
        """Number of core variables."""
        return sum(b.size for b in self.blocks)

    def bounds(self, free: dict) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds of the core variables: freed values within their bounds
        (SI units), blocks with their own bounds within them, the rest unbounded."""
        lo, hi = [], []
        for b in self.blocks:
            if b.bounds is not None:
                lo += list(b.bounds[0])
                hi += list(b.bounds[1])
                continue
            a, c = free[b.name] if b.kind == "value" else (-np.inf, np.inf)
            lo += [a] * b.size
            hi += [c] * b.size
        return np.array(lo, float), np.array(hi, float)
