"""Bounded work: a wall-clock budget per problem, and a clean stop on Ctrl-C.

A :class:`Budget` is the wall-clock limit of one problem (``optimizer.solver.max_time``,
``--time-limit``). Inside :func:`enforced` it is checked two ways:

* cooperatively: loops that may run long (the simulations) call :func:`check_time`;
* by a timer (main thread, POSIX): when the budget runs out, ``SIGALRM`` raises
  :class:`TimeLimitExceeded` wherever the work is, Ipopt included (CasADi checks for signals
  every iteration).

CasADi catches an exception raised inside Ipopt, stops Ipopt and returns as if nothing had
happened; so the timer raises again every :data:`REPEAT` seconds until the block is left, and
the next raise lands in Python code. Ctrl-C inside :func:`enforced` works the same way: it
raises KeyboardInterrupt now and again every :data:`REPEAT` seconds. Whatever escapes the block
after a stop (CasADi may turn the exception into another type) is reported as what it was: the
block re-raises it as KeyboardInterrupt or :class:`TimeLimitExceeded`.
"""

from __future__ import annotations

import contextlib
import math
import os
import signal
import socket
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager

REPEAT = 0.25
"""Seconds between repeated raises after a stop (CasADi swallows one inside Ipopt)."""
_CLEANUP_FILES = {__file__, contextlib.__file__}


class TimeLimitExceeded(BaseException):
    """The wall-clock budget ran out.

    A BaseException, like KeyboardInterrupt: a stop must not be taken for an ordinary error by
    an ``except Exception`` on the way out.
    """

    def __init__(self, budget: Budget) -> None:
        self.seconds, self.elapsed = budget.limit, budget.elapsed
        super().__init__(f"wall-clock limit of {self.seconds:g} s reached")


class Budget:
    """A wall-clock budget [s], counted from its creation.

    Parameters
    ----------
    seconds : float
        The limit [s].
    """

    def __init__(self, seconds: float) -> None:
        self.seconds = self.limit = float(seconds)
        self.start = time.monotonic()
        self.fired = False
        self.uncounted = 0.0  # seconds of finished uncounted blocks (see :func:`uncounted`)
        self.paused_since: float | None = None  # the start of the uncounted block running

    @property
    def elapsed(self) -> float:
        """Seconds counted since the budget started: its uncounted blocks left out."""
        now = time.monotonic()
        paused = 0.0 if self.paused_since is None else now - self.paused_since
        return now - self.start - self.uncounted - paused

    def remaining(self) -> float:
        """Seconds left (negative once exceeded)."""
        return self.seconds - self.elapsed

    def check(self) -> None:
        """Raise :class:`TimeLimitExceeded` when the budget has run out."""
        if self.remaining() <= 0:
            self.fired = True
            raise TimeLimitExceeded(self)


class _State:
    budget: Budget | None = None
    interrupted = False
    armed = False  # the handlers act only inside an enforced block


def check_time() -> None:
    """Raise :class:`TimeLimitExceeded` when the active budget has run out (else nothing)."""
    if _State.budget is not None:
        _State.budget.check()


def remaining() -> float:
    """Seconds left in the active budget (``math.inf`` outside :func:`enforced`): a search
    that can return its best plan so far plans its stages by it instead of being stopped."""
    return math.inf if _State.budget is None else _State.budget.remaining()


def check_stop() -> None:
    """Raise the stop that CasADi may have swallowed inside a solver: KeyboardInterrupt after
    Ctrl-C, :class:`TimeLimitExceeded` once the budget has run out (else nothing). Called when
    a solver returns, so that its result is not taken for a plan until the timer's next repeat
    (:data:`REPEAT`), by which time a fast planner may have finished."""
    if _State.armed and _State.interrupted:
        raise KeyboardInterrupt
    check_time()


GRACE = 0.9
"""Seconds past the limit that a plan solved before it gets, to be sampled and verified
(:func:`grant_grace`): a search returns its best plan by the limit plus at most 1 s, and the
timer's repeat (:data:`REPEAT`) may take a quarter of a second of that to stop it."""


def stopped_by_time(err: BaseException) -> bool:
    """True when ``err`` is the active budget's stop: :class:`TimeLimitExceeded`, or another
    error (what CasADi made of the stop) raised once the budget has fired. Never Ctrl-C."""
    if isinstance(err, TimeLimitExceeded):
        return True
    budget = _State.budget
    return isinstance(err, Exception) and budget is not None and budget.fired


def grant_grace() -> None:
    """Let the active budget run to its limit plus :data:`GRACE` seconds (once: a second call
    grants nothing more; nothing outside :func:`enforced`). A search stopped by the limit
    after it had solved a plan calls it, so that the plan is sampled and verified instead of
    lost; the budget stays ``fired``."""
    budget = _State.budget
    if budget is not None:
        budget.seconds = max(budget.seconds, budget.limit + GRACE)


@contextmanager
def uncounted() -> Iterator[None]:
    """Run a block whose time the active budget does not count (nothing outside
    :func:`enforced`): a one-time compile of C code that a fresh machine runs and the next
    solve does not, so that a time limit means the same on both. The timer does not stop the
    block (Ctrl-C does); the block's duration is added to the budget when it ends, and the
    reporter's ``on_uncounted`` (:mod:`cpopt.runtime.progress`) hears of its start (None) and
    of its end (its seconds), so that a parent process extends its own limit as well.
    """
    budget = _State.budget
    if budget is None or budget.paused_since is not None:  # no budget, or nested
        yield
        return
    from . import progress  # the reporter of the block being run, if any

    budget.paused_since = time.monotonic()
    progress.current().uncounted(None)
    try:
        yield
    finally:
        seconds = time.monotonic() - budget.paused_since
        budget.uncounted += seconds
        budget.paused_since = None
        progress.current().uncounted(seconds)


def _in_cleanup(frame) -> bool:
    """True inside this module or contextlib: a stop raised there would skip the restoring of
    the signal handlers; the next repeat lands elsewhere."""
    return frame is not None and frame.f_code.co_filename in _CLEANUP_FILES


def _on_alarm(signum, frame) -> None:
    if not _State.armed or _in_cleanup(frame):
        return
    if _State.interrupted:
        raise KeyboardInterrupt
    budget = _State.budget
    if budget is not None and budget.paused_since is None and budget.remaining() <= 0:
        budget.fired = True  # (the timer repeats: a block left uncounted is stopped later)
        raise TimeLimitExceeded(budget)


def _on_interrupt(signum, frame) -> None:
    if _State.armed:
        _State.interrupted = True
        signal.setitimer(signal.ITIMER_REAL, REPEAT, REPEAT)
        if _in_cleanup(frame):
            return
    raise KeyboardInterrupt


class _WithoutStopWarnings:
    """sys.stderr without CasADi's warning about the KeyboardInterrupt it caught in Ipopt
    (the stop is reported once, by whoever handles it)."""

    def __init__(self, stream) -> None:
        self.stream, self.pending = stream, ""

    def write(self, text: str) -> int:
        lines = (self.pending + text).split("\n")
        self.pending = lines.pop()
        for line in lines:
            if "KeyboardInterruptException" not in line:
                self.stream.write(line + "\n")
        return len(text)

    def flush(self) -> None:
        if self.pending and "KeyboardInterruptException" not in self.pending:
            self.stream.write(self.pending)
        self.pending = ""
        self.stream.flush()

    def __getattr__(self, name):
        return getattr(self.stream, name)


def _can_signal() -> bool:
    return hasattr(signal, "setitimer") and threading.current_thread() is threading.main_thread()


@contextmanager
def enforced(budget: Budget) -> Iterator[Budget]:
    """Run a block under ``budget`` (see the module docstring); blocks do not nest.

    Raises
    ------
    TimeLimitExceeded
        When the budget runs out inside the block.
    KeyboardInterrupt
        On Ctrl-C inside the block, whatever CasADi turned it into.
    """
    _State.budget, _State.interrupted, _State.armed = budget, False, True
    stderr, sys.stderr = sys.stderr, _WithoutStopWarnings(sys.stderr)
    timed = _can_signal()
    if timed:
        handlers = signal.signal(signal.SIGALRM, _on_alarm), signal.getsignal(signal.SIGINT)
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            signal.signal(signal.SIGINT, _on_interrupt)
        signal.setitimer(signal.ITIMER_REAL, max(budget.remaining(), 1e-3), REPEAT)
    try:
        yield budget
    except GeneratorExit:
        raise
    except BaseException as err:
        if _State.interrupted and not isinstance(err, KeyboardInterrupt):
            raise KeyboardInterrupt from None
        if budget.fired and not isinstance(err, TimeLimitExceeded | KeyboardInterrupt):
            raise TimeLimitExceeded(budget) from None
        raise
    finally:
        try:
            _State.armed = False
        finally:  # even if a last signal lands on the line above
            if timed:
                signal.setitimer(signal.ITIMER_REAL, 0)
                signal.signal(signal.SIGALRM, handlers[0])
                signal.signal(signal.SIGINT, handlers[1])
            _State.budget, _State.interrupted = None, False
            sys.stderr.flush()
            sys.stderr = stderr


INTERRUPT_GRACE = 1.0
"""Seconds a Ctrl-C gets to unwind the work before :func:`hard_stop_on_interrupt` exits (named
apart from :data:`GRACE`, which it used to rebind)."""


@contextmanager
def hard_stop_on_interrupt(
    on_stop, grace: float = INTERRUPT_GRACE, code: int = 130
) -> Iterator[None]:
    """For a command line: a Ctrl-C that has not ended the work after ``grace`` seconds ends
    the process: ``on_stop()`` is called (say so, remove temporary files), then ``os._exit``.

    Python runs signal handlers only between bytecodes, so a long CasADi call that does not
    check for signals (building an NLP takes seconds) would hold a Ctrl-C until it returns. The
    C-level handler writes the signal number to a wakeup socket at once, and a watcher thread
    reads it (CasADi releases the GIL). Main thread only; elsewhere a no-op.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    reader, writer = socket.socketpair()
    writer.setblocking(False)
    previous = signal.set_wakeup_fd(writer.fileno(), warn_on_full_buffer=False)

    def watch() -> None:
        try:
            data = b""
            while signal.SIGINT not in data:
                data = reader.recv(64)
                if not data:  # shut down: the block ended
                    return
        except OSError:
            return
        time.sleep(grace)
        on_stop()
        os._exit(code)

    threading.Thread(target=watch, name="cpopt-interrupt", daemon=True).start()
    try:
        yield
    finally:
        signal.set_wakeup_fd(previous)
        writer.close()
        reader.shutdown(socket.SHUT_RDWR)
        reader.close()


__all__ = [
    "GRACE",
    "INTERRUPT_GRACE",
    "Budget",
    "TimeLimitExceeded",
    "check_time",
    "enforced",
    "grant_grace",
    "hard_stop_on_interrupt",
    "remaining",
    "uncounted",
]
