"""The live map page (``GET /map``) of Bad Hersfeld with 1,000 live vehicles, in a real browser.

A real ``csws serve`` of the Bad Hersfeld network alone (:mod:`benchmarks.servers`) is fed
1,000 vehicles by lane id, as one ``POST /v1/warnings`` batch a second from a thread of this
process: each vehicle drives along its lane at its own speed, so every answer changes every
second. With the fleet live, headless Chromium (the Debian package ``chromium``, driven by
Playwright) opens ``/map?network=badhersfeld`` in a 1200 x 800 view and the page is left to
refresh itself at 1 Hz for :data:`WINDOW_S` seconds. Figures:

* the initial data: the bytes the page received (headers and compressed bodies, from the
  browser's own resource timing) for every request that ended before its first complete
  draw: the page, Leaflet, the roads, the curves of the view and the first fleet answer;
* the time from opening the page to its first complete draw (the end of the first refresh
  that placed all 1,000 vehicles), from the page's clock;
* the page's own time per refresh (fetch, decode and marker update, kept by ``map.js`` in
  ``cswsMap.fleetTimes``), p50 and p99 over the window, and whether it falls behind: ticks
  skipped because the refresh before was still running, and refreshes that failed;
* ``GET /v1/fleet`` of the 1,000 vehicles in the page's view while the fleet is fed, round
  trip from this process (the route sends no ``Server-Timing``), p50 and p99.

Targets: initial data <= 2 MB; p99 refresh < 1 s, no tick skipped and no refresh failed.
The run takes about a minute.

Measured on the 2-core development machine (other work beside it), a run of 44 s: initial
data 0.736 MB in 7 requests (page and Leaflet 51.7 kB, roads 142.2 kB, curves 486.8 kB, first
fleet answer 54.9 kB); first complete draw 0.89 s after opening; refresh p50 / p99 32 / 54.6 ms
over 30 refreshes (with 30 the p99 is about the slowest), none skipped or failed, longest gap
between refreshes 1002.6 ms; ``GET /v1/fleet`` round trip p50 / p99 20.2 / 50 ms, 54.6 kB.

Run with ``python -m benchmarks.map``.
"""

from __future__ import annotations

import tempfile
import threading
import time
from pathlib import Path

import httpx
import numpy as np

from benchmarks.command import arguments
from csws.networks import networks_dir
from csws.road.roadmap import RoadMap

from .rows import Row, at_most, context, table
from .servers import Running, csws_serve
from .service import lane_queries

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
REAL_NET = networks_dir() / "badhersfeld.net.xml.gz"
NETWORK = "badhersfeld"
VEHICLES = 1000
#: How long the page refreshes on its own while its refreshes are timed, s.
WINDOW_S = 30.0
#: How many ``GET /v1/fleet`` are timed from this process.
FLEET_GETS = 30
#: The longest the page may take to draw everything, ms.
WAIT_MS = 60_000
TARGET_INITIAL_MB = 2.0
TARGET_REFRESH_P99_MS = 1000.0
TARGET_SKIPPED = 0


def missing() -> str | None:
    """Why the benchmark cannot run here (no Chromium, no Playwright), or None."""
    if not Path(CHROMIUM).exists():
        return f"no Chromium at {CHROMIUM} (Debian package chromium)"
    try:
        import playwright.sync_api  # noqa: F401 - only whether it is there
    except ImportError:
        return "Playwright for Python is not installed (pip install -e '.[test]')"
    return None


class Feeder(threading.Thread):
    """Sends the fleet's positions as one ``POST /v1/warnings`` a second until stopped: each vehicle of
    ``queries`` (by lane id) moves along its lane at its speed and wraps round at the lane's end."""

    def __init__(self, url: str, queries: list[dict], lane_lengths_m: np.ndarray) -> None:
        super().__init__(daemon=True)
        self.url, self.queries, self.lane_lengths_m = url, queries, lane_lengths_m
        self.start_m = np.array([query["lane_pos_m"] for query in queries])
        self.speeds_ms = np.array([query["speed_kmh"] for query in queries]) / 3.6
        self.stopping = threading.Event()
        self.ticks = 0
        self.error: str | None = None

    def tick(self, client: httpx.Client) -> None:
        """One batch: every vehicle where it is ``ticks`` seconds after the start."""
        lane_pos_m = (self.start_m + self.speeds_ms * self.ticks) % self.lane_lengths_m
        queries = [
            {**query, "lane_pos_m": float(pos_m), "timestamp_s": 1000.0 + self.ticks}
            for query, pos_m in zip(self.queries, lane_pos_m, strict=False)
        ]
        client.post("/v1/warnings", json={"queries": queries}).raise_for_status()
        self.ticks += 1

    def run(self) -> None:
        started = time.monotonic()
        with httpx.Client(base_url=self.url, timeout=30.0) as client:
            while not self.stopping.is_set():
                try:
                    self.tick(client)
                except httpx.HTTPError as error:
                    self.error = f"{type(error).__name__}: {error}"
                    return
                self.stopping.wait(max(0.0, started + self.ticks - time.monotonic()))


def _initial_data(page, first_draw_ms: float) -> dict:
    """The bytes the page received (headers and compressed bodies) for the requests that ended by
    ``first_draw_ms`` (the page's clock), in all and by what was asked for."""
    entries = page.evaluate("""() => [...performance.getEntriesByType('navigation'),
                                      ...performance.getEntriesByType('resource')]
        .map(e => ({name: e.name, bytes: e.transferSize, ended_ms: e.responseEnd}))""")
    by_kind: dict[str, int] = {}
    ended = [entry for entry in entries if entry["ended_ms"] <= first_draw_ms]
    for entry in ended:
        path = entry["name"].split("://", 1)[-1].split("/", 1)[-1].split("?")[0]
        kind = path if path.startswith("v1/") else "page and Leaflet"
        by_kind[kind] = by_kind.get(kind, 0) + entry["bytes"]
    return {
        "initial_mb": round(sum(by_kind.values()) / 1e6, 3),
        "initial_requests": len(ended),
        "initial_kb_by_kind": {kind: round(size / 1e3, 1) for kind, size in by_kind.items()},
    }


def _refreshes(times: dict, first_draw_ms: float) -> dict:
    """Per-refresh figures of the page's own timing after its first complete draw."""
    window = [r for r in times["refreshes"] if r["started_ms"] > first_draw_ms]
    took_ms = np.array([r["took_ms"] for r in window])
    gaps_ms = np.diff([r["started_ms"] for r in window])
    return {
        "refreshes": len(window),
        "refresh_ms_p50": round(float(np.median(took_ms)), 1),
        "refresh_ms_p99": round(float(np.percentile(took_ms, 99)), 1),
        "refresh_ms_max": round(float(took_ms.max()), 1),
        "refresh_gap_ms_max": round(float(gaps_ms.max()), 1),
        "ticks_skipped": times["skipped"],
        "refreshes_failed": times["failed"],
        "skipped_or_failed": times["skipped"] + times["failed"],
        "vehicles_drawn": min(r["vehicles"] for r in window),
    }


def browse(served: Running) -> dict:
    """Open the map of Bad Hersfeld in headless Chromium, let it refresh for :data:`WINDOW_S`; its figures
    and the view it showed."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": 1200, "height": 800})
            page.goto(f"{served.url}/map?network={NETWORK}")
            page.wait_for_function(
                f"() => cswsMap.fleetTimes.refreshes.some(r => r.vehicles >= {VEHICLES})", timeout=WAIT_MS
            )
            first = page.evaluate(f"() => cswsMap.fleetTimes.refreshes.find(r => r.vehicles >= {VEHICLES})")
            first_draw_ms = first["started_ms"] + first["took_ms"]
            figures = _initial_data(page, first_draw_ms) | {"first_draw_s": round(first_draw_ms / 1000.0, 2)}
            page.wait_for_timeout(WINDOW_S * 1000.0)
            figures |= _refreshes(page.evaluate("() => cswsMap.fleetTimes"), first_draw_ms)
            figures["bbox"] = page.evaluate("() => document.body.dataset.curvesBbox")
        finally:
            browser.close()
    return figures


def fleet_round_trips(served: Running, bbox: str) -> dict:
    """``GET /v1/fleet`` of the page's view :data:`FLEET_GETS` times, one every 0.2 s: round trip p50 and
    p99, ms, and the answer's size on the wire (gzipped), kB."""
    took_ms, sizes = [], []
    with httpx.Client(base_url=served.url, timeout=30.0) as client:
        for _ in range(FLEET_GETS):
            started = time.perf_counter()
            response = client.get("/v1/fleet", params={"network": NETWORK, "bbox": bbox})
            response.raise_for_status()
            took_ms.append((time.perf_counter() - started) * 1000.0)
            sizes.append(response.num_bytes_downloaded)
            time.sleep(0.2)
    return {
        "fleet_get_ms_p50": round(float(np.median(took_ms)), 1),
        "fleet_get_ms_p99": round(float(np.percentile(took_ms, 99)), 1),
        "fleet_get_vehicles": len(response.json()["features"]),
        "fleet_get_kb": round(float(np.median(sizes)) / 1e3, 1),
    }


def run() -> dict:
    """Serve Bad Hersfeld, feed it the fleet, open and watch the map, time ``/v1/fleet``; the figures,
    or ``{"not_run": why}`` where Chromium or Playwright is missing."""
    why = missing()
    if why is not None:
        return {"not_run": why}
    road_map = RoadMap.load(REAL_NET)
    queries = lane_queries(road_map, VEHICLES)
    lane_lengths_m = np.array([road_map.lane(query["lane_id"]).length_m for query in queries])
    with tempfile.TemporaryDirectory(prefix="csws-bench-map-") as folder:
        served = csws_serve(Path(folder) / "map.sqlite3", "--net", str(REAL_NET))
        feeder = Feeder(served.url, queries, lane_lengths_m)
        try:
            feeder.start()
            while feeder.ticks == 0 and feeder.is_alive():
                time.sleep(0.05)
            figures = browse(served)
            figures |= fleet_round_trips(served, figures.pop("bbox"))
        finally:
            feeder.stopping.set()
            feeder.join(timeout=30.0)
            served.stop()
    if feeder.error is not None:
        raise RuntimeError(f"feeding the fleet failed: {feeder.error}")
    return figures | {"vehicles": VEHICLES, "window_s": WINDOW_S, "feeder_ticks": feeder.ticks}


def map_rows(figures: dict) -> list[Row]:
    """The live map of Bad Hersfeld with 1,000 vehicles fed at 1 Hz, in headless Chromium."""
    if "not_run" in figures:
        return [context("map: live map in a real browser", "skipped", figures["not_run"])]
    vehicles = f"{figures['vehicles']:,} vehicles"
    by_kind = ", ".join(f"{kind} {kb:g}" for kind, kb in figures["initial_kb_by_kind"].items())
    return [
        at_most(
            "map: initial data of Bad Hersfeld until the first complete draw, MB",
            figures["initial_mb"],
            TARGET_INITIAL_MB,
            f"{figures['initial_requests']} requests, kB: {by_kind}",
        ),
        context(
            "map: page open to first complete draw, s",
            figures["first_draw_s"],
            f"roads, curves of the view and {vehicles}",
        ),
        Row(
            f"map: refresh at 1 Hz, {vehicles}, page's own time p99 ms",
            figures["refresh_ms_p99"],
            f"< {TARGET_REFRESH_P99_MS:g}",
            figures["refresh_ms_p99"] < TARGET_REFRESH_P99_MS,
            f"p50 {figures['refresh_ms_p50']:g}, max {figures['refresh_ms_max']:g} ms over {figures['refreshes']} "
            f"refreshes (fetch, decode, marker update)",
        ),
        at_most(
            f"map: refreshes skipped or failed in {figures['window_s']:g} s",
            figures["skipped_or_failed"],
            TARGET_SKIPPED,
            f"longest gap between refreshes {figures['refresh_gap_ms_max']:g} ms; "
            f"{figures['vehicles_drawn']:,} vehicles drawn, {figures['feeder_ticks']} batches fed",
        ),
        context(
            f"map: GET /v1/fleet of {vehicles} in the view, round trip p50 / p99 ms",
            f"{figures['fleet_get_ms_p50']:g} / {figures['fleet_get_ms_p99']:g}",
            f"{figures['fleet_get_kb']:g} kB gzipped; while fed at 1 Hz; no Server-Timing on this route",
        ),
    ]


def main() -> None:
    """Print the rows ``python -m benchmarks`` shows of this benchmark: each figure beside its target."""
    arguments("benchmarks.map", __doc__)
    print(table(map_rows(run())))


if __name__ == "__main__":
    main()
