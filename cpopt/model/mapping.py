"""Evaluating a CasADi function over many samples at once."""

from __future__ import annotations

from functools import lru_cache

import casadi as ca


@lru_cache(maxsize=512)
def mapped(function: ca.Function, count: int) -> ca.Function:
    """``function.map(count)``, built once per function and count (maps are not free: the
    simulations evaluate the same ones thousands of times)."""
    return function.map(count)
