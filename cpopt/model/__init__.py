"""The arm: its parameters, kinematics, dynamics, flat output, limits and cost terms.

``robot`` (frozen dataclasses in SI units: ``Link``, ``Arm``, ``K``), ``kinematics`` (joints ↔
the third link's base, reach, inverse kinematics), ``dynamics`` (Lagrangian B, c, g as CasADi
functions; inverse and forward dynamics), ``flat`` (the centre of percussion and its maps: γ,
the compensator (ξ, η), forward and inverse), ``mapping`` (CasADi functions mapped over samples),
``limits`` and ``objectives`` (each limit and each cost term defined once) and ``mujoco_arm`` (the
same arm as a MuJoCo model, imported lazily). It may import ``cpopt.runtime`` and ``cpopt.io``;
nothing in it knows of plans, problem files, planners or verification.
"""
