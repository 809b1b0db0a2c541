"""The service held at saturation on loopback: throughput, latency, errors and memory; and
the throughput of two workers against one.

``CLIENTS`` concurrent clients (asyncio and httpx, one keep-alive connection each) post
single ``POST /v1/warning`` fixes back to back to one uvicorn worker serving the Table 7
track, for a fixed time: the server always has a request waiting. Each vehicle id sends
:data:`FIXES_PER_VEHICLE` fixes and then falls silent for good, like a vehicle leaving the
area, and the service runs with a short session idle time, so sessions expire as fast as
new vehicles come. The server's resident memory (``VmRSS`` of ``/proc/PID/status``) after a
warm-up and at the end must differ by at most :data:`MAX_RSS_GROWTH_MB`; no request may
fail.

:func:`run_workers` drives ``csws serve --workers 1`` and ``--workers 2`` (the vehicles in one
SQLite state file, as in production) with the same clients, posting batches of
:data:`WORKERS_BATCH_SIZE` vehicles as fleet backends do, in alternating rounds so that both
see the same machine load, and gives the ratio of their throughputs in queries/s. The clients
run on the same machine and take part of what the second worker would use.

Everything is bounded: the run stops at its deadline, every request has a timeout, and
the server is stopped at the end whatever happens.

Run with ``python -m benchmarks.load [--seconds 60] [--clients 16] [--session-idle-s 2]``, or
``python -m benchmarks.load --workers [--seconds 60]`` for the comparison of the worker counts.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import httpx
import numpy as np

from benchmarks.service import SERVICE, TRACK_NET, _fixes, _start

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
#: load: clients posting batches of this many vehicles (a single query costs the client about as
#: much as the service, so that on a small machine the clients and not the workers would decide).
WORKER_COUNTS = (1, 2)
WORKER_ROUNDS = 2
WORKERS_CLIENTS = 4
WORKERS_BATCH_SIZE = 50
#: Target: two workers answer at least this many times what one answers (the clients
#: run on the same machine: on two cores they take part of what the second would use).
MIN_WORKERS_RATIO = 1.2


def rss_mb(pid: int) -> float:
    """Resident memory of a process from ``/proc/PID/status`` (``VmRSS``), MB."""
    with open(f"/proc/{pid}/status", encoding="ascii") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    raise RuntimeError(f"no VmRSS in /proc/{pid}/status")


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


async def _client(url: str, number: int, fixes: list[dict], deadline: float, tally: Tally, batch_size: int = 0) -> None:
    """Post fixes back to back until ``deadline``: one per ``POST /v1/warning``, or ``batch_size`` vehicles'
    fixes per ``POST /v1/warnings``; each vehicle sends :data:`FIXES_PER_VEHICLE` fixes, then new ones come."""
    headers = {"content-type": "application/json"}
    size, path = (batch_size, "/v1/warnings") if batch_size else (1, "/v1/warning")
    sent = 0
    async with httpx.AsyncClient(base_url=url, timeout=REQUEST_TIMEOUT_S) as client:
        while time.monotonic() < deadline:
            first_vehicle, fix = divmod(sent, FIXES_PER_VEHICLE)
            tally.vehicles += size if fix == 0 else 0
            queries = [{**fixes[(sent * size + i) % len(fixes)], "vehicle_id": f"c{number}-v{first_vehicle * size + i}"}
                       for i in range(size)]  # fmt: skip
            body = json.dumps({"queries": queries} if batch_size else queries[0])
            sent += 1
            started = time.perf_counter()
            try:
                response = await client.post(path, content=body, headers=headers)
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
    fixes = _fixes(1000)
    tally = Tally()
    health_s: list[float] = []
    started = time.monotonic()
    deadline = started + seconds
    runs = asyncio.gather(_health(url, deadline, health_s), *(_client(url, n, fixes, deadline, tally) for n in range(clients)))
    await asyncio.sleep(min(WARM_UP_FRACTION * seconds, MAX_WARM_UP_S))
    warm_rss_mb = rss_mb(pid)
    await asyncio.wait_for(runs, timeout=seconds + 2 * REQUEST_TIMEOUT_S)
    return tally, time.monotonic() - started, warm_rss_mb, rss_mb(pid), health_s


async def _saturate(url: str, seconds: float, clients: int, batch_size: int) -> Tally:
    """Only the clients (with batches of ``batch_size``), for ``seconds``: what the service answers at saturation."""
    fixes = _fixes(1000)
    tally = Tally()
    deadline = time.monotonic() + seconds
    clients_done = asyncio.gather(*(_client(url, n, fixes, deadline, tally, batch_size) for n in range(clients)))
    await asyncio.wait_for(clients_done, timeout=seconds + 2 * REQUEST_TIMEOUT_S)
    return tally


def run_workers(seconds: float = SECONDS, clients: int = WORKERS_CLIENTS, batch_size: int = WORKERS_BATCH_SIZE) -> dict:
    """Hold ``csws serve --workers N`` at saturation for each of :data:`WORKER_COUNTS`, ``seconds`` in all
    shared out in alternating rounds; return each one's throughput in queries/s and the ratio of the
    last to the first."""
    answered = dict.fromkeys(WORKER_COUNTS, 0)
    errors = 0
    round_s = seconds / (len(WORKER_COUNTS) * WORKER_ROUNDS)
    with tempfile.TemporaryDirectory(prefix="csws-bench-workers-") as folder:
        for _ in range(WORKER_ROUNDS):
            for workers in WORKER_COUNTS:
                process, url = _start(["csws", "serve", "--net", str(TRACK_NET), "--workers", str(workers),
                                       "--state-db", str(Path(folder) / "vehicles.sqlite3")], {})  # fmt: skip
                try:
                    tally = asyncio.run(_saturate(url, round_s, clients, batch_size))
                finally:
                    process.terminate()
                    process.wait(timeout=15)
                answered[workers] += len(tally.latencies_s) * batch_size
                errors += tally.errors
    rps = {workers: count / (round_s * WORKER_ROUNDS) for workers, count in answered.items()}
    first, last = WORKER_COUNTS[0], WORKER_COUNTS[-1]
    return {"seconds": round(seconds, 1), "clients": clients, "batch_size": batch_size, "errors": errors,
            **{f"queries_per_s_{workers}_workers": round(value, 1) for workers, value in rps.items()},
            "ratio": round(rps[last] / rps[first], 2)}


def run(seconds: float = SECONDS, clients: int = CLIENTS, session_idle_s: float = SESSION_IDLE_S) -> dict:
    """Start the service, hold it at saturation for ``seconds``, stop it; return the figures."""
    process, url = _start(SERVICE, {"CSWS_NETS": str(TRACK_NET), "CSWS_STATE_DB": ":memory:",
                                    "CSWS_SESSION_IDLE_S": str(session_idle_s)})  # fmt: skip
    try:
        start_rss_mb = rss_mb(process.pid)
        tally, measured_s, warm_rss_mb, end_rss_mb, health_s = asyncio.run(_drive(url, process.pid, seconds, clients))
        sessions = httpx.get(f"{url}/readyz").json()["vehicle_sessions"]
    finally:
        process.terminate()
        process.wait(timeout=10)
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
    parser.add_argument("--seconds", type=float, default=SECONDS, help=f"how long to load the service (default {SECONDS:g})")
    parser.add_argument("--clients", type=int, default=CLIENTS, help=f"concurrent clients (default {CLIENTS})")
    parser.add_argument("--session-idle-s", type=float, default=SESSION_IDLE_S,
                        help=f"the service's session idle time, s (default {SESSION_IDLE_S:g})")
    parser.add_argument("--workers", action="store_true",
                        help=f"compare the throughput of csws serve with 1 and with 2 workers instead "
                        f"({WORKERS_CLIENTS} clients posting batches of {WORKERS_BATCH_SIZE})")
    args = parser.parse_args()
    figures = run_workers(args.seconds) if args.workers else run(args.seconds, args.clients, args.session_idle_s)
    targets = {"errors": f"<= {MAX_ERRORS}", "rss_growth_mb": f"<= {MAX_RSS_GROWTH_MB:g}"}
    for name, value in figures.items():
        target = targets.get(name, "")
        print(f"{name:>26}: {value!s:<12} {('target ' + target) if target else ''}")


if __name__ == "__main__":
    main()
