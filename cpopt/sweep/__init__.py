"""Parameter sweeps: ``cpopt sweep BASE.yaml --vary KEY=SPEC ...`` on dask.distributed.

* :mod:`cpopt.sweep.spec`: ``--vary`` specifications, the grid of points, their names and
  their validation (before any work);
* :mod:`cpopt.sweep.table`: ``sweep.csv``, each point's ``sweep_point.json`` and what
  ``--resume`` may skip;
* :mod:`cpopt.sweep.engine`: the Dask cluster (a ``LocalCluster`` or a running scheduler),
  the tasks and the results as they complete;
* :mod:`cpopt.sweep.task`: what a worker runs; :mod:`cpopt.sweep.quiet_workers`: the local
  workers ignore Ctrl-C;
* :mod:`cpopt.sweep.bar`: the progress bar; :mod:`cpopt.sweep.plot`: ``sweep.png``;
* :mod:`cpopt.sweep.run`: the command itself.

Nothing here imports Dask at import time: only running a sweep does.
"""
