"""Progress of long work on stderr: which problem, which stage, how long so far.

A :class:`Progress` writes one line per event, ``cpopt: <problem>: <what> [<elapsed> s]``,
only when asked: not with ``quiet``, and only to a terminal unless ``verbose`` (a log then
gets the labels of the Ipopt runs it holds). Library code reports through the module
functions :func:`stage`, :func:`ipopt_run` and :func:`iteration`: they go to the reporter of
the :func:`reporting` block being run and do nothing outside one, so a planner reports
without taking an argument.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager

ITERATION_EVERY = 1.0
"""Shortest time between two iteration lines [s]."""


class Progress:
    """A progress reporter.

    Parameters
    ----------
    stream : file, optional
        Where lines go (default ``sys.stderr``).
    quiet : bool
        Write nothing.
    verbose : bool
        Write even when the stream is not a terminal, and label each Ipopt run.
    """

    def __init__(self, stream=None, quiet: bool = False, verbose: bool = False) -> None:
        self.stream = sys.stderr if stream is None else stream
        terminal = getattr(self.stream, "isatty", lambda: False)()
        self.enabled = not quiet and (terminal or verbose)
        self.verbose = verbose and not quiet
        self.problem = ""
        self.start = time.monotonic()
        self.listener = None  # called with every stage, shown or not (see cpopt.isolate)
        self.on_uncounted = None  # called as a block the time limit does not count starts
        # (with None) and ends (with its seconds): see cpopt.runtime.budget.uncounted
        self._last_iteration = -ITERATION_EVERY

    def stage(self, text: str) -> None:
        """A stage reached: written, and passed to ``listener`` when there is one."""
        if self.listener is not None:
            self.listener(text)
        self.write(text)

    def uncounted(self, seconds: float | None) -> None:
        """A block the time limit does not count starts (``seconds`` None) or ends after
        ``seconds`` [s]: passed to ``on_uncounted`` when there is one."""
        if self.on_uncounted is not None:
            self.on_uncounted(seconds)

    def write(self, text: str) -> None:
        """One line, when enabled."""
        if self.enabled:
            sys.stdout.flush()  # keep the order of Ipopt's output (stdout) and these lines
            elapsed = time.monotonic() - self.start
            print(f"cpopt: {self.problem}: {text} [{elapsed:.1f} s]", file=self.stream, flush=True)

    def iteration(self, count: int, detail: str = "") -> None:
        """An iteration count: a run's first, then at most once every :data:`ITERATION_EVERY`
        seconds."""
        now = time.monotonic()
        if count == 1 or now - self._last_iteration >= ITERATION_EVERY:
            self._last_iteration = now
            self.write(f"iteration {count}" + (f" ({detail})" if detail else ""))


_SILENT = Progress(quiet=True)
_current = _SILENT


@contextmanager
def reporting(progress: Progress, problem: str) -> Iterator[Progress]:
    """Send the reports of a block about ``problem`` to ``progress``."""
    global _current
    previous, _current = _current, progress
    progress.problem, progress.start = problem, time.monotonic()
    try:
        yield progress
    finally:
        _current = previous


def current() -> Progress:
    """The reporter of the :func:`reporting` block being run (a silent one outside any)."""
    return _current


def active() -> bool:
    """True inside a :func:`reporting` block (the command line always has one, quiet or not)."""
    return _current is not _SILENT


def stage(text: str) -> None:
    """Report the stage the work has reached (``planning``, ``verifying``, ...)."""
    _current.stage(text)


def ipopt_run(label: str) -> None:
    """Label an Ipopt run about to start (shown with ``verbose``, above Ipopt's own output)."""
    if _current.verbose:
        _current.write(f"Ipopt run: {label}")


def iteration(count: int, detail: str = "") -> None:
    """Report an iteration count of a long solve (rate-limited)."""
    _current.iteration(count, detail)


__all__ = ["Progress", "active", "current", "ipopt_run", "iteration", "reporting", "stage"]
