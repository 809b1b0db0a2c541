"""The HTTP service as its operators run it, on loopback: ``uvicorn`` (:class:`Server`) and
``csws serve --workers N`` (:class:`Workers`), each a subprocess that a test's own fixture starts
with its networks and settings and stops, crashes or kills as the test needs; and a client that
keeps switching vehicles while that happens (:class:`SwitchWriter`).
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import httpx
from builders import TRACK_NET

from service.settings import ServiceSettings
from service.store import VehicleSetting, open_store

STARTUP_TIMEOUT_S = 60.0


def free_port() -> int:
    """A loopback port that nothing listens on now."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


class Server:
    """``python -m uvicorn --factory service.app:create_app`` on loopback, stopped by :meth:`stop`."""

    def __init__(self, nets: list[Path], state_db: Path, **settings: str) -> None:
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        env = {
            **os.environ,
            "CSWS_NETS": os.pathsep.join(map(str, nets)),
            "CSWS_STATE_DB": str(state_db),
            **{f"CSWS_{name.upper()}": value for name, value in settings.items()},
        }
        self.process = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "uvicorn",
                "--factory",
                "service.app:create_app",
                "--host",
                "127.0.0.1",
                "--port",
                str(self.port),
                "--log-level",
                "warning",
            ],
            env=env,
            cwd=Path(__file__).resolve().parents[1],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
        )
        self.client = httpx.Client(base_url=self.url, timeout=30.0)
        deadline = time.monotonic() + STARTUP_TIMEOUT_S
        while time.monotonic() < deadline:
            if self.process.poll() is not None:
                output = self.process.stdout.read() if self.process.stdout else b""
                raise RuntimeError(f"the service exited: {output.decode()}")
            try:
                if self.client.get("/readyz").status_code == 200:
                    return
            except httpx.TransportError:
                time.sleep(0.1)
        self.stop()
        raise RuntimeError(f"the service was not ready within {STARTUP_TIMEOUT_S} s")

    def stop(self) -> None:
        """Close the client and SIGTERM the service (SIGKILL after 10 s)."""
        self.client.close()
        self.process.terminate()
        try:
            self.process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait(timeout=10)


class Workers:
    """``csws serve --workers 2`` on a free loopback port, ready (at least one worker answers), in a
    process group of its own so that the whole server can be killed at once (:meth:`crash`).

    Parameters
    ----------
    nets
        The networks to serve.
    state_options
        Where the state is kept: ``--state-db FILE`` or ``--state URL``.
    workers
        How many workers.
    startup_timeout_s
        How long it may take to be ready, s (a large network takes longer).
    """

    def __init__(
        self, nets: list[Path], *state_options: str, workers: int = 2, startup_timeout_s: float = STARTUP_TIMEOUT_S
    ) -> None:
        self.url = f"http://127.0.0.1:{free_port()}"
        self.process = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "csws",
                "serve",
                *(f"--net={net}" for net in nets),
                *state_options,
                "--port",
                self.url.rsplit(":", 1)[1],
                "--workers",
                str(workers),
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,
        )
        deadline = time.monotonic() + startup_timeout_s
        while time.monotonic() < deadline:
            try:
                if httpx.get(f"{self.url}/readyz", timeout=2.0).status_code == 200:
                    return
            except httpx.TransportError:
                time.sleep(0.2)
        self.crash()
        raise RuntimeError(f"csws serve --workers {workers} was not ready within {startup_timeout_s} s")

    def clients(self) -> tuple[httpx.Client, httpx.Client]:
        """Two keep-alive connections served by different workers (``/metrics`` names the worker that answers)."""
        first = httpx.Client(base_url=self.url, timeout=30.0)
        worker = worker_of(first)
        for _ in range(100):
            other = httpx.Client(base_url=self.url, timeout=30.0)
            if worker_of(other) != worker:
                return first, other
            other.close()
        raise RuntimeError("100 connections in a row were served by the same worker")

    def stop(self) -> None:
        """SIGTERM, as an operator stops it."""
        self.process.terminate()
        try:
            self.process.wait(timeout=15)
        except subprocess.TimeoutExpired:
            self.crash()

    def crash(self) -> None:
        """SIGKILL to the master and its workers at once: nothing gets the chance to finish."""
        os.killpg(self.process.pid, signal.SIGKILL)
        self.process.wait(timeout=10)


def worker_of(client: httpx.Client) -> str:
    """The process id of the worker serving ``client``'s connection (the ``X-Csws-Worker`` header of ``/metrics``)."""
    return client.get("/metrics").headers["x-csws-worker"]


class SwitchWriter:
    """PUTs switching vehicles v0 to v999 (even ones on, odd ones off) one after the other, on a
    thread of its own, until done or the server is gone; what was acknowledged and what refused."""

    def __init__(self, url: str) -> None:
        self.acknowledged: list[str] = []
        self.refused: list[httpx.Response] = []
        self.thread = threading.Thread(target=self._put_all, args=(url,))
        self.thread.start()

    def _put_all(self, url: str) -> None:
        with httpx.Client(base_url=url, timeout=10.0) as client:
            for number in range(1000):
                try:
                    answer = client.put(f"/v1/vehicles/v{number}", json={"switched_on": number % 2 == 0})
                except httpx.TransportError:
                    return
                if answer.status_code == 200:
                    self.acknowledged.append(f"v{number}")
                else:
                    self.refused.append(answer)

    def wait_for(self, condition, timeout_s: float = 60.0) -> None:
        """Wait until ``condition(self)`` holds."""
        deadline = time.monotonic() + timeout_s
        while not condition(self):
            assert time.monotonic() < deadline, "the writer did not get there"
            time.sleep(0.01)

    def assert_stored(self, state: dict[str, Any]) -> None:
        """Every acknowledged switch is in the store, as it was set."""
        self.thread.join(timeout=120)
        store = open_store(ServiceSettings(nets=[TRACK_NET], **state))
        stored = store.read(self.acknowledged)
        store.close()
        assert all(stored[v].setting == VehicleSetting(int(v[1:]) % 2 == 0) for v in self.acknowledged)


def state_options(state: dict[str, str]) -> list[str]:
    """The command-line options of a ``state`` fixture's store."""
    return ["--state", state["state"]] if "state" in state else ["--state-db", state["state_db"]]
