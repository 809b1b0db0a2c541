"""The workers of ``csws serve --workers N``: forked from a master that loaded everything once.

The master builds the app (networks read, road chains fitted or read from the profile
cache, the spatial index and the engines made, the state store checked), binds the
address, moves every object it made out of the garbage collector's reach (``gc.freeze``),
and forks the workers. They share the loaded networks copy-on-write: N workers cost one
start-up, and the pages of the arrays stay shared because nothing writes to them, not even
a collection. Each worker listens on the address with a socket of its own (Linux's
``SO_REUSEPORT``), so that the kernel spreads new connections over the workers: on one
shared socket, the worker that wakes first accepts every waiting connection, and a burst of
clients can land on a single worker. Only sockets of one service share the port: the master
first makes sure that nothing else listens on it (:func:`_free_port`). Each worker serves
through the connection guard of :mod:`service.guard`. Each worker has its own event loop and its own
connection to the state store; a worker that dies is forked again from the master, ready
at once. The master stops its workers when it is told to
stop (SIGTERM, SIGINT), and a worker whose master is gone leaves (:func:`leave_with_master`).
"""

from __future__ import annotations

import errno
import gc
import os
import shutil
import signal
import socket
import sys
import tempfile
import threading
import time
from contextlib import suppress
from typing import Any

from .guard import Limits, serve
from .metrics import METRICS_DIR_VARIABLE

__all__ = [
    "MASTER_PID_VARIABLE",
    "MASTER_CHECK_S",
    "RESPAWN_PAUSE_S",
    "OWN_SOCKETS",
    "leave_with_master",
    "bound_socket",
    "listening_socket",
    "start_listening",
    "serve_forked",
]

#: Set by ``csws serve --workers N`` for its workers: the process id of the master.
MASTER_PID_VARIABLE = "CSWS_MASTER_PID"
#: How often a worker looks whether its master is still there, s.
MASTER_CHECK_S = 1.0
#: A worker that died within this long of being forked is forked again only after this pause, s,
#: so that one failing at once does not make the master fork without end.
RESPAWN_PAUSE_S = 1.0
#: Whether each worker listens on a socket of its own, among which the kernel balances connections.
OWN_SOCKETS = sys.platform.startswith("linux") and hasattr(socket, "SO_REUSEPORT")
#: Connections waiting to be accepted, per listening socket.
BACKLOG = 2048


def leave_with_master() -> None:
    """In a worker of ``csws serve --workers N``: end this process when the master is gone.

    A master killed with SIGKILL cannot stop its workers, and they would go on serving, the
    port taken, with nobody to restart or stop them. Each worker checks every
    :data:`MASTER_CHECK_S` whether its parent is still the master (from its start-up on, so
    that one still starting when the master died leaves too), and otherwise shuts down as
    on SIGTERM. Outside such a worker (no master recorded) nothing is started.
    """
    master = os.environ.get(MASTER_PID_VARIABLE)
    if not master:
        return
    # A worker still starting when its master was killed finds another parent at once, and leaves.

    def watch() -> None:
        while os.getppid() == int(master):
            time.sleep(MASTER_CHECK_S)
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(3.0)
        os._exit(1)  # the graceful shutdown did not end it

    threading.Thread(target=watch, name="csws-master-watch", daemon=True).start()


def _tcp_socket(family: int) -> socket.socket:
    """A TCP socket made as TCP (protocol ``IPPROTO_TCP``), so that asyncio switches Nagle's algorithm
    off on its connections: small answers go out at once, never waiting about 40 ms for the
    client's delayed acknowledgement (uvicorn issue 3149)."""
    made = socket.socket(family, socket.SOCK_STREAM, socket.IPPROTO_TCP)
    made.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    if OWN_SOCKETS:
        made.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEPORT, 1)
    return made


def _resolved(host: str, port: int) -> tuple[int, Any]:
    """The address family and socket address of ``host:port``."""
    family, _kind, _protocol, _name, address = socket.getaddrinfo(
        host, port, type=socket.SOCK_STREAM, proto=socket.IPPROTO_TCP
    )[0]
    return family, address


def _in_use(host: str, port: int, error: OSError) -> OSError:
    """The one-line error of an address that cannot be bound."""
    reason = (
        "it is in use (another program, or another csws serve)" if error.errno == errno.EADDRINUSE else error.strerror
    )
    return OSError(f"cannot listen on {host}:{port}: {reason}; give another --port")


def _free_port(family: int, address: Any) -> int:
    """The port of ``address`` if nothing else listens on it; raises OSError otherwise.

    Sockets with ``SO_REUSEPORT`` of one user share a port, so a second service would join the
    first and the kernel would split the connections between them. A probe socket bound
    without ``SO_REUSEPORT`` fails on any socket listening on the port, ``SO_REUSEPORT`` or
    not, and then nothing is served; the service's own sockets are bound after it is closed.
    (Only a second service starting in the same instant can slip in between.) Port 0 is
    resolved here to the free port the probe got.
    """
    with socket.socket(family, socket.SOCK_STREAM, socket.IPPROTO_TCP) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # connections of an earlier run in TIME_WAIT
        probe.bind(address)
        return int(probe.getsockname()[1])


def bound_socket(host: str, port: int) -> socket.socket:
    """The master's socket on ``host:port``: bound, so that an address in use is an error before any
    worker starts, also when the other is a service listening with ``SO_REUSEPORT``
    (:func:`_free_port`); listening only where the workers share it (without :data:`OWN_SOCKETS`).

    Raises
    ------
    OSError
        If the address cannot be bound.
    """
    family, address = _resolved(host, port)
    bound = _tcp_socket(family)
    try:
        if OWN_SOCKETS:
            address = (address[0], _free_port(family, address), *address[2:])
        bound.bind(address)
    except OSError as error:
        bound.close()
        raise _in_use(host, port, error) from None
    if not OWN_SOCKETS:
        bound.listen(BACKLOG)
    return bound


def listening_socket(host: str, port: int) -> socket.socket:
    """A socket listening on ``host:port`` for a single server process, bound before anything is
    said to be served (:func:`bound_socket`)."""
    return start_listening(bound_socket(host, port))


def start_listening(bound: socket.socket) -> socket.socket:
    """The socket of :func:`bound_socket`, listening for a single server process (once it is ready to answer:
    until then a client is refused rather than left waiting)."""
    if OWN_SOCKETS:
        bound.listen(BACKLOG)
    return bound


def _worker_socket(master: socket.socket) -> socket.socket:
    """In a worker: a listening socket of its own on the master's address (port 0 resolved), or the
    master's where sockets are shared."""
    if not OWN_SOCKETS:
        return master
    own = _tcp_socket(master.family)
    own.bind(master.getsockname())
    own.listen(BACKLOG)
    return own


def _run_worker(app: Any, master: socket.socket, limits: Limits, log_level: str) -> None:
    """In a forked worker: serve ``app`` on the master's address until told to stop, then exit."""
    status = 1
    try:
        serve(app, _worker_socket(master), limits, log_level)
        status = 0
    finally:
        os._exit(status)  # never return into the master's code


def serve_forked(app: Any, master: socket.socket, workers: int, limits: Limits, log_level: str = "warning") -> None:
    """Fork ``workers`` processes serving ``app`` on the address of ``master``, keep that many until stopped.

    The workers share their metrics through a temporary folder of the master's (:mod:`service.metrics`),
    removed when it stops.

    Parameters
    ----------
    app
        The ASGI app, built (networks loaded) in this process.
    master
        The master's socket (:func:`bound_socket`).
    workers
        How many worker processes.
    limits
        The bounds of each worker's connections (:mod:`service.guard`).
    log_level
        The level of uvicorn's log in the workers.
    """
    os.environ[MASTER_PID_VARIABLE] = str(os.getpid())  # the workers leave when this process is gone
    metrics_folder = tempfile.mkdtemp(prefix="csws-metrics-")
    os.environ[METRICS_DIR_VARIABLE] = metrics_folder  # each worker's counters, summed by /metrics
    gc.collect()
    gc.freeze()  # what the master made is shared with the workers: no collection may write to it
    forked_at_s: dict[int, float] = {}
    stopping: list[int] = []
    stop_signals = {signal.SIGTERM, signal.SIGINT}

    def fork() -> None:
        signal.pthread_sigmask(signal.SIG_BLOCK, stop_signals)  # no stop() in a worker before it resets
        pid = os.fork()
        if pid == 0:
            for number in stop_signals:
                signal.signal(number, signal.SIG_DFL)
            signal.pthread_sigmask(signal.SIG_UNBLOCK, stop_signals)
            _run_worker(app, master, limits, log_level)
        forked_at_s[pid] = time.monotonic()
        signal.pthread_sigmask(signal.SIG_UNBLOCK, stop_signals)

    def stop(signal_number: int, _frame: Any) -> None:
        stopping.append(signal_number)
        for pid in list(forked_at_s):
            with suppress(ProcessLookupError):
                os.kill(pid, signal.SIGTERM)

    previous = {number: signal.signal(number, stop) for number in stop_signals}
    try:
        for _ in range(workers):
            fork()
        while forked_at_s:
            pid, _status = os.wait()
            lived_s = time.monotonic() - forked_at_s.pop(pid, time.monotonic())
            if not stopping:
                if lived_s < RESPAWN_PAUSE_S:
                    time.sleep(RESPAWN_PAUSE_S)
                fork()
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)
        master.close()
        shutil.rmtree(metrics_folder, ignore_errors=True)
        del os.environ[METRICS_DIR_VARIABLE]
