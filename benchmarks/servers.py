"""Servers on loopback for the benchmarks: started, timed until ready, measured, stopped.

:func:`start` runs ``python -m COMMAND --host 127.0.0.1 --port PORT`` (uvicorn, or ``csws serve``)
on a free port and returns once ``/readyz`` answers 200, with the seconds that took: the
start-up of the service as an operator sees it. :func:`memory_mb` reads a process's resident
memory and its proportional share of the pages it shares with others (Linux
``/proc/PID/smaps_rollup``): workers forked from one master share the loaded networks, which
RSS counts in each of them and PSS divides among them.
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import httpx

__all__ = ["STARTUP_TIMEOUT_S", "Running", "start", "csws_serve", "memory_mb", "children", "cpu_s", "redis_server"]

#: How long a server may take to answer /readyz, s: the bundled networks fitted afresh take a while.
STARTUP_TIMEOUT_S = 180.0
#: How long a server may take to stop after SIGTERM before it is killed, s.
STOP_TIMEOUT_S = 15.0


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


@dataclass
class Running:
    """A server started by :func:`start`.

    Attributes
    ----------
    process
        Its (master) process.
    url
        Where it answers, ``http://127.0.0.1:PORT``.
    startup_s
        Seconds from its start to the first 200 of ``/readyz``.
    """

    process: subprocess.Popen
    url: str
    startup_s: float

    def stop(self) -> None:
        """SIGTERM, as an operator stops it; SIGKILL if it does not end."""
        self.process.terminate()
        try:
            self.process.wait(timeout=STOP_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait(timeout=STOP_TIMEOUT_S)


def start(command: list[str], env: dict[str, str] | None = None) -> Running:
    """``python -m COMMAND --host 127.0.0.1 --port PORT`` on a free port, ready.

    Raises
    ------
    RuntimeError
        If it exits or does not answer ``/readyz`` within :data:`STARTUP_TIMEOUT_S`.
    """
    port = _free_port()
    started = time.perf_counter()
    process = subprocess.Popen(
        [sys.executable, "-m", *command, "--host", "127.0.0.1", "--port", str(port)],
        env={**os.environ, **(env or {})},
        cwd=Path(__file__).resolve().parents[1],
        stdout=subprocess.DEVNULL,
    )
    url = f"http://127.0.0.1:{port}"
    deadline = time.monotonic() + STARTUP_TIMEOUT_S
    while time.monotonic() < deadline and process.poll() is None:
        try:
            if httpx.get(f"{url}/readyz").status_code == 200:
                return Running(process, url, time.perf_counter() - started)
        except httpx.TransportError:
            time.sleep(0.05)
    process.kill()
    process.wait(timeout=STOP_TIMEOUT_S)
    raise RuntimeError(f"{' '.join(command)} was not ready within {STARTUP_TIMEOUT_S} s (exit {process.returncode})")


def csws_serve(state_db: Path, *options: str) -> Running:
    """``csws serve OPTIONS`` with its vehicles in the SQLite file ``state_db``, ready."""
    return start(["csws", "serve", "--state-db", str(state_db), *options])


def memory_mb(pid: int) -> tuple[float, float]:
    """Resident memory (RSS) of a process and its proportional share (PSS), MB."""
    values = {}
    with open(f"/proc/{pid}/smaps_rollup", encoding="ascii") as rollup:
        for line in rollup:
            name, _, rest = line.partition(":")
            if name in ("Rss", "Pss"):
                values[name] = int(rest.split()[0]) / 1024.0
    return values["Rss"], values["Pss"]


def children(pid: int) -> list[int]:
    """The processes whose parent is ``pid`` (a master's workers), as Linux lists them."""
    return sorted(int(child) for child in Path(f"/proc/{pid}/task/{pid}/children").read_text().split())


def cpu_s(pids: list[int]) -> float:
    """CPU time (user and system) the processes ``pids`` have used so far, s."""
    ticks = 0
    for pid in pids:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        ticks += int(fields[11]) + int(fields[12])
    return ticks / os.sysconf("SC_CLK_TCK")


def redis_server(folder: Path) -> tuple[subprocess.Popen, str]:
    """A redis-server on a free loopback port, keeping its files in ``folder`` (no persistence: the benchmarks
    measure the service, not the disk); the process and the URL of its database 0."""
    binary = shutil.which("redis-server")
    if binary is None:
        raise RuntimeError("this benchmark needs redis-server (apt-get install redis-server)")
    port = _free_port()
    process = subprocess.Popen(
        [binary, "--bind", "127.0.0.1", "--port", str(port), "--dir", str(folder), "--save", ""],
        stdout=subprocess.DEVNULL,
    )
    time.sleep(0.5)
    return process, f"redis://127.0.0.1:{port}/0"
