"""``--scheduler ADDRESS`` checked before any work: its syntax, then a TCP connection.

Dask reports a malformed address as a ``ValueError`` deep in its address parsing, and a
scheduler that does not answer only after its own connect timeout, once the output folder is
made; the sweep asks first, so that both are one line and exit code 2 with nothing written.
"""

from __future__ import annotations

import re
import socket
from dataclasses import dataclass

from ..io.safe_yaml import echo
from .spec import SweepError

SCHEDULER_TIMEOUT = 5.0
"""Seconds a ``--scheduler`` has to accept a TCP connection before the sweep is refused."""

_ADDRESS = re.compile(
    r"(?:(?P<scheme>[A-Za-z][A-Za-z0-9+.-]*)://)?"
    r"(?:\[(?P<ipv6>[0-9A-Fa-f:.]+)\]|(?P<host>[A-Za-z0-9](?:[A-Za-z0-9.-]*[A-Za-z0-9])?))"
    r"(?::(?P<port>[^:]*))?"
)
EXPECTED = "expected [tcp://]HOST:PORT, e.g. tcp://127.0.0.1:8786"


@dataclass(frozen=True)
class SchedulerAddress:
    """A scheduler's address: host name or IP address, and TCP port."""

    host: str
    port: int

    @property
    def url(self) -> str:
        """The address as Dask takes it (``tcp://host:port``, an IPv6 host in brackets)."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"tcp://{host}:{self.port}"


def parse_scheduler(text: str) -> SchedulerAddress:
    """The host and port of a ``--scheduler`` (``tcp://`` optional).

    Raises
    ------
    SweepError
        Naming the option, the address and what was expected.
    """
    where = f"--scheduler {echo(text)}"
    match = _ADDRESS.fullmatch(text.strip())
    if match is None:
        raise SweepError(f"{where}: {EXPECTED}")
    if match["scheme"] not in (None, "tcp"):
        raise SweepError(f"{where}: only tcp:// is supported, got {match['scheme']}://")
    if match["port"] is None:
        raise SweepError(f"{where}: no port number; {EXPECTED}")
    port = int(match["port"]) if match["port"].isdigit() else 0
    if not 1 <= port <= 65535:
        raise SweepError(f"{where}: the port must be a whole number 1-65535, got {match['port']!r}")
    return SchedulerAddress(match["ipv6"] or match["host"], port)


def check_scheduler(text: str, timeout: float = SCHEDULER_TIMEOUT) -> SchedulerAddress:
    """:func:`parse_scheduler`, then a TCP connection to it that must succeed in ``timeout`` s
    (closed at once: Dask's client connects again).

    Raises
    ------
    SweepError
        For a malformed address, a host that does not resolve, a refused connection or no
        answer in time.
    """
    address = parse_scheduler(text)
    where = f"--scheduler {echo(text)}"
    try:
        with socket.create_connection((address.host, address.port), timeout=timeout):
            pass
    except socket.gaierror:
        raise SweepError(f"{where}: cannot resolve the host {address.host!r}") from None
    except TimeoutError:
        raise SweepError(
            f"{where}: no answer within {timeout:g} s (is a Dask scheduler running there?)"
        ) from None
    except ConnectionRefusedError:
        raise SweepError(
            f"{where}: connection refused (is a Dask scheduler running there?)"
        ) from None
    except OSError as err:
        raise SweepError(f"{where}: cannot connect ({err.strerror or err})") from None
    return address


__all__ = ["SCHEDULER_TIMEOUT", "SchedulerAddress", "check_scheduler", "parse_scheduler"]
