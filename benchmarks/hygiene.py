"""The service under clients that misbehave: slow heads, and more connections than descriptors.

Each figure comes from a ``csws serve`` on loopback (the Table 7 track, vehicles in a SQLite
file), started and stopped here:

* ``/healthz`` latency (p50, p99) of an honest client opening a connection per request, with
  nothing else going on, and then with :data:`DRIPPING` connections dripping one header line
  each per second and :data:`SATURATING` clients posting single queries as fast as they are
  answered; the errors of the honest client and of the saturating ones; and how long the
  dripping connections stayed open (the head deadline, ``service.guard``);
* the same ``/healthz`` figures, quiet and under both loads, of a reference: a bare ASGI app
  (:func:`bare_app`, no framework, a constant answer to every request, the saturating clients'
  posts too) served by plain uvicorn, one worker, in the same harness. What the reference cannot
  reach on this machine, the service cannot either: its p99 under load is the floor that the
  machine and the harness (the clients run on the same two cores) set;
* descriptor exhaustion: a service whose descriptor limit is 128 (soft and hard) holding
  :data:`IDLE` idle connections: what ``/healthz`` answers meanwhile, how soon it answers 200
  after they leave, and how many log lines the service wrote.

Run with ``python -m benchmarks.hygiene``.
"""

from __future__ import annotations

import os
import resource
import selectors
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from contextlib import suppress
from pathlib import Path
from typing import cast

import httpx
import numpy as np

from benchmarks.command import arguments
from csws.networks import networks_dir

TRACK_NET = networks_dir() / "t7_left.net.xml"
DRIPPING = 1000
SATURATING = 32
IDLE = 140
MEASURE_S = 8.0
QUERY = {"vehicle_id": "truck", "category": "N", "speed_kmh": 80.0, "lane_id": "curve_0", "lane_pos_m": 85.0}
TARGETS = {"healthz_dripping_saturating_p99_ms": "<= 50", "exhaustion_log_lines": "<= 10"}


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


async def bare_app(scope: dict, receive: Callable, send: Callable) -> None:
    """A bare ASGI app, the reference: reads each request's body and answers 200 with a constant JSON body."""
    if scope["type"] == "lifespan":
        while (await receive())["type"] != "lifespan.shutdown":
            await send({"type": "lifespan.startup.complete"})
        await send({"type": "lifespan.shutdown.complete"})
        return
    if scope["type"] != "http":
        return
    while (await receive()).get("more_body", False):
        pass
    await send({"type": "http.response.start", "status": 200, "headers": [(b"content-type", b"application/json")]})
    await send({"type": "http.response.body", "body": b'{"status":"ok"}'})


def _serve(folder: Path, nofile: int | None = None, bare: bool = False) -> tuple[subprocess.Popen, int, Path]:
    """``csws serve`` on the track (or plain uvicorn serving :func:`bare_app`), ready; its process, port and
    log file."""
    port, log = _free_port(), folder / f"serve-{time.monotonic_ns()}.log"
    if bare:
        command = ["uvicorn", "benchmarks.hygiene:bare_app", "--log-level", "warning", "--port", str(port)]
    else:
        command = ["csws", "serve", f"--net={TRACK_NET}", "--port", str(port)]
        command += ["--state-db", str(folder / f"v{port}.sqlite3")]
    with log.open("wb") as out:
        process = subprocess.Popen(
            [sys.executable, "-m", *command],
            cwd=Path(__file__).resolve().parents[1],
            stdout=out,
            stderr=subprocess.STDOUT,
            preexec_fn=(lambda: resource.setrlimit(resource.RLIMIT_NOFILE, (nofile, nofile))) if nofile else None,
        )
    deadline = time.monotonic() + 60.0
    while time.monotonic() < deadline:
        try:
            if httpx.get(f"http://127.0.0.1:{port}/readyz").status_code == 200:
                return process, port, log
        except httpx.TransportError:
            time.sleep(0.1)
    process.kill()
    raise RuntimeError("csws serve was not ready within 60 s")


def _healthz_once(port: int) -> bool:
    """One ``GET /healthz`` on a new connection, by hand (an HTTP client's own set-up would dominate); 200?"""
    with socket.create_connection(("127.0.0.1", port), timeout=5.0) as sock:
        sock.sendall(b"GET /healthz HTTP/1.1\r\nHost: bench\r\nConnection: close\r\n\r\n")
        answer = b""
        while chunk := sock.recv(4096):
            answer += chunk
    return answer.startswith(b"HTTP/1.1 200")


def _healthz_ms(port: int, seconds: float) -> tuple[np.ndarray, int]:
    """Latencies of ``/healthz``, each on a new connection, for ``seconds``; and the errors."""
    latencies, errors = [], 0
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        started = time.perf_counter()
        try:
            ok = _healthz_once(port)
        except OSError:
            ok = False
        latencies.append((time.perf_counter() - started) * 1000.0)
        errors += not ok
        time.sleep(0.02)
    return np.array(latencies), errors


def _drip(port: int, count: int, seconds: float, open_s: list[float]) -> None:
    """``count`` connections sending one header line a second until closed or ``seconds`` pass; how long
    each stayed open goes to ``open_s``."""
    selector = selectors.DefaultSelector()
    started = {}
    for _ in range(count):
        sock = socket.create_connection(("127.0.0.1", port))
        sock.sendall(b"GET /healthz HTTP/1.1\r\n")
        sock.setblocking(False)
        selector.register(sock, selectors.EVENT_READ)
        started[sock] = time.monotonic()
    end = time.monotonic() + seconds
    next_drip = time.monotonic() + 1.0
    while started and time.monotonic() < end:
        for key, _events in selector.select(timeout=0.1):
            ended = cast(socket.socket, key.fileobj)  # readable: the 408 or the close that ends the head
            with suppress(OSError):
                ended.recv(4096)
            open_s.append(time.monotonic() - started.pop(ended))
            selector.unregister(ended)
            ended.close()
        if time.monotonic() >= next_drip:
            for sock in list(started):
                with suppress(OSError):
                    sock.send(b"X-Drip: 1\r\n")
            next_drip += 1.0
    for sock in started:
        sock.close()


def _saturate(port: int, stop: threading.Event, errors: list[int]) -> None:
    """Post single queries as fast as they are answered until ``stop``; count the errors."""
    with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=10.0) as client:
        while not stop.is_set():
            try:
                if client.post("/v1/warning", json=QUERY).status_code != 200:
                    errors.append(1)
            except httpx.HTTPError:
                errors.append(1)


def _under(port: int, dripping: int, saturating: int) -> dict:
    """``/healthz`` latencies with ``dripping`` connections dripping heads and ``saturating`` clients."""
    open_s: list[float] = []
    saturating_errors: list[int] = []
    stop = threading.Event()
    load = [threading.Thread(target=_saturate, args=(port, stop, saturating_errors)) for _ in range(saturating)]
    drip = threading.Thread(target=_drip, args=(port, dripping, 15.0, open_s))
    for thread in [drip, *load]:
        thread.start()
    time.sleep(1.0)
    latencies, errors = _healthz_ms(port, MEASURE_S)
    stop.set()
    for thread in [drip, *load]:
        thread.join()
    return {
        "p50_ms": round(float(np.percentile(latencies, 50)), 2),
        "p99_ms": round(float(np.percentile(latencies, 99)), 2),
        "errors": errors + len(saturating_errors),
        "closed": len(open_s),
        "open_s_max": round(max(open_s), 2) if open_s else None,
    }


#: The loads ``/healthz`` is measured under: (dripping connections, saturating clients) by phase.
PHASES = {
    "quiet": (0, 0),
    "dripping": (DRIPPING, 0),
    "saturating": (0, SATURATING),
    "dripping_saturating": (DRIPPING, SATURATING),
}


def dripping(folder: Path, bare: bool = False, phases: tuple[str, ...] = tuple(PHASES)) -> dict:
    """``/healthz`` of the service (or of the reference, ``bare``) in each of ``phases``."""
    process, port, _log = _serve(folder, bare=bare)
    figures = {}
    try:
        for phase in phases:
            drips, clients = PHASES[phase]
            for name, value in _under(port, drips, clients).items():
                if drips or name not in ("closed", "open_s_max"):
                    figures[f"{'reference_' if bare else ''}healthz_{phase}_{name}"] = value
    finally:
        process.terminate()
        process.wait(timeout=15)
    return figures


def exhaustion(folder: Path) -> dict:
    """A service at 128 descriptors holding :data:`IDLE` idle connections, and after they leave."""
    os.environ["CSWS_HEAD_TIMEOUT_S"] = "60"  # idle for the whole measure
    try:
        process, port, log = _serve(folder, nofile=128)
    finally:
        del os.environ["CSWS_HEAD_TIMEOUT_S"]
    idle = []
    try:
        idle = [socket.create_connection(("127.0.0.1", port)) for _ in range(IDLE)]
        time.sleep(1.0)
        held = httpx.get(f"http://127.0.0.1:{port}/healthz", timeout=5.0).status_code
        for sock in idle:
            sock.close()
        left = time.perf_counter()
        while httpx.get(f"http://127.0.0.1:{port}/healthz", timeout=5.0).status_code != 200:
            time.sleep(0.01)
        recovered_ms = (time.perf_counter() - left) * 1000.0
    finally:
        for sock in idle:
            sock.close()
        process.terminate()
        process.wait(timeout=15)
    return {
        "exhaustion_healthz_status_held": held,
        "exhaustion_recovery_ms": round(recovered_ms, 1),
        "exhaustion_log_lines": len(log.read_text(errors="replace").splitlines()) - 1,  # less "serving"
    }


def run() -> dict:
    """Measure the service, the reference (quiet and under both loads) and exhaustion; the figures."""
    with tempfile.TemporaryDirectory(prefix="csws-bench-hygiene-") as folder:
        reference = dripping(Path(folder), bare=True, phases=("quiet", "dripping_saturating"))
        return dripping(Path(folder)) | reference | exhaustion(Path(folder))


def main() -> None:
    """Print each figure beside its target."""
    arguments("benchmarks.hygiene", __doc__)
    for name, value in run().items():
        target = TARGETS.get(name, "")
        print(f"{name:>32}: {value!s:<10} {('target ' + target) if target else ''}")


if __name__ == "__main__":
    main()
