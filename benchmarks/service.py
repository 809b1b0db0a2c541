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
  of the default serve with two workers, and the memory of each of those workers;
* the cost of the warning events' outbox (:func:`outbox_figures`): single queries and the 10,000-query
  batch of vehicles whose warnings start and end (on a tenth of the answers, and on every answer) against
  the same vehicles driving steadily, which make none (the outbox cannot be switched off);
* ``POST /v1/traccar``: positions in Traccar's forwarding format on Bad Hersfeld, sequential, per second.

Run with ``python -m benchmarks.service``.
"""

from __future__ import annotations

import json
import math
import os
import sqlite3
import tempfile
import time
from datetime import UTC, datetime
from pathlib import Path

import httpx
import numpy as np
from fastapi import FastAPI, Request
from fastapi.responses import Response

from benchmarks.command import arguments
from csws.networks import networks_dir
from csws.road.matching import lane_points
from csws.road.roadmap import RoadMap
from service.traccar import KNOT_KMH

from .servers import Running, children, csws_serve, memory_mb, start

TRACK_NET = networks_dir() / "t7_left.net.xml"
REAL_NET = networks_dir() / "badhersfeld.net.xml.gz"
SINGLE_REQUESTS = 2000
SINGLE_ROUNDS = 10
BATCH_SIZE = 10_000
BATCH_REPEATS = 5
FIRST_QUERIES = 1000
#: The speeds of the drive that makes warning events, km/h, one a tick: at 130 km/h every curve of the Table 7
#: track ahead within its warning distance warns, at 10 km/h (under every V_w) none does, so the level of each
#: vehicle whose curve is near rises and falls again with every tick (curve_onset, curve_release).
EVENT_SPEEDS_KMH = (130.0, 10.0)
#: Sizes of the outbox's measurement: single requests per kind, and batch ticks.
EVENT_SINGLE_REQUESTS = 1000
EVENT_BATCH_REPEATS = 4
#: The drive with some events: one vehicle in this many changes speed (batch), or a vehicle changes it every this
#: many requests (single): a warning starting or ending on a tenth of the answers.
EVENT_TURN_EVERY = 10
#: Positions posted to ``/v1/traccar``, one per device each round, and the rounds.
TRACCAR_DEVICES = 200
TRACCAR_ROUNDS = 5
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
    "outbox_batch_ratio_some": "<= 1.10",
    "outbox_single_ratio_some": ">= 0.90",
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


def outbox_events(state_db: Path) -> int:
    """How many events the service's SQLite outbox holds (what the drives made)."""
    with sqlite3.connect(state_db) as db:
        return int(db.execute("SELECT count(*) FROM vehicle_events").fetchone()[0])


def _turning(query: dict, vehicle_id: str, turn_every: int | None, count: int) -> list[bytes]:
    """``count`` requests of one vehicle: at the first of :data:`EVENT_SPEEDS_KMH` throughout (``turn_every``
    None), or changing to the next one every ``turn_every`` requests."""
    speeds = [EVENT_SPEEDS_KMH[0 if turn_every is None else k // turn_every % 2] for k in range(count)]
    return [json.dumps({**query, "vehicle_id": vehicle_id, "speed_kmh": v}).encode() for v in speeds]


def single_event_rates(service: Running, state_db: Path, query: dict, count: int = EVENT_SINGLE_REQUESTS) -> dict:
    """Requests per second of sequential ``POST /v1/warning`` of three vehicles: one at a steady speed (no event
    after its first answer), one changing its speed every :data:`EVENT_TURN_EVERY` requests and one every request
    (an event on each), in interleaved rounds; and the events per request of each."""
    headers = {"content-type": "application/json"}
    per_round = count // SINGLE_ROUNDS
    turns = {"steady": None, "some": EVENT_TURN_EVERY, "every": 1}
    bodies = {name: _turning(query, f"single-{name}", every, per_round) for name, every in turns.items()}
    elapsed_s, events = dict.fromkeys(turns, 0.0), dict.fromkeys(turns, 0)
    with httpx.Client(base_url=service.url) as client:
        for name in turns:
            client.post("/v1/warning", content=bodies[name][-1], headers=headers).raise_for_status()
        for _ in range(SINGLE_ROUNDS):
            for name in turns:
                before = outbox_events(state_db)
                started = time.perf_counter()
                for body in bodies[name]:
                    client.post("/v1/warning", content=body, headers=headers).raise_for_status()
                elapsed_s[name] += time.perf_counter() - started
                events[name] += outbox_events(state_db) - before
    requests = per_round * SINGLE_ROUNDS
    return {name: (requests / elapsed_s[name], events[name] / requests) for name in turns}


def _event_batches(served: Running, state_db: Path, queries: list[dict]) -> dict[int, dict]:
    """The median server time of the batch and of its stages, ms, and the events per tick, of three fleets of
    ``queries`` (vehicles of their own) at the first of :data:`EVENT_SPEEDS_KMH`: steady (0), one vehicle in
    :data:`EVENT_TURN_EVERY` changing speed every tick, and every vehicle (1); their ticks interleaved, so that
    each fleet sees the same machine load, one second apart after one that starts the sessions."""
    fleets = {
        every: [{**q, "vehicle_id": f"{q['vehicle_id']}-{every}"} for q in queries]
        for every in (0, EVENT_TURN_EVERY, 1)
    }
    timings: dict[int, list[dict[str, float]]] = {every: [] for every in fleets}
    events = dict.fromkeys(fleets, 0)
    with httpx.Client(base_url=served.url, timeout=60.0) as client:
        for tick in range(EVENT_BATCH_REPEATS + 1):
            for every, vehicles in fleets.items():
                speed = {"speed_kmh": EVENT_SPEEDS_KMH[tick % 2]}
                ticked = [
                    {**q, "speed_kmh": EVENT_SPEEDS_KMH[0], "timestamp_s": 1000.0 + tick}
                    | (speed if every and not k % every else {})
                    for k, q in enumerate(vehicles)
                ]
                before = outbox_events(state_db)
                response = client.post("/v1/warnings", json={"queries": ticked})
                response.raise_for_status()
                if tick:
                    timings[every].append(server_timing(response.headers["server-timing"]))
                    events[every] += outbox_events(state_db) - before
    return {
        every: {name: round(float(np.median([t.get(name, 0.0) for t in rows])), 1) for name in rows[0]}
        | {"events_per_tick": round(events[every] / EVENT_BATCH_REPEATS)}
        for every, rows in timings.items()
    }


def outbox_figures(state_db: Path, queries: list[dict]) -> dict:
    """The cost of writing warning events (the outbox cannot be switched off, so against drives that make none):
    single queries and the 10,000-query batch by lane id on the Table 7 track, steady (no event after the first
    answer) against vehicles changing speed so that their warnings start and end, on one service."""
    served = csws_serve(state_db, "--net", str(TRACK_NET))
    try:
        single = single_event_rates(served, state_db, queries[0])
        batches = _event_batches(served, state_db, queries)
    finally:
        served.stop()
    figures: dict = {"outbox_load_average": round(os.getloadavg()[0], 1)}
    for name, (rate, per_request) in single.items():
        figures[f"outbox_single_rps_{name}"] = round(rate, 1)
        figures[f"outbox_single_events_per_request_{name}"] = round(per_request, 2)
    for every, stages in batches.items():
        name = {0: "steady", 1: "every"}.get(every, "some")
        figures[f"outbox_batch_{name}_ms"] = stages.pop("csws")
        figures[f"outbox_batch_{name}_events_per_tick"] = stages.pop("events_per_tick")
        figures[f"outbox_batch_{name}_stages_ms"] = stages
    for kind in ("some", "every"):
        figures[f"outbox_single_ratio_{kind}"] = round(
            figures[f"outbox_single_rps_{kind}"] / figures["outbox_single_rps_steady"], 3
        )
        figures[f"outbox_batch_ratio_{kind}"] = round(
            figures[f"outbox_batch_{kind}_ms"] / figures["outbox_batch_steady_ms"], 3
        )
    return figures


def traccar_payloads(road_map: RoadMap, count: int, fix_time: str) -> list[bytes]:
    """Positions of ``count`` trucks on a geo-referenced map's roads in Traccar's forwarding format
    (``forward.type=json``: degrees, knots, ``course``, ``fixTime``), encoded."""
    payloads = []
    for number, fix in enumerate(road_fixes(road_map, count, seed=13)):
        lon, lat = road_map.xy_to_lonlat(fix["position"]["x"], fix["position"]["y"])
        position = {
            "id": number, "deviceId": number, "protocol": "osmand", "fixTime": fix_time, "deviceTime": fix_time,
            "serverTime": fix_time, "outdated": False, "valid": True, "latitude": lat, "longitude": lon,
            "altitude": 200.0, "speed": fix["speed_kmh"] / KNOT_KMH, "course": fix["heading_deg"], "accuracy": 3.0,
            "attributes": {"motion": True},
        }  # fmt: skip
        device = {"id": number, "name": f"truck-{number}", "uniqueId": f"86612345{number:07d}", "category": "truck"}
        payloads.append(json.dumps({"position": position, "device": device}).encode())
    return payloads


def traccar_rate(served: Running, road_map: RoadMap, devices: int = TRACCAR_DEVICES) -> float:
    """Positions per second of sequential keep-alive ``POST /v1/traccar``: each device's position once a round,
    every round with the fix time of its start (the fixes are fresh, so evaluated)."""
    headers = {"content-type": "application/json"}
    elapsed_s = 0.0
    with httpx.Client(base_url=served.url) as client:
        for _ in range(TRACCAR_ROUNDS):
            fix_time = datetime.now(UTC).isoformat(timespec="milliseconds")
            payloads = traccar_payloads(road_map, devices, fix_time)
            started = time.perf_counter()
            for payload in payloads:
                response = client.post("/v1/traccar", content=payload, headers=headers)
                if response.status_code != 200:  # 202: a position not evaluated
                    raise RuntimeError(f"/v1/traccar answered {response.status_code}: {response.text[:200]}")
            elapsed_s += time.perf_counter() - started
    return devices * TRACCAR_ROUNDS / elapsed_s


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
                objects_ms = objects.pop("csws")
                figures |= {
                    "batch_objects_ms": objects_ms,
                    "batch_objects_stages_ms": objects,
                    "batch_objects_ratio": round(objects_ms / figures["batch_lane_ms"], 2),
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
            figures["traccar_positions_per_s"] = round(traccar_rate(real, real_map), 1)
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
        figures |= outbox_figures(Path(folder) / "outbox.sqlite3", lane_queries(RoadMap.load(TRACK_NET), BATCH_SIZE))
    return figures


def main() -> None:
    """Print each figure beside its target."""
    arguments("benchmarks.service", __doc__)
    for name, value in run().items():
        target = TARGETS.get(name, "")
        print(f"{name:>28}: {value!s:<14} {('target ' + target) if target else ''}")


if __name__ == "__main__":
    main()
