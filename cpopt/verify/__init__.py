"""Verification: a plan simulated exactly, on the model it was planned for.

``simulate`` (the reduced model, the closed loop of dynamic feedback linearisation and the
open-loop replay of the plan's torques; ``verify``), ``verify_steps`` (their compiled right-hand
sides), ``integrate`` (the fixed-step integrator and its divergence guard) and ``extrapolation``
(Richardson extrapolation of whole phases). It may import ``cpopt.closedform``,
``cpopt.model``, ``cpopt.runtime`` and ``cpopt.io``, and the per-sample functions and control
laws it shares with the planners (``cpopt.flatopt.samples``, ``cpopt.tracking.dfl`` and what
that imports); the planners and the application import it, never the other way round.
"""
