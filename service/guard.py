"""Connections bounded in time and number: what ``csws serve`` puts between the socket and the app.

uvicorn closes an idle keep-alive connection (``timeout_keep_alive``) and bounds a request head
in size (h11's ``max_incomplete_event_size``), but a client that sends a partial request line,
or drips one header line every few seconds, would hold its connection for ever: before the
head is in, no ASGI code runs, so no key check and no middleware can end it. The service
therefore runs uvicorn's h11 protocol with a guard (:class:`GuardedH11Protocol`):

* the request head (request line and headers) must be complete within :attr:`Limits.head_timeout_s`
  of the connection's start, or of the end of the previous answer on a keep-alive connection;
  otherwise the client gets a 408 and the connection is closed;
* a worker holds at most :attr:`Limits.max_connections` connections; one more gets a 503 with
  ``Retry-After`` and is closed at once, so that the worker never runs out of file descriptors
  (the limit is kept below the process's descriptor limit, raised to its hard limit at start);
* log lines that a flood of bad clients can repeat (a refused connection, an invalid request,
  ``accept()`` out of resources) are written at most once per :data:`LOG_INTERVAL_S`
  each, with the number of those left out (:class:`OncePerInterval`), an operating-system error
  as one line (:class:`OneLine`).

The body is bounded by :class:`service.limits.BodyLimit` (size, and a pause of at most
``body_timeout_s`` between its parts); the number of header lines by
:class:`service.headers.ResponseHeaders` (a 431).
"""

from __future__ import annotations

import asyncio
import logging
import socket
import time
from dataclasses import dataclass
from typing import Any

import h11
from uvicorn.protocols.http.h11_impl import H11Protocol

try:
    import resource
except ImportError:  # Windows: no descriptor limit to raise
    resource = None  # type: ignore[assignment]

__all__ = [
    "HEAD_TIMEOUT_S",
    "KEEP_ALIVE_S",
    "MAX_HEAD_BYTES",
    "MAX_CONNECTIONS",
    "FD_RESERVE",
    "LOG_INTERVAL_S",
    "Limits",
    "OncePerInterval",
    "OneLine",
    "GuardedH11Protocol",
    "connection_limits",
    "serve",
]

#: A request head must be complete within this long, s.
HEAD_TIMEOUT_S = 10.0
#: An idle keep-alive connection is closed after this long, s.
KEEP_ALIVE_S = 5.0
#: The largest request head (request line and headers), bytes: a larger one is a 400.
MAX_HEAD_BYTES = 16 * 1024
#: Most connections one worker holds at once.
MAX_CONNECTIONS = 4096
#: File descriptors kept free of connections, for the state store, the networks and the log.
FD_RESERVE = 64
#: A log line a flood can repeat is written at most once per this long, s.
LOG_INTERVAL_S = 10.0

_TIMED_OUT = b"HTTP/1.1 408 Request Timeout\r\ncontent-length: 0\r\nconnection: close\r\n\r\n"
_FULL = b"HTTP/1.1 503 Service Unavailable\r\ncontent-length: 0\r\nretry-after: 1\r\nconnection: close\r\n\r\n"

logger = logging.getLogger("csws.service")


@dataclass(frozen=True)
class Limits:
    """The bounds of the connections of one worker.

    Attributes
    ----------
    head_timeout_s
        How long a request head may take to arrive, s.
    max_connections
        Most connections held at once.
    """

    head_timeout_s: float = HEAD_TIMEOUT_S
    max_connections: int = MAX_CONNECTIONS


class OncePerInterval(logging.Filter):
    """A logging filter that lets each message (by its format string) through at most once per
    ``interval_s``, the next one saying how many were left out since."""

    def __init__(self, interval_s: float = LOG_INTERVAL_S) -> None:
        super().__init__()
        self.interval_s = interval_s
        self._last_s: dict[str, float] = {}
        self._left_out: dict[str, int] = {}

    def filter(self, record: logging.LogRecord) -> bool:
        now_s = time.monotonic()
        key = str(record.msg)
        if now_s - self._last_s.get(key, -float("inf")) < self.interval_s:
            self._left_out[key] = self._left_out.get(key, 0) + 1
            return False
        self._last_s[key] = now_s
        left_out = self._left_out.pop(key, 0)
        if left_out:
            record.msg = f"{record.msg} (and {left_out} more like it in the last {self.interval_s:g} s)"
        return True


class OneLine(logging.Filter):
    """A logging filter that writes an operating-system error as one line, without its traceback
    (asyncio's ``accept()`` out of descriptors would be seven)."""

    def filter(self, record: logging.LogRecord) -> bool:
        error = record.exc_info[1] if record.exc_info else None
        if isinstance(error, OSError):
            record.msg = f"{record.getMessage().splitlines()[0]}: {error}"
            record.args, record.exc_info, record.exc_text = None, None, None
        return True


class GuardedH11Protocol(H11Protocol):
    """uvicorn's h11 protocol with a deadline for each request head and a cap on connections (see the
    module). :attr:`limits` is set on a subclass made per server (:func:`serve`)."""

    limits = Limits()
    _head_timer: asyncio.TimerHandle | None = None

    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
        super().connection_made(transport)
        if len(self.connections) > self.limits.max_connections:
            logger.warning("a connection was refused: the worker holds %d, the most it takes", len(self.connections))
            transport.write(_FULL)
            transport.close()
            return
        self._arm_head_timer()

    def data_received(self, data: bytes) -> None:
        super().data_received(data)
        if self._head_timer is not None and self.conn.their_state is not h11.IDLE:
            self._head_timer.cancel()  # the head is in
            self._head_timer = None

    def on_response_complete(self) -> None:
        super().on_response_complete()
        if not self.transport.is_closing() and self.conn.their_state is h11.IDLE:
            self._arm_head_timer()  # the next request's head, on a keep-alive connection

    def connection_lost(self, exc: Exception | None) -> None:
        if self._head_timer is not None:
            self._head_timer.cancel()
            self._head_timer = None
        super().connection_lost(exc)

    def _arm_head_timer(self) -> None:
        """Start the deadline of the next request head."""
        if self._head_timer is not None:
            self._head_timer.cancel()
        self._head_timer = self.loop.call_later(self.limits.head_timeout_s, self._head_timed_out)

    def _head_timed_out(self) -> None:
        """The head did not arrive in time: a 408 if no answer is under way, and the connection closed."""
        self._head_timer = None
        if self.transport.is_closing() or self.conn.their_state is not h11.IDLE:
            return
        if self.conn.our_state is h11.IDLE:
            self.transport.write(_TIMED_OUT)
        self.transport.close()


def connection_limits(head_timeout_s: float = HEAD_TIMEOUT_S) -> Limits:
    """The limits for this process: the file descriptor limit raised to its hard limit, and the
    connections kept :data:`FD_RESERVE` below it (at most :data:`MAX_CONNECTIONS`)."""
    if resource is None:
        return Limits(head_timeout_s, MAX_CONNECTIONS)
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    wanted = MAX_CONNECTIONS + FD_RESERVE
    if soft != resource.RLIM_INFINITY and soft < wanted and (hard == resource.RLIM_INFINITY or hard > soft):
        soft = wanted if hard == resource.RLIM_INFINITY else min(wanted, hard)
        resource.setrlimit(resource.RLIMIT_NOFILE, (soft, hard))
    available = MAX_CONNECTIONS if soft == resource.RLIM_INFINITY else soft - FD_RESERVE
    return Limits(head_timeout_s, max(1, min(MAX_CONNECTIONS, available)))


def _quiet_floods() -> None:
    """Write the lines a flood of clients repeats at most once per :data:`LOG_INTERVAL_S` each."""
    logging.getLogger("asyncio").addFilter(OneLine())
    for name in ("asyncio", "uvicorn.error", logger.name):
        logging.getLogger(name).addFilter(OncePerInterval())


def serve(app: Any, listening: socket.socket, limits: Limits, log_level: str = "warning") -> None:
    """Serve ``app`` with uvicorn on the listening socket, guarded by ``limits``, until told to stop; uvicorn's
    log at ``log_level``."""
    import uvicorn

    _quiet_floods()
    protocol = type("Guarded", (GuardedH11Protocol,), {"limits": limits})
    config = uvicorn.Config(
        app,
        log_level=log_level,
        access_log=False,  # csws serve --access-log writes its own (service.access_log)
        http=protocol,
        timeout_keep_alive=int(KEEP_ALIVE_S),
        h11_max_incomplete_event_size=MAX_HEAD_BYTES,
    )
    uvicorn.Server(config).run(sockets=[listening])
