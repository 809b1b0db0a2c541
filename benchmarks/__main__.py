"""Run every benchmark and print one table: each figure beside its target.

``python -m benchmarks [--quick] [--json PATH] [--osm FILE] [--load-seconds S]`` runs
each benchmark module's ``run()`` in turn and prints one table: each figure, its value,
the baseline it is compared with where one was measured in the same run, its target and
PASS or FAIL. ``--quick`` uses smaller sizes and a 10 s load test (a few
minutes in all instead of about five); ``--json PATH`` also writes the figures and every
module's raw results as JSON for tracking.

The real-network load time is measured on the bundled Bad Hersfeld network
(``networks/badhersfeld.net.xml.gz``). Importing OpenStreetMap needs the extract, which
is not shipped: give it with ``--osm FILE`` to time the import too; without it the
import row says it was skipped. The live map is measured in headless Chromium (the Debian
package ``chromium``, driven by Playwright): without them its row says it was skipped.

A benchmark that fails to run is a FAIL row with its error; the others still run.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import sys
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from datetime import UTC, datetime
from pathlib import Path

from benchmarks import (
    citymaps,
    cosim,
    cosim_read,
    curvature,
    fcw,
    fcw_traffic,
    fleet,
    hygiene,
    jt808,
    load,
    matching,
    opendrive,
    osm,
    push,
    roadmap,
    roads,
    service,
    sweep,
    telematics,
    warning,
)
from benchmarks import map as live_map
from benchmarks.library_rows import (
    citymaps_rows,
    cosim_rows,
    curvature_rows,
    fcw_rows,
    fcw_traffic_rows,
    grid_rows,
    matching_rows,
    osm_rows,
    real_network_rows,
    roads_rows,
    sweep_rows,
    warning_rows,
)
from benchmarks.rows import Row, table
from benchmarks.service_rows import fleet_rows, hygiene_rows, load_rows, service_rows, workers_rows


# ------------------------------------------------------------------ the run
@dataclass(frozen=True)
class Benchmark:
    """A benchmark: how to run it, how long that takes, and its rows."""

    name: str
    run: Callable[[], dict]
    about: str
    rows: Callable[[dict], list[Row]]


def benchmarks(quick: bool, osm_file: Path | None, load_seconds: float | None) -> list[Benchmark]:
    """Every benchmark, in the order they run; ``quick`` shrinks the sizes that allow it."""
    load_seconds = load_seconds or (10.0 if quick else load.SECONDS)
    chosen = [
        Benchmark(
            "curvature",
            lambda: curvature.run(cases=60 if quick else curvature.CASES_PER_CATEGORY),
            "about 10-60 s",
            curvature_rows,
        ),
        Benchmark(
            "roads", lambda: roads.run(cases=10 if quick else roads.CASES_PER_FAMILY), "about 10-40 s", roads_rows
        ),
        Benchmark(
            "opendrive",
            lambda: opendrive.run(per_family=2 if quick else opendrive.ROADS_PER_FAMILY),
            "about 1 minute: OpenDRIVE roads imported, fitted and exact",
            opendrive.rows,
        ),
        Benchmark("warning", warning.run, "a few seconds", warning_rows),
        Benchmark("fcw", fcw.run, "a few seconds", fcw_rows),
        Benchmark("service", service.run, "about 1-2 minutes", service_rows),
        Benchmark(
            "city maps",
            lambda: citymaps.run(osm=osm_file),
            "about a minute (plus an import with --osm)",
            citymaps_rows,
        ),
        Benchmark("matching", matching.run, "about half a minute: 10,000 vehicles on Bad Hersfeld", matching_rows),
        Benchmark(
            "hygiene", hygiene.run, "about a minute: slow heads, saturation, descriptor exhaustion", hygiene_rows
        ),
        Benchmark(
            "fleet",
            lambda: fleet.run(vehicles=10_000 if quick else fleet.VEHICLES),
            "about 1-2 minutes: 100,000 vehicles given, their pages read",
            fleet_rows,
        ),
        Benchmark("load", lambda: load.run(seconds=load_seconds), f"{load_seconds:g} s at saturation", load_rows),
        Benchmark(
            "workers", lambda: load.run_workers(seconds=load_seconds), f"{load_seconds:g} s at saturation", workers_rows
        ),
        Benchmark(
            "cosim",
            cosim.run,
            f"long: about 2-3 min, {cosim.VEHICLES:,} vehicles six times, {cosim.CITY_VEHICLES:,} three times",
            cosim_rows,
        ),
        Benchmark(
            "cosim read",
            lambda: cosim_read.run(duration_s=10.0, rounds=1) if quick else cosim_read.run(),
            "about 5 minutes: the fleet road read four ways at four due shares, three rounds",
            cosim_read.rows,
        ),
        Benchmark("fcw traffic", fcw_traffic.run, "about 1-2 minutes: two scenarios, every vehicle", fcw_traffic_rows),
        Benchmark(
            "telematics",
            lambda: telematics.run(quick=quick),
            "a few minutes" if quick else "long: about 4.5 CPU-minutes, two cities' fleets fed seven ways",
            telematics.rows,
        ),
        Benchmark(
            "jt808",
            lambda: jt808.run_all(terminals=500 if quick else jt808.BENCH_TERMINALS),
            "about 4 minutes: terminals at 1 Hz to one gateway for 60 s; one and two gateways on Redis",
            jt808.rows,
        ),
        Benchmark(
            "push",
            lambda: push.run(vehicles=1_000 if quick else push.BENCH_VEHICLES),
            "about a minute: events of every vehicle at 1 Hz to a webhook receiver and to mosquitto",
            push.rows,
        ),
        Benchmark("sweep", sweep.run, f"about 1 minute: {sweep.RUNS} co-simulations three times", sweep_rows),
        Benchmark(
            "map", live_map.run, f"about a minute: the page watched for {live_map.WINDOW_S:g} s", live_map.map_rows
        ),
        Benchmark("real network", roadmap.real_network_load, "a few seconds", real_network_rows),
        Benchmark(
            "grid",
            lambda: roadmap.run(junctions_per_side=8 if quick else 18),
            "a few seconds" if quick else "long: about 30-90 s",
            grid_rows,
        ),
    ]
    if osm_file is not None:
        chosen.append(Benchmark("osm", lambda: osm.run(osm_file), "long: about 1-3 minutes", osm_rows))
    return chosen


def run_all(chosen: list[Benchmark], log=sys.stderr) -> tuple[list[Row], dict]:
    """Run each benchmark; a failing one becomes a FAIL row and the rest still run."""
    rows: list[Row] = []
    raw: dict = {}
    for number, benchmark in enumerate(chosen, start=1):
        print(f"[{number}/{len(chosen)}] {benchmark.name} ({benchmark.about}) ...", file=log, flush=True)
        started = time.perf_counter()
        try:
            raw[benchmark.name] = benchmark.run()
            rows += benchmark.rows(raw[benchmark.name])
        except Exception as error:  # noqa: BLE001 - one broken benchmark must not hide the others' figures
            raw[benchmark.name] = {"error": f"{type(error).__name__}: {error}"}
            rows.append(Row(benchmark.name, "error", "runs", False, raw[benchmark.name]["error"]))
        raw[benchmark.name + "_wall_s"] = round(time.perf_counter() - started, 1)
    return rows, raw


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks", description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller sizes and a 10 s load test")
    parser.add_argument("--json", type=Path, default=None, metavar="PATH", help="also write the results as JSON")
    parser.add_argument(
        "--osm",
        type=Path,
        default=None,
        metavar="FILE",
        help="an OpenStreetMap extract: also time its import (skipped without it)",
    )
    parser.add_argument("--load-seconds", type=float, default=None, help="length of the load test, s")
    args = parser.parse_args(argv)
    if args.osm is not None and not args.osm.is_file():
        parser.error(f"no OSM file at {args.osm}")
    started = datetime.now(UTC)
    rows, raw = run_all(benchmarks(args.quick, args.osm, args.load_seconds))
    if args.osm is None:
        rows.append(
            Row(
                "OSM: import_s",
                "skipped",
                f"<= {osm.TARGETS['import_s']:g}",
                None,
                "no OpenStreetMap extract given (--osm FILE)",
            )
        )
    print(table(rows))
    judged = [r for r in rows if r.passed is not None]
    print(
        f"{sum(r.passed is True for r in judged)} of {len(judged)} judged figures meet their targets"
        f"{' (quick sizes)' if args.quick else ''}"
    )
    if args.json is not None:
        document = {
            "started": started.isoformat(timespec="seconds"),
            "quick": args.quick,
            "python": platform.python_version(),
            "machine": platform.machine(),
            "rows": [asdict(r) | {"verdict": r.verdict} for r in rows],
            "results": raw,
        }
        args.json.write_text(json.dumps(_plain(document), indent=1, allow_nan=False) + "\n", encoding="utf-8")
        print(f"wrote {args.json}")
    return 0


def _plain(value):
    """Standard JSON of the raw results: numpy values as Python ones, non-finite numbers as text."""
    if isinstance(value, dict):
        return {key: _plain(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(item) for item in value]
    value = value.tolist() if hasattr(value, "tolist") else value
    if isinstance(value, list):
        return _plain(value)
    return str(value) if isinstance(value, float) and not math.isfinite(value) else value


if __name__ == "__main__":
    sys.exit(main())
