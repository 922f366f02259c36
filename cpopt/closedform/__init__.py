"""Plans of the centre of percussion: curves, nodes, the paper's closed form, sampled motion.

``curves`` and ``bspline`` (piecewise polynomials with derivatives 0..4 and the exact γ
certificate; clamped B-spline bases), ``plan`` (``Node``, ``Phase``, ``CPPlan``: a CP curve per
phase with its own sign of γ), ``nodes`` (node names and fields, file ↔ SI units), ``paths``
(geometric paths for path-and-timing plans) and ``trajectory`` (a plan sampled into joint
motion and torques, its metrics). It may import ``cpopt.model``, ``cpopt.runtime`` and
``cpopt.io``; it never imports the problem file's schema, the optimizers or verification.
"""
