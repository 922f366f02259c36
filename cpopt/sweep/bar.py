"""The sweep's progress on stderr: points done, failed, running, and the time left.

On a terminal one line is redrawn in place; elsewhere (a log) one line is written per finished
point. ``--quiet`` silences both. The estimate of the time left is the mean wall time per point
finished in this run, times the points left, divided by the points that run at once.
"""

from __future__ import annotations

import sys
import time


def clock(seconds: float) -> str:
    """``1:02:03``, ``2:03`` or ``17 s``."""
    seconds = max(round(float(seconds)), 0)
    hours, rest = divmod(seconds, 3600)
    minutes, secs = divmod(rest, 60)
    if hours:
        return f"{hours}:{minutes:02d}:{secs:02d}"
    return f"{minutes}:{secs:02d}" if minutes else f"{secs} s"


class SweepBar:
    """Progress of a sweep.

    Parameters
    ----------
    total : int
        Points of the grid.
    skipped : int
        Points already complete (``--resume``), counted as done.
    slots : int
        Points that run at once (the cluster's worker threads).
    stream : file, optional
        Where it goes (default ``sys.stderr``).
    quiet : bool
        Write nothing.
    """

    WIDTH = 24

    def __init__(
        self, total: int, skipped: int = 0, slots: int = 1, stream=None, quiet: bool = False
    ) -> None:
        self.stream = sys.stderr if stream is None else stream
        self.terminal = getattr(self.stream, "isatty", lambda: False)()
        self.quiet = quiet
        self.total, self.skipped, self.slots = total, skipped, max(slots, 1)
        self.done = self.failed = 0
        self.start = time.monotonic()
        self._drawn = False

    @property
    def finished(self) -> int:
        """Points done, skipped ones included."""
        return self.skipped + self.done

    def running(self) -> int:
        """Points being solved now (at most one per slot)."""
        return min(self.total - self.finished, self.slots)

    def eta(self) -> float | None:
        """Seconds left, estimated; None before the first point of this run finishes."""
        if not self.done:
            return None
        per_point = (time.monotonic() - self.start) / self.done
        return per_point * (self.total - self.finished)

    def line(self) -> str:
        """The progress line (without a newline)."""
        filled = self.WIDTH * self.finished // max(self.total, 1)
        eta = self.eta()
        return (
            f"cpopt sweep [{'#' * filled}{'.' * (self.WIDTH - filled)}] "
            f"{self.finished}/{self.total} done, {self.failed} failed, {self.running()} running, "
            f"ETA {'?' if eta is None else clock(eta)}"
        )

    def begin(self, slots: int) -> None:
        """The cluster is up with ``slots`` worker threads: the clock starts, the bar shows."""
        self.slots, self.start = max(slots, 1), time.monotonic()
        self.show()

    def show(self) -> None:
        """Draw the line (the first time, and on a terminal after every change)."""
        if self.quiet:
            return
        if self.terminal:
            self.stream.write("\r\x1b[2K" + self.line())
            self._drawn = True
        elif not self.done:
            self.stream.write(self.line() + "\n")
        self.stream.flush()

    def advance(self, name: str, status: str) -> None:
        """A point finished with ``status``."""
        self.done += 1
        self.failed += status != "solved"
        if self.quiet:
            return
        if self.terminal:
            self.show()
        else:
            self.stream.write(f"{self.line()}  ({name}: {status})\n")
            self.stream.flush()

    def clear(self) -> None:
        """Take the line off the terminal (before other output)."""
        if self._drawn and not self.quiet:
            self.stream.write("\r\x1b[2K")
            self.stream.flush()
            self._drawn = False

    def close(self) -> None:
        """Leave the last line on the terminal."""
        if self._drawn and not self.quiet:
            self.stream.write("\n")
            self.stream.flush()
            self._drawn = False


__all__ = ["SweepBar", "clock"]
