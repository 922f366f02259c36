"""The flat optimizer's constraints as they are assembled, shared by the transcription
(:mod:`cpopt.flatopt.transcribe`) and the curve families that add rows to it
(:mod:`cpopt.flatopt.path_timing`)."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class Constraints:
    """The NLP's constraints as they are assembled: expressions, bounds, and a label per row
    (the constraint's name and where it sits: phase, normalised time)."""

    exprs: list = field(default_factory=list)
    lower: list = field(default_factory=list)
    upper: list = field(default_factory=list)
    rows: list = field(default_factory=list)

    def add(self, expr, lo: float, hi, name: str, where: list) -> None:
        """Append ``lo <= expr <= hi``; ``where`` labels each row, or all rows alike."""
        self.exprs.append(expr)
        k = int(expr.numel())
        self.lower.extend([lo] * k)
        self.upper.extend([hi] * k)
        self.rows.extend((name, w) for w in (where if len(where) == k else where * k))
