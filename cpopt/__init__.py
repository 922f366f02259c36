"""cpopt: motion planning for three-link planar robots with a passive third joint under gravity.

The Python API (see docs/getting_started.md, "Python")::

    import cpopt

    problem = cpopt.load("problems/swing_up_min_torque.yaml", **{"motion.duration": 2.0})
    solution = cpopt.solve(problem)          # a Solution: status, metrics, sample(t), plot, save
    outcome = cpopt.track(solution, controller="tvlqr", plant={"links": [{}, {}, {"mass": 0.6}]})

* :func:`load` → :class:`Problem` (values changed by key path; :class:`ProblemError` names the
  file and the key path);
* :func:`solve` → :class:`Solution` (``.status``, ``.metrics``, ``.free_values``,
  ``.sample(t)``, ``.to_dict()``, ``.save(dir)``, ``.plot(kind)``);
* :func:`track` → :class:`~cpopt.tracking.TrackingOutcome`, as a problem's ``tracking`` block;
* :func:`replan` → :class:`~cpopt.flatopt.replan.Replan`: the remaining motion of a flat plan
  from a measured state (what the ``flat_mpc`` controller does in its loop).

The names are imported on first use, so ``import cpopt`` (and ``cpopt --version``) stays fast.
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

_LAZY = {
    "load": "cpopt.api",
    "solve": "cpopt.api",
    "track": "cpopt.api",
    "replan": "cpopt.replanning",
    "Problem": "cpopt.problem",
    "ProblemError": "cpopt.problem",
    "Solution": "cpopt.solution",
}
"""Public name -> the module that defines it, imported when the name is first used."""

__all__ = [
    "Problem",
    "ProblemError",
    "Solution",
    "__version__",
    "load",
    "replan",
    "solve",
    "track",
]


def __getattr__(name: str):
    """The API's names, imported on first access (PEP 562)."""
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'cpopt' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # later accesses skip this function
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})
