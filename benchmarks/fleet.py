"""``GET /v1/fleet`` over a large fleet: what a page costs, and what reading pages costs the single fixes.

One ``csws serve`` (one worker, vehicles in a SQLite file) on the Table 7 track, started and
stopped here, is given :data:`VEHICLES` vehicles of one fleet in batches (each at a lane position
of its own along the track's lanes). Figures:

* the server-side time of a page (the client's time to the last byte, loopback): the first page
  at the default size and at the largest, a whole walk at the default size (pages and time), a
  1 x 1 m box, and a box holding 3 % of the fleet (the first page);
* single fixes (``POST /v1/warning``, one keep-alive client, one after the other) on the same
  worker: p50 and p99 alone, and then while a second client reads pages of the fleet without
  pause (the whole fleet at the default page size, cursor after cursor): the fixes' p99 must stay
  within :data:`FIX_P99_TARGET_MS`.

The Redis store is measured on its own (:func:`run_redis`, no HTTP): :data:`VEHICLES` places spread
over a square of network metres, written in batches through :class:`service.store.redis.RedisStore`;
figures: the first page of 1,000 (no box, and in a box holding 3 % of the fleet), a 1 x 1 m box, and
the p99 of one vehicle's write (a single fix's round trip to the store) alone and while a second
client reads pages of 1,000 of the 3 % box without pause (Redis runs one script at a time).

Run with ``python -m benchmarks.fleet [VEHICLES]``, or ``python -m benchmarks.fleet --redis [VEHICLES]``.
"""

from __future__ import annotations

import argparse
import tempfile
import threading
import time
from pathlib import Path

import httpx
import numpy as np

from benchmarks.command import arguments
from benchmarks.servers import csws_serve, redis_server
from csws.networks import networks_dir
from csws.road.roadmap import RoadMap
from service.store import Place, VehicleWrite
from service.store.redis import RedisStore

TRACK_NET = networks_dir() / "t7_left.net.xml"
VEHICLES = 100_000
BATCH = 10_000
MEASURE_S = 8.0
FIX_P99_TARGET_MS = 20.0
TARGETS = {"fix_p99_reading_pages_ms": f"<= {FIX_P99_TARGET_MS:g}"}
LANES = ("approach_0", "curve_0", "runout_0")
#: The side of the square the Redis benchmark spreads its places over, m, and the size of its pages.
REDIS_SQUARE_M = 1000.0
REDIS_PAGE = 1000
#: Places written per request while filling the store: small enough that a loaded machine answers each within
#: the store's timeout (the fill is not what is measured).
REDIS_BATCH = 2000
#: A session as large as the service's (a matched lane, the state, the release rule's memory), bytes.
REDIS_SESSION = b"s" * 200


def _fill(client: httpx.Client, vehicles: int) -> float:
    """Give the service ``vehicles`` vehicles spread along the track's lanes; the seconds it took."""
    track = RoadMap.load(TRACK_NET)
    lengths = np.array([track.lane(lane).length_m for lane in LANES])
    started = time.perf_counter()
    for first in range(0, vehicles, BATCH):
        numbers = np.arange(first, min(first + BATCH, vehicles))
        lane = numbers % len(LANES)
        lane_pos_m = (numbers // len(LANES)) * 0.37 % (lengths[lane] - 1.0)
        queries = [
            {"vehicle_id": f"truck-{n:06d}", "category": "N", "speed_kmh": 60.0, "lane_id": LANES[k], "lane_pos_m": p}
            for n, k, p in zip(numbers.tolist(), lane.tolist(), lane_pos_m.tolist(), strict=True)
        ]
        answer = client.post("/v1/warnings", json={"queries": queries}, timeout=300.0)
        answer.raise_for_status()
    return time.perf_counter() - started


def _page_ms(client: httpx.Client, **params: str) -> tuple[float, dict]:
    """One page of the fleet: the ms to its last byte and the page."""
    started = time.perf_counter()
    answer = client.get("/v1/fleet", params=params, timeout=60.0)
    answer.raise_for_status()
    return (time.perf_counter() - started) * 1000.0, answer.json()


def pages(client: httpx.Client) -> dict:
    """The time of pages of each kind."""
    figures = {}
    figures["first_page_default_ms"], first = _page_ms(client)
    figures["first_page_default_vehicles"] = len(first["features"])
    figures["first_page_max_ms"], largest = _page_ms(client, limit="10000")
    figures["first_page_max_vehicles"] = len(largest["features"])
    x, y = first["features"][0]["geometry"]["coordinates"]
    figures["box_1m_ms"], small = _page_ms(client, bbox=f"{x - 0.5},{y - 0.5},{x + 0.5},{y + 0.5}")
    figures["box_1m_vehicles"] = len(small["features"])
    figures["box_3pc_ms"], three_pc = _page_ms(client, bbox="0,-1,90,1")
    figures["box_3pc_vehicles_first_page"] = len(three_pc["features"])
    walked, count, cursor = time.perf_counter(), 0, None
    while True:
        _ms, page = _page_ms(client, **({"cursor": cursor} if cursor else {}))
        count += 1
        cursor = page["next_cursor"]
        if cursor is None:
            break
    figures["walk_default_pages"] = count
    figures["walk_default_s"] = round(time.perf_counter() - walked, 2)
    return {name: round(value, 2) if isinstance(value, float) else value for name, value in figures.items()}


def _fixes_ms(client: httpx.Client, seconds: float) -> np.ndarray:
    """Latencies of single fixes, one after the other, for ``seconds``, ms."""
    latencies, number = [], 0
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        fix = {"vehicle_id": "probe", "category": "N", "speed_kmh": 60.0, "lane_id": "approach_0"}
        started = time.perf_counter()
        client.post("/v1/warning", json={**fix, "lane_pos_m": float(number % 800)}).raise_for_status()
        latencies.append((time.perf_counter() - started) * 1000.0)
        number += 1
    return np.array(latencies)


def _read_pages(url: str, stop: threading.Event, read: list[int]) -> None:
    """Walk the fleet's pages at the default size over and over until ``stop``; count the pages."""
    with httpx.Client(base_url=url, timeout=60.0) as client:
        cursor = None
        while not stop.is_set():
            page = client.get("/v1/fleet", params={"cursor": cursor} if cursor else {}).json()
            cursor = page["next_cursor"]
            read.append(1)


def fixes(url: str) -> dict:
    """Single fixes' latency alone, then while pages are read."""
    with httpx.Client(base_url=url, timeout=30.0) as client:
        _fixes_ms(client, 1.0)  # warm
        alone = _fixes_ms(client, MEASURE_S)
        stop, read = threading.Event(), list[int]()
        reader = threading.Thread(target=_read_pages, args=(url, stop, read))
        reader.start()
        time.sleep(0.5)
        during = _fixes_ms(client, MEASURE_S)
        stop.set()
        reader.join()
    return {
        "fix_p50_alone_ms": round(float(np.percentile(alone, 50)), 2),
        "fix_p99_alone_ms": round(float(np.percentile(alone, 99)), 2),
        "fix_p50_reading_pages_ms": round(float(np.percentile(during, 50)), 2),
        "fix_p99_reading_pages_ms": round(float(np.percentile(during, 99)), 2),
        "pages_read_per_s": round(len(read) / MEASURE_S, 1),
    }


def run(vehicles: int = VEHICLES) -> dict:
    """Fill a service with ``vehicles`` vehicles and measure; the figures."""
    with tempfile.TemporaryDirectory(prefix="csws-bench-fleet-") as folder:
        server = csws_serve(Path(folder) / "vehicles.sqlite3", f"--net={TRACK_NET}")
        try:
            with httpx.Client(base_url=server.url) as client:
                figures: dict = {"vehicles": vehicles, "fill_s": round(_fill(client, vehicles), 1)}
                figures |= pages(client)
            figures |= fixes(server.url)
        finally:
            server.stop()
    return figures


def _fill_redis(store: RedisStore, vehicles: int) -> tuple[float, np.ndarray]:
    """Write ``vehicles`` places spread at random over the square; the seconds it took and the places (x, y)."""
    points = np.random.default_rng(1).uniform(0.0, REDIS_SQUARE_M, (vehicles, 2))
    started = time.perf_counter()
    for first in range(0, vehicles, REDIS_BATCH):
        store.write(
            {
                f"bench|truck-{n:06d}": VehicleWrite(0, REDIS_SESSION, place=Place("track", x, y))
                for n, (x, y) in enumerate(points[first : first + REDIS_BATCH].tolist(), first)
            }
        )
    return time.perf_counter() - started, points


def _placed_ms(store: RedisStore, box: tuple[float, float, float, float] | None) -> tuple[float, int]:
    """The first page of :data:`REDIS_PAGE` in ``box``: its ms and its vehicles."""
    started = time.perf_counter()
    page = store.placed("bench|", "", REDIS_PAGE, ["track"], box)
    return (time.perf_counter() - started) * 1000.0, len(page)


def _writes_ms(store: RedisStore, seconds: float) -> np.ndarray:
    """Latencies of one vehicle's writes, one after the other, for ``seconds``, ms."""
    latencies, version = [], 0
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        write = VehicleWrite(version, REDIS_SESSION, place=Place("track", float(version % 800), 1.0))
        started = time.perf_counter()
        store.write({"bench|probe": write})
        latencies.append((time.perf_counter() - started) * 1000.0)
        version += 1
    return np.array(latencies)


def run_redis(vehicles: int = VEHICLES) -> dict:
    """Fill a Redis store with ``vehicles`` places and measure its pages and one vehicle's writes; the figures."""
    three_pc_side_m = REDIS_SQUARE_M * 0.03**0.5
    three_pc = (0.0, 0.0, three_pc_side_m, three_pc_side_m)
    with tempfile.TemporaryDirectory(prefix="csws-bench-fleet-redis-") as folder:
        process, url = redis_server(Path(folder))
        store = RedisStore(url, 3600.0)
        try:
            fill_s, points = _fill_redis(store, vehicles)
            figures: dict = {"vehicles": vehicles, "fill_s": fill_s}
            figures["first_page_ms"], figures["first_page_vehicles"] = _placed_ms(store, None)
            x, y = points[0].tolist()
            figures["box_1m_ms"], figures["box_1m_vehicles"] = _placed_ms(store, (x - 0.5, y - 0.5, x + 0.5, y + 0.5))
            figures["box_3pc_ms"], figures["box_3pc_vehicles_first_page"] = _placed_ms(store, three_pc)
            alone = _writes_ms(store, MEASURE_S / 2)
            stop, read = threading.Event(), list[int]()

            def read_pages() -> None:
                pages_store = RedisStore(url, 3600.0)
                try:
                    while not stop.is_set():
                        pages_store.placed("bench|", "", REDIS_PAGE, ["track"], three_pc)
                        read.append(1)
                finally:
                    pages_store.close()

            reader = threading.Thread(target=read_pages)
            reader.start()
            during = _writes_ms(store, MEASURE_S / 2)
            stop.set()
            reader.join()
        finally:
            store.close()
            process.terminate()
            process.wait(timeout=30)
    figures |= {
        "write_p99_alone_ms": float(np.percentile(alone, 99)),
        "write_p99_reading_pages_ms": float(np.percentile(during, 99)),
        "pages_read_per_s": len(read) / (MEASURE_S / 2),
    }
    return {name: round(value, 2) if isinstance(value, float) else value for name, value in figures.items()}


def _add_arguments(parser: argparse.ArgumentParser) -> None:
    """The fleet's size, and which store is measured."""
    parser.add_argument("vehicles", type=int, nargs="?", default=VEHICLES, help="vehicles in the fleet")
    parser.add_argument("--redis", action="store_true", help="measure the Redis store alone (no HTTP)")


def main() -> None:
    """Print each figure beside its target."""
    given = arguments("benchmarks.fleet", __doc__, _add_arguments)
    for name, value in (run_redis if given.redis else run)(given.vehicles).items():
        target = TARGETS.get(name, "")
        print(f"{name:>32}: {value!s:<10} {('target ' + target) if target else ''}")


if __name__ == "__main__":
    main()
