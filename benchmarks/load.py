"""The service held at saturation on loopback: throughput, latency, errors and memory; and
the single-query throughput of two workers against one.

``CLIENTS`` concurrent clients (asyncio and httpx, one keep-alive connection each) post
single ``POST /v1/warning`` fixes back to back to one uvicorn worker serving the Table 7
track, for a fixed time: the server always has a request waiting. Each vehicle id sends
:data:`FIXES_PER_VEHICLE` fixes and then falls silent for good, like a vehicle leaving the
area, and the service runs with a short session idle time, so sessions expire as fast as
new vehicles come. The server's resident memory after a warm-up and at the end must differ
by at most :data:`MAX_RSS_GROWTH_MB`; no request may fail.

:func:`run_workers` drives ``csws serve --workers 1`` and ``--workers 2`` on the Table 7 track (the
vehicles in one SQLite state file, as in production) with single queries, in alternating rounds
so that both see the same machine load, and gives the ratio of their throughputs. The clients
run on the same machine, so they are lean: :data:`WORKERS_CONNECTIONS` keep-alive connections
in one asyncio loop writing prepared HTTP/1.1 requests and reading each answer by its length,
a few percent of a core where httpx would take about as much as a worker. Beside the ratio
come the cores the service's processes used in each case, the share of a core the clients
took and the machine's load average: on a shared machine they bound what a second worker can add.

Everything is bounded: the run stops at its deadline, every request has a timeout, and
the server is stopped at the end whatever happens.

Run with ``python -m benchmarks.load [--seconds 60] [--clients 16] [--session-idle-s 2]``, or
``python -m benchmarks.load --workers [--seconds 60]`` for the comparison of the worker counts.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import re
import tempfile
import time
from dataclasses import dataclass, field
from itertools import cycle
from pathlib import Path

import httpx
import numpy as np

from benchmarks.servers import children, cpu_s, csws_serve, memory_mb, start
from benchmarks.service import SERVICE, TRACK_NET, track_fixes

SECONDS = 60.0
CLIENTS = 16
SESSION_IDLE_S = 2.0
FIXES_PER_VEHICLE = 10
#: Part of the run (at most :data:`MAX_WARM_UP_S`) before the starting memory is read: caches fill.
WARM_UP_FRACTION = 0.1
MAX_WARM_UP_S = 5.0
REQUEST_TIMEOUT_S = 10.0
#: Targets: no failed request, and memory at the end within this much of that after the warm-up.
MAX_ERRORS = 0
MAX_RSS_GROWTH_MB = 20.0
#: While the server is saturated, /healthz is asked every this many seconds; its p99 must stay within the target.
HEALTH_PERIOD_S = 0.05
MAX_HEALTHZ_P99_MS = 50.0
#: Worker counts compared by :func:`run_workers`, how many alternating rounds each gets, and its
#: load: lean keep-alive connections posting single queries, each for its own vehicles.
WORKER_COUNTS = (1, 2)
WORKER_ROUNDS = 2
WORKERS_CONNECTIONS = 8
WORKERS_VEHICLES_PER_CONNECTION = 100
#: Target: two workers on two cores answer at least this many times the single queries one answers.
MIN_WORKERS_RATIO = 1.8
_CONTENT_LENGTH = re.compile(rb"content-length: *(\d+)", re.IGNORECASE)


def rss_mb(pid: int) -> float:
    """Resident memory of a process, MB."""
    return memory_mb(pid)[0]


@dataclass
class Tally:
    """What the clients saw: latency of every answered request, and the failures."""

    latencies_s: list[float] = field(default_factory=list)
    errors: int = 0
    first_error: str | None = None
    vehicles: int = 0

    def fail(self, reason: str) -> None:
        self.errors += 1
        self.first_error = self.first_error or reason


async def _client(url: str, number: int, fixes: list[dict], deadline: float, tally: Tally) -> None:
    """Post fixes back to back until ``deadline``, one per ``POST /v1/warning``; each vehicle sends
    :data:`FIXES_PER_VEHICLE` fixes, then a new one comes."""
    headers = {"content-type": "application/json"}
    sent = 0
    async with httpx.AsyncClient(base_url=url, timeout=REQUEST_TIMEOUT_S) as client:
        while time.monotonic() < deadline:
            vehicle, fix = divmod(sent, FIXES_PER_VEHICLE)
            tally.vehicles += 1 if fix == 0 else 0
            body = json.dumps({**fixes[sent % len(fixes)], "vehicle_id": f"c{number}-v{vehicle}"})
            sent += 1
            started = time.perf_counter()
            try:
                response = await client.post("/v1/warning", content=body, headers=headers)
            except httpx.HTTPError as error:
                tally.fail(f"{type(error).__name__}: {error}")
                continue
            if response.status_code != 200:
                tally.fail(f"HTTP {response.status_code}: {response.text[:200]}")
                continue
            tally.latencies_s.append(time.perf_counter() - started)


async def _health(url: str, deadline: float, latencies_s: list[float]) -> None:
    """Ask /healthz every :data:`HEALTH_PERIOD_S` until ``deadline``, on a connection of its own."""
    async with httpx.AsyncClient(base_url=url, timeout=REQUEST_TIMEOUT_S) as client:
        while time.monotonic() < deadline:
            started = time.perf_counter()
            response = await client.get("/healthz")
            if response.status_code == 200:
                latencies_s.append(time.perf_counter() - started)
            await asyncio.sleep(HEALTH_PERIOD_S)


async def _drive(url: str, pid: int, seconds: float, clients: int) -> tuple[Tally, float, float, float, list[float]]:
    """Run the clients and the health prober; return the tally, the measured seconds, the RSS
    after warm-up and at the end, and the /healthz latencies."""
    fixes = track_fixes(1000)
    tally = Tally()
    health_s: list[float] = []
    started = time.monotonic()
    deadline = started + seconds
    runs = asyncio.gather(
        _health(url, deadline, health_s), *(_client(url, n, fixes, deadline, tally) for n in range(clients))
    )
    await asyncio.sleep(min(WARM_UP_FRACTION * seconds, MAX_WARM_UP_S))
    warm_rss_mb = rss_mb(pid)
    await asyncio.wait_for(runs, timeout=seconds + 2 * REQUEST_TIMEOUT_S)
    return tally, time.monotonic() - started, warm_rss_mb, rss_mb(pid), health_s


def _post_request(path: str, body: bytes) -> bytes:
    """A keep-alive HTTP/1.1 POST of a JSON body, as bytes."""
    return (
        f"POST {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
        f"Content-Length: {len(body)}\r\n\r\n"
    ).encode() + body


async def _post_back_to_back(port: int, requests: list[bytes], deadline: float, tally: Tally) -> None:
    """Send ``requests`` in turn on one keep-alive connection, each when the answer before it came,
    until ``deadline``; an answer is read by its ``Content-Length``."""
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    try:
        for request in cycle(requests):
            if time.monotonic() >= deadline:
                return
            started = time.perf_counter()
            writer.write(request)
            head = await asyncio.wait_for(reader.readuntil(b"\r\n\r\n"), REQUEST_TIMEOUT_S)
            length = _CONTENT_LENGTH.search(head)
            if length is None:
                raise ValueError(f"an answer without Content-Length: {head.splitlines()[0].decode()}")
            body = await reader.readexactly(int(length.group(1)))
            if head[9:12] == b"200":
                tally.latencies_s.append(time.perf_counter() - started)
            else:
                tally.fail(f"{head.splitlines()[0].decode()}: {body[:200].decode(errors='replace')}")
    finally:
        writer.close()


async def _saturate(url: str, seconds: float) -> Tally:
    """Lean connections posting single queries back to back for ``seconds``, each for its own vehicles."""
    fixes = track_fixes(WORKERS_VEHICLES_PER_CONNECTION)
    port = int(url.rsplit(":", 1)[1])
    tally = Tally()
    deadline = time.monotonic() + seconds

    def requests(connection: int) -> list[bytes]:
        bodies = [json.dumps({**fix, "vehicle_id": f"c{connection}-{fix['vehicle_id']}"}).encode() for fix in fixes]
        return [_post_request("/v1/warning", body) for body in bodies]

    connections = [_post_back_to_back(port, requests(n), deadline, tally) for n in range(WORKERS_CONNECTIONS)]
    await asyncio.wait_for(asyncio.gather(*connections), timeout=seconds + 2 * REQUEST_TIMEOUT_S)
    return tally


def run_workers(seconds: float = SECONDS) -> dict:
    """Hold ``csws serve --workers N`` at saturation with single queries for each of :data:`WORKER_COUNTS`,
    ``seconds`` in all shared out in alternating rounds; return each one's throughput in queries/s, the
    ratio of the last to the first, the share of a core the clients took and the machine's load average."""
    answered = dict.fromkeys(WORKER_COUNTS, 0)
    service_cpu_s = dict.fromkeys(WORKER_COUNTS, 0.0)
    errors, first_error, client_cpu_s = 0, None, 0.0
    round_s = seconds / (len(WORKER_COUNTS) * WORKER_ROUNDS)
    load_average = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="csws-bench-workers-") as folder:
        for _ in range(WORKER_ROUNDS):
            for workers in WORKER_COUNTS:
                served = csws_serve(
                    Path(folder) / "vehicles.sqlite3", "--net", str(TRACK_NET), "--workers", str(workers)
                )
                try:
                    processes = [served.process.pid, *children(served.process.pid)]
                    cpu_before, service_before = time.process_time(), cpu_s(processes)
                    tally = asyncio.run(_saturate(served.url, round_s))
                    client_cpu_s += time.process_time() - cpu_before
                    service_cpu_s[workers] += cpu_s(processes) - service_before
                finally:
                    served.stop()
                answered[workers] += len(tally.latencies_s)
                errors += tally.errors
                first_error = first_error or tally.first_error
    rps = {workers: count / (round_s * WORKER_ROUNDS) for workers, count in answered.items()}
    first, last = WORKER_COUNTS[0], WORKER_COUNTS[-1]
    return {
        "seconds": round(seconds, 1),
        "connections": WORKERS_CONNECTIONS,
        "errors": errors,
        "first_error": first_error,
        **{f"queries_per_s_{workers}_workers": round(value, 1) for workers, value in rps.items()},
        **{
            f"service_cores_{workers}_workers": round(used_s / (round_s * WORKER_ROUNDS), 2)
            for workers, used_s in service_cpu_s.items()
        },
        "ratio": round(rps[last] / rps[first], 2),
        "client_core_share": round(client_cpu_s / seconds, 2),
        "load_average_1min": round(load_average, 2),
    }


def run(seconds: float = SECONDS, clients: int = CLIENTS, session_idle_s: float = SESSION_IDLE_S) -> dict:
    """Start the service, hold it at saturation for ``seconds``, stop it; return the figures."""
    served = start(
        SERVICE, {"CSWS_NETS": str(TRACK_NET), "CSWS_STATE_DB": ":memory:", "CSWS_SESSION_IDLE_S": str(session_idle_s)}
    )
    try:
        start_rss_mb = rss_mb(served.process.pid)
        tally, measured_s, warm_rss_mb, end_rss_mb, health_s = asyncio.run(
            _drive(served.url, served.process.pid, seconds, clients)
        )
        sessions = httpx.get(f"{served.url}/readyz").json()["vehicle_sessions"]
    finally:
        served.stop()
    latencies_ms = np.array(tally.latencies_s) * 1000.0
    return {
        "seconds": round(measured_s, 1),
        "clients": clients,
        "requests": len(latencies_ms) + tally.errors,
        "throughput_rps": round(len(latencies_ms) / measured_s, 1),
        "latency_ms_p50": round(float(np.percentile(latencies_ms, 50)), 2),
        "latency_ms_p99": round(float(np.percentile(latencies_ms, 99)), 2),
        "healthz_ms_p99": round(float(np.percentile(np.array(health_s) * 1000.0, 99)), 2) if health_s else None,
        "healthz_probes": len(health_s),
        "errors": tally.errors,
        "first_error": tally.first_error,
        "vehicles": tally.vehicles,
        "session_idle_s": session_idle_s,
        "sessions_at_end": sessions,
        "rss_mb_idle": round(start_rss_mb, 1),
        "rss_mb_start": round(warm_rss_mb, 1),
        "rss_mb_end": round(end_rss_mb, 1),
        "rss_growth_mb": round(end_rss_mb - warm_rss_mb, 1),
    }


def main() -> None:
    """Print each figure beside its target."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.load", description=__doc__.splitlines()[0])
    parser.add_argument(
        "--seconds", type=float, default=SECONDS, help=f"how long to load the service (default {SECONDS:g})"
    )
    parser.add_argument("--clients", type=int, default=CLIENTS, help=f"concurrent clients (default {CLIENTS})")
    parser.add_argument(
        "--session-idle-s",
        type=float,
        default=SESSION_IDLE_S,
        help=f"the service's session idle time, s (default {SESSION_IDLE_S:g})",
    )
    parser.add_argument(
        "--workers",
        action="store_true",
        help=f"compare the single-query throughput of csws serve with 1 and with 2 workers instead "
        f"({WORKERS_CONNECTIONS} lean keep-alive connections)",
    )
    args = parser.parse_args()
    figures = run_workers(args.seconds) if args.workers else run(args.seconds, args.clients, args.session_idle_s)
    targets = {
        "errors": f"<= {MAX_ERRORS}",
        "rss_growth_mb": f"<= {MAX_RSS_GROWTH_MB:g}",
        "ratio": f">= {MIN_WORKERS_RATIO:g}",
    }
    for name, value in figures.items():
        target = targets.get(name, "")
        print(f"{name:>26}: {value!s:<12} {('target ' + target) if target else ''}")


if __name__ == "__main__":
    main()
