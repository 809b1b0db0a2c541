"""How fast the HTTP service answers, against a trivial FastAPI endpoint served the same way.

Two uvicorn processes on loopback, started and stopped here: the service on the Table 7
track, and a trivial FastAPI app (:data:`trivial_app`) whose endpoint takes a JSON body
and answers a constant. Figures:

* single-query throughput: sequential keep-alive ``POST /v1/warning`` requests against
  the same number of ``POST /trivial`` requests with the same body, in interleaved
  rounds; the ratio is the target (>= 0.70);
* a 10,000-query batch (one fleet tick, fixes map-matched from x, y and heading): the
  server time the service reports in its ``Server-Timing`` header (target <= 100 ms),
  and where that time goes, measured in-process on the same batch: validation, reading
  the vehicles from the state store, map matching, engines, writing their sessions back,
  answer encoding to JSON.

Run with ``python -m benchmarks.service``.
"""

from __future__ import annotations

import gc
import json
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import httpx
import numpy as np
from fastapi import FastAPI, Request
from fastapi.responses import Response

from csws.networks import networks_dir

TRACK_NET = networks_dir() / "t7_left.net.xml"
STARTUP_TIMEOUT_S = 60.0
SINGLE_REQUESTS = 2000
SINGLE_ROUNDS = 10
BATCH_SIZE = 10_000
BATCH_REPEATS = 5

trivial_app = FastAPI()


@trivial_app.post("/trivial")
async def _trivial(request: Request) -> Response:
    await request.body()
    return Response(b'{"ok": true}', media_type="application/json")


@trivial_app.get("/readyz")
async def _ready() -> dict:
    return {"status": "ready"}


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


#: ``python -m`` of these serves the service and the trivial app (uvicorn).
SERVICE = ["uvicorn", "--factory", "service.app:create_app", "--log-level", "warning"]
TRIVIAL = ["uvicorn", "benchmarks.service:trivial_app", "--log-level", "warning"]


def _start(command: list[str], env: dict[str, str]) -> tuple[subprocess.Popen, str]:
    """``python -m COMMAND --host 127.0.0.1 --port PORT`` (uvicorn, or ``csws serve``) on a free port, ready."""
    port = _free_port()
    process = subprocess.Popen(
        [sys.executable, "-m", *command, "--host", "127.0.0.1", "--port", str(port)],
        env={**os.environ, **env}, cwd=Path(__file__).resolve().parents[1], stdout=subprocess.DEVNULL,
    )
    url = f"http://127.0.0.1:{port}"
    deadline = time.monotonic() + STARTUP_TIMEOUT_S
    while time.monotonic() < deadline:
        try:
            if httpx.get(f"{url}/readyz").status_code == 200:
                return process, url
        except httpx.TransportError:
            time.sleep(0.1)
    process.kill()
    raise RuntimeError(f"{' '.join(command)} was not ready within {STARTUP_TIMEOUT_S} s")


def _fixes(count: int, seed: int = 5) -> list[dict]:
    """Queries of ``count`` vehicles spread over the track's approach and first curve, as GNSS fixes."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(10.0, 990.0, count)
    y = rng.normal(0.0, 1.0, count)
    speed = rng.uniform(30.0, 120.0, count)
    categories = rng.choice(["M1", "M2", "M3", "N", "O"], count)
    return [
        {"vehicle_id": f"v{i}", "category": str(c), "speed_kmh": float(v), "position": {"x": float(a), "y": float(b)},
         "heading_deg": 90.0}
        for i, (a, b, v, c) in enumerate(zip(x, y, speed, categories))
    ]


def _requests_per_s(clients: dict[str, tuple[httpx.Client, str]], body: bytes, count: int) -> dict[str, float]:
    """Sequential keep-alive POSTs of ``body`` to each ``(client, path)``, ``count`` each, in interleaved rounds.

    Interleaving puts both servers under the same background load of the machine.
    """
    headers = {"content-type": "application/json"}
    for client, path in clients.values():
        for _ in range(50):
            client.post(path, content=body, headers=headers)
    elapsed_s = dict.fromkeys(clients, 0.0)
    for _ in range(SINGLE_ROUNDS):
        for name, (client, path) in clients.items():
            started = time.perf_counter()
            for _ in range(count // SINGLE_ROUNDS):
                client.post(path, content=body, headers=headers).raise_for_status()
            elapsed_s[name] += time.perf_counter() - started
    return {name: count // SINGLE_ROUNDS * SINGLE_ROUNDS / seconds for name, seconds in elapsed_s.items()}


def _breakdown_ms(queries: list[dict]) -> dict[str, float]:
    """Where a batch's server time goes, measured in-process on a fresh service set up as uvicorn runs it."""
    from service.answers import EncodedAnswers
    from service.app import create_app
    from service.decoding import DecodedBatch, decode
    from service.schemas import BATCH_ADAPTER
    from service.settings import ServiceSettings

    service = create_app(ServiceSettings(nets=[TRACK_NET], state_db=":memory:")).state.service
    gc.freeze()  # as the app's start-up does
    body = json.dumps({"queries": queries}).encode()
    service.answer(decode(body, DecodedBatch, BATCH_ADAPTER).queries)  # warm the look-ahead caches like a running server
    marks = [time.perf_counter()]
    batch = decode(body, DecodedBatch, BATCH_ADAPTER).queries
    marks.append(time.perf_counter())
    vehicles = service.registry.read({query.vehicle_id for query in batch})
    marks.append(time.perf_counter())
    service.check(batch, vehicles)
    placements = service.place(batch, vehicles)
    marks.append(time.perf_counter())
    engine = service.networks[0].engine
    for query, placement in zip(batch, placements):
        vehicles.place(query.vehicle_id, placement.network_index)
    inputs = [service.vehicle_input(q, p, vehicles) for q, p in zip(batch, placements)]
    results = engine.evaluate_many(inputs)
    marks.append(time.perf_counter())
    for query, placement in zip(batch, placements):
        vehicles.seen(query.vehicle_id, placement.lane_id)
    service.registry.store.write(vehicles.writes())
    vehicles.close()
    marks.append(time.perf_counter())
    EncodedAnswers([service.encode(r, p, q.vehicle_id) for r, p, q in zip(results, placements, batch)], [], []).batch_json()
    marks.append(time.perf_counter())
    gc.unfreeze()
    names = ("validate_ms", "read_state_ms", "check_and_match_ms", "engine_ms", "write_state_ms", "encode_json_ms")
    return {name: round((b - a) * 1000.0, 1) for name, a, b in zip(names, marks, marks[1:])}


def run() -> dict:
    """Start both servers, measure, stop them; return the figures."""
    service, service_url = _start(SERVICE, {"CSWS_NETS": str(TRACK_NET), "CSWS_STATE_DB": ":memory:"})
    trivial, trivial_url = _start(TRIVIAL, {})
    try:
        single = json.dumps(_fixes(1)[0]).encode()
        with httpx.Client(base_url=trivial_url) as trivial_client, httpx.Client(base_url=service_url) as client:
            rates = _requests_per_s({"trivial": (trivial_client, "/trivial"), "service": (client, "/v1/warning")},
                                    single, SINGLE_REQUESTS)
        trivial_rps, service_rps = rates["trivial"], rates["service"]
        queries = _fixes(BATCH_SIZE)
        batch = json.dumps({"queries": queries}).encode()
        server_ms, round_trip_ms = [], []
        with httpx.Client(base_url=service_url, timeout=60.0) as client:
            for _ in range(BATCH_REPEATS):
                started = time.perf_counter()
                response = client.post("/v1/warnings", content=batch, headers={"content-type": "application/json"})
                round_trip_ms.append((time.perf_counter() - started) * 1000.0)
                response.raise_for_status()
                server_ms.append(float(response.headers["server-timing"].split("dur=")[1]))
            levels = np.bincount([a["level"] for a in response.json()["answers"]], minlength=3)
    finally:
        for process in (service, trivial):
            process.terminate()
            process.wait(timeout=10)
    return {
        "trivial_rps": round(trivial_rps, 1),
        "service_rps": round(service_rps, 1),
        "single_ratio": round(service_rps / trivial_rps, 3),
        "batch_size": BATCH_SIZE,
        "batch_server_ms": round(float(np.median(server_ms)), 1),
        "batch_round_trip_ms": round(float(np.median(round_trip_ms)), 1),
        "batch_levels_0_1_2": levels.tolist(),
        **_breakdown_ms(queries),
    }


TARGETS = {"single_ratio": ">= 0.70", "batch_server_ms": "<= 100"}


def main() -> None:
    """Print each figure beside its target."""
    figures = run()
    for name, value in figures.items():
        target = TARGETS.get(name, "")
        print(f"{name:>22}: {value!s:<14} {('target ' + target) if target else ''}")


if __name__ == "__main__":
    main()
