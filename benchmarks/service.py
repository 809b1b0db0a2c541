"""How fast the HTTP service answers, against a trivial FastAPI endpoint served the same way.

Servers are uvicorn processes on loopback, started and stopped here (:mod:`benchmarks.servers`),
keeping their vehicles in a SQLite file as ``csws serve`` does: a trivial FastAPI app
(:data:`trivial_app`, whose endpoint takes a JSON body and answers a constant), ``csws serve``
on the Table 7 track, the default ``csws serve`` (the bundled city, Bad Hersfeld), and ``csws serve --net`` on Bad
Hersfeld. Figures:

* single-query throughput: sequential keep-alive ``POST /v1/warning`` of a fix by x, y and
  heading against the same number of ``POST /trivial`` with the same body, in interleaved
  rounds; the ratio, with one network and with the default serve (a fix on Bad Hersfeld's roads);
* a 10,000-query batch (one fleet tick), the server time its ``Server-Timing`` header reports
  with its stages: by lane id on the Table 7 track, and by x, y and heading on Bad Hersfeld's
  roads on the default serve. Each batch comes one second after the one before (the queries'
  timestamps), as a fleet reporting at 1 Hz: every session changes and is written;
* the same 10,000-query batch by lane id with 5 sensor objects and a yaw rate in each query
  (:func:`with_objects`), whose forward collision warning keeps its state in the sessions: its server
  time, and the ratio to the batch without objects;
* the first query on each of 1,000 never-queried lanes of Bad Hersfeld (a fix at the middle of
  the lane, as a batch of one, so that the server times it);
* the start-up (to the first ready ``/readyz``) of the default serve, of Bad Hersfeld alone, and
  of the default serve with two workers, and the memory of each of those workers.

Run with ``python -m benchmarks.service``.
"""

from __future__ import annotations

import json
import math
import tempfile
import time
from pathlib import Path

import httpx
import numpy as np
from fastapi import FastAPI, Request
from fastapi.responses import Response

from csws.networks import networks_dir
from csws.road.matching import lane_points
from csws.road.roadmap import RoadMap

from .servers import Running, children, csws_serve, memory_mb, start

TRACK_NET = networks_dir() / "t7_left.net.xml"
REAL_NET = networks_dir() / "badhersfeld.net.xml.gz"
SINGLE_REQUESTS = 2000
SINGLE_ROUNDS = 10
BATCH_SIZE = 10_000
BATCH_REPEATS = 5
FIRST_QUERIES = 1000
#: Sensor objects in each query of the batch with objects.
OBJECTS_PER_QUERY = 5
#: GNSS noise of the fixes on Bad Hersfeld's roads: position (per axis) and heading, m and degrees.
GNSS_SIGMA_M = 1.0
HEADING_SIGMA_DEG = 3.0
#: Targets: single-query throughput over the trivial endpoint's; batch server time by lane id on
#: one network and by x, y on the default serve, ms; p99 of the first query on a lane, ms.
TARGETS = {
    "single_ratio_one_network": ">= 0.70",
    "single_ratio_default": ">= 0.70",
    "batch_lane_ms": "<= 100",
    "batch_xy_default_ms": "<= 150",
    "batch_objects_ratio": "<= 2.0",
    "first_query_ms_p99": "<= 10",
}

trivial_app = FastAPI()


@trivial_app.post("/trivial")
async def _trivial(request: Request) -> Response:
    await request.body()
    return Response(b'{"ok": true}', media_type="application/json")


@trivial_app.get("/readyz")
async def _ready() -> dict:
    return {"status": "ready"}


#: ``python -m`` of these serves the service (settings from CSWS_* variables) and the trivial app.
SERVICE = ["uvicorn", "--factory", "service.app:create_app", "--log-level", "warning"]
TRIVIAL = ["uvicorn", "benchmarks.service:trivial_app", "--log-level", "warning"]


def track_fixes(count: int, seed: int = 5) -> list[dict]:
    """Queries of ``count`` vehicles spread over the Table 7 track's approach, as GNSS fixes heading east."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(10.0, 990.0, count)
    y = rng.normal(0.0, 1.0, count)
    speed = rng.uniform(30.0, 120.0, count)
    categories = rng.choice(["M1", "M2", "M3", "N", "O"], count)
    return [
        {
            "vehicle_id": f"v{i}",
            "category": str(c),
            "speed_kmh": float(v),
            "position": {"x": float(a), "y": float(b)},
            "heading_deg": 90.0,
        }
        for i, (a, b, v, c) in enumerate(zip(x, y, speed, categories, strict=False))
    ]


def _truck_lanes(road_map: RoadMap) -> list[str]:
    """The normal lanes of a map that trucks may use."""
    lanes = [road_map.lane(lane_id) for lane_id in road_map.lane_ids]
    return [lane.lane_id for lane in lanes if not lane.is_internal and "truck" in lane.allowed_vclasses]


def road_fix(road_map: RoadMap, lane_id: str, lane_pos_m: float, rng: np.random.Generator) -> dict:
    """A GNSS fix of a vehicle at a lane position: x, y and the lane's heading there, with noise."""
    length_m = road_map.lane(lane_id).length_m
    (x, y), (ahead_x, ahead_y) = lane_points(road_map, lane_id, np.array([lane_pos_m, min(lane_pos_m + 1.0, length_m)]))
    heading_deg = (90.0 - math.degrees(math.atan2(ahead_y - y, ahead_x - x))) % 360.0
    noisy_heading_deg = (heading_deg + rng.normal(0.0, HEADING_SIGMA_DEG)) % 360.0
    return {
        "position": {"x": float(x + rng.normal(0.0, GNSS_SIGMA_M)), "y": float(y + rng.normal(0.0, GNSS_SIGMA_M))},
        "heading_deg": noisy_heading_deg if noisy_heading_deg < 360.0 else 0.0,
    }


def road_fixes(road_map: RoadMap, count: int, seed: int = 7) -> list[dict]:
    """Queries of ``count`` trucks and buses at random positions of a map's truck lanes, as GNSS fixes."""
    rng = np.random.default_rng(seed)
    lanes = _truck_lanes(road_map)
    queries = []
    for i, lane_index in enumerate(rng.integers(0, len(lanes), count)):
        lane_id = lanes[lane_index]
        fix = road_fix(road_map, lane_id, float(rng.uniform(0.0, road_map.lane(lane_id).length_m)), rng)
        queries.append(
            {
                "vehicle_id": f"r{i}",
                "category": str(rng.choice(["M3", "N", "O"])),
                "speed_kmh": float(rng.uniform(30.0, 90.0)),
                **fix,
            }
        )
    return queries


def lane_queries(road_map: RoadMap, count: int, seed: int = 9) -> list[dict]:
    """Queries of ``count`` vehicles by lane id and lane position on a map's normal lanes."""
    rng = np.random.default_rng(seed)
    lanes = [lane_id for lane_id in road_map.lane_ids if not road_map.lane(lane_id).is_internal]
    queries = []
    for i, lane_index in enumerate(rng.integers(0, len(lanes), count)):
        lane_id = lanes[lane_index]
        queries.append(
            {
                "vehicle_id": f"l{i}",
                "category": str(rng.choice(["M1", "M2", "M3", "N", "O"])),
                "speed_kmh": float(rng.uniform(30.0, 120.0)),
                "lane_id": lane_id,
                "lane_pos_m": float(rng.uniform(0.0, road_map.lane(lane_id).length_m)),
            }
        )
    return queries


def with_objects(queries: list[dict], count: int = OBJECTS_PER_QUERY, seed: int = 11) -> list[dict]:
    """The queries with ``count`` sensor objects each (ahead within 150 m, across three lanes, closing or
    opening) and a yaw rate: a radar's track list, for the forward collision warning (vehicles of their own,
    whose sessions the batch without objects did not start)."""
    rng = np.random.default_rng(seed)
    return [
        {
            **query,
            "vehicle_id": f"{query['vehicle_id']}-fcw",
            "yaw_rate_dps": float(rng.normal(0.0, 1.0)),
            "accel_mps2": float(rng.normal(0.0, 0.5)),
            "objects": [
                {
                    "id": int(object_id),
                    "x_m": float(rng.uniform(5.0, 150.0)),
                    "y_m": float(rng.normal(0.0, 2.5)),
                    "relative_speed_mps": float(rng.uniform(-15.0, 5.0)),
                    "accel_mps2": float(rng.normal(0.0, 1.0)),
                    "width_m": 1.8,
                }
                for object_id in rng.choice(1000, size=count, replace=False)
            ],
        }
        for query in queries
    ]


def single_rates(service: Running, trivial: Running, query: dict, count: int = SINGLE_REQUESTS) -> dict[str, float]:
    """Requests per second of sequential keep-alive POSTs of ``query``: ``service`` to ``/v1/warning``,
    ``trivial`` to ``/trivial``, in interleaved rounds so that both see the same machine load."""
    body, headers = json.dumps(query).encode(), {"content-type": "application/json"}
    targets = {"service": (service.url, "/v1/warning"), "trivial": (trivial.url, "/trivial")}
    elapsed_s = dict.fromkeys(targets, 0.0)
    with httpx.Client() as client:
        for url, path in targets.values():
            for _ in range(50):
                client.post(url + path, content=body, headers=headers).raise_for_status()
        for _ in range(SINGLE_ROUNDS):
            for name, (url, path) in targets.items():
                started = time.perf_counter()
                for _ in range(count // SINGLE_ROUNDS):
                    client.post(url + path, content=body, headers=headers).raise_for_status()
                elapsed_s[name] += time.perf_counter() - started
    return {name: count // SINGLE_ROUNDS * SINGLE_ROUNDS / seconds for name, seconds in elapsed_s.items()}


def server_timing(header: str) -> dict[str, float]:
    """The stages of a ``Server-Timing`` header, ms (``csws`` is the total)."""
    stages = {}
    for entry in header.split(","):
        name, _, duration = entry.strip().partition(";dur=")
        stages[name] = float(duration)
    return stages


def batch_ms(service: Running, queries: list[dict], repeats: int = BATCH_REPEATS) -> dict[str, float]:
    """The median server time of a batch of ``queries`` and of its stages, ms, over ``repeats`` fleet
    ticks one second apart (after one that starts the sessions); the median round trip."""
    timings, round_trip_ms = [], []
    with httpx.Client(base_url=service.url, timeout=60.0) as client:
        for tick in range(repeats + 1):
            body = json.dumps({"queries": [{**query, "timestamp_s": 1000.0 + tick} for query in queries]})
            started = time.perf_counter()
            response = client.post("/v1/warnings", content=body, headers={"content-type": "application/json"})
            response.raise_for_status()
            if tick:
                round_trip_ms.append((time.perf_counter() - started) * 1000.0)
                timings.append(server_timing(response.headers["server-timing"]))
    stages = {name: round(float(np.median([t.get(name, 0.0) for t in timings])), 1) for name in timings[0]}
    return {**stages, "round_trip": round(float(np.median(round_trip_ms)), 1)}


def first_queries_ms(service: Running, road_map: RoadMap, count: int = FIRST_QUERIES, seed: int = 3) -> np.ndarray:
    """The server time of the first query on each of ``count`` random truck lanes of a map no query
    reached before: a new vehicle at the middle of the lane, sent as a batch of one, ms."""
    rng = np.random.default_rng(seed)
    lanes = _truck_lanes(road_map)
    took_ms = []
    with httpx.Client(base_url=service.url, timeout=60.0) as client:
        for number, lane_index in enumerate(rng.choice(len(lanes), size=min(count, len(lanes)), replace=False)):
            lane_id = lanes[lane_index]
            fix = road_fix(road_map, lane_id, road_map.lane(lane_id).length_m / 2.0, rng)
            query = {"vehicle_id": f"first-{number}", "category": "N", "speed_kmh": 80.0, **fix}
            response = client.post("/v1/warnings", json={"queries": [query]})
            response.raise_for_status()
            took_ms.append(server_timing(response.headers["server-timing"])["csws"])
    return np.array(took_ms)


def _workers_memory(state_db: Path) -> dict:
    """The start-up of the default serve with two workers, and each worker's memory after some queries."""
    served = csws_serve(state_db, "--workers", "2")
    try:
        with httpx.Client(base_url=served.url) as client:
            for query in track_fixes(50):
                client.post("/v1/warning", json=query).raise_for_status()
        memory = [memory_mb(pid) for pid in children(served.process.pid)]
    finally:
        served.stop()
    return {
        "startup_default_2_workers_s": round(served.startup_s, 2),
        "worker_rss_mb": [round(rss) for rss, _ in memory],
        "worker_pss_mb": [round(pss) for _, pss in memory],
    }


def run() -> dict:
    """Start the servers one after the other, measure, stop them; return the figures."""
    real_map = RoadMap.load(REAL_NET)
    figures: dict = {}
    with tempfile.TemporaryDirectory(prefix="csws-bench-service-") as folder:
        trivial = start(TRIVIAL)
        try:
            one = csws_serve(Path(folder) / "one.sqlite3", "--net", str(TRACK_NET))
            try:
                rates = single_rates(one, trivial, track_fixes(1)[0])
                figures |= {
                    "trivial_rps": round(rates["trivial"], 1),
                    "service_rps_one_network": round(rates["service"], 1),
                    "single_ratio_one_network": round(rates["service"] / rates["trivial"], 3),
                }
                queries = lane_queries(RoadMap.load(TRACK_NET), BATCH_SIZE)
                lane = batch_ms(one, queries)
                figures |= {"batch_lane_ms": lane.pop("csws"), "batch_lane_stages_ms": lane}
                objects = batch_ms(one, with_objects(queries))
                figures |= {
                    "batch_objects_ms": objects.pop("csws"),
                    "batch_objects_stages_ms": objects,
                    "batch_objects_ratio": round(figures["batch_objects_ms"] / figures["batch_lane_ms"], 2),
                }
            finally:
                one.stop()
            default = csws_serve(Path(folder) / "default.sqlite3")
            try:
                figures["startup_default_s"] = round(default.startup_s, 2)
                rates = single_rates(default, trivial, road_fixes(real_map, 1)[0])
                figures |= {
                    "service_rps_default": round(rates["service"], 1),
                    "single_ratio_default": round(rates["service"] / rates["trivial"], 3),
                }
                xy = batch_ms(default, road_fixes(real_map, BATCH_SIZE))
                figures |= {"batch_xy_default_ms": xy.pop("csws"), "batch_xy_default_stages_ms": xy}
            finally:
                default.stop()
        finally:
            trivial.stop()
        real = csws_serve(Path(folder) / "real.sqlite3", "--net", str(REAL_NET))
        try:
            first_ms = first_queries_ms(real, real_map)
        finally:
            real.stop()
        figures |= {
            "startup_real_s": round(real.startup_s, 2),
            "first_queries": len(first_ms),
            "first_query_ms_p50": round(float(np.median(first_ms)), 2),
            "first_query_ms_p99": round(float(np.percentile(first_ms, 99)), 2),
            "first_query_ms_max": round(float(first_ms.max()), 2),
        }
        figures |= _workers_memory(Path(folder) / "workers.sqlite3")
    return figures


def main() -> None:
    """Print each figure beside its target."""
    for name, value in run().items():
        target = TARGETS.get(name, "")
        print(f"{name:>28}: {value!s:<14} {('target ' + target) if target else ''}")


if __name__ == "__main__":
    main()
