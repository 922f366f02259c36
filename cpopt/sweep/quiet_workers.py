"""A Dask worker plugin of ``cpopt sweep``'s local cluster (this module imports Dask)."""

from __future__ import annotations

import signal
import threading

from distributed.diagnostics.plugin import WorkerPlugin


class IgnoreCtrlC(WorkerPlugin):
    """Workers of the local cluster ignore Ctrl-C: the terminal signals the whole process
    group, and the ``cpopt sweep`` process alone answers it (it cancels the tasks and closes
    the cluster). The first workers are started with SIGINT ignored already; this covers the
    workers the nanny starts again after one was lost."""

    name = "cpopt-ignore-ctrl-c"

    def setup(self, worker) -> None:
        """Ignore SIGINT in this worker process (where its event loop runs the main thread)."""
        if threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGINT, signal.SIG_IGN)


__all__ = ["IgnoreCtrlC"]
