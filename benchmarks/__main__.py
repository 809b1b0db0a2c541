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
    roadmap,
    roads,
    service,
    sweep,
    telematics,
    warning,
)
from benchmarks import map as live_map
from benchmarks.rows import Row, at_least, at_most, context, table


# ------------------------------------------------------------------ each benchmark's rows
def curvature_rows(figures: dict) -> list[Row]:
    """Ours beside the three-point method; dense and mapped ways are judged (sparse is shown unjudged)."""
    rows = []
    for kind, column in (("dense", 0), ("mapped", 1)):
        for name, limits in curvature.TARGETS.items():
            ours, three_point = figures[kind]["ours"][name], figures[kind]["three_point"][name]
            rows.append(at_most(f"curvature {kind}: {name}", ours, limits[column], f"{three_point:.3g} (3-point)"))
    sparse = figures["sparse"]
    for name in curvature.TARGETS:
        rows.append(
            context(
                f"curvature sparse (unjudged): {name}",
                sparse["ours"][name],
                f"{sparse['three_point'][name]:.3g} (3-point)",
            )
        )
    for kind in ("mapped", "sparse"):
        bound, reference = figures[kind]["bound"], figures[kind]["reference"]
        rows.append(
            context(
                f"curvature {kind}: arcs_started_over_5_m",
                figures[kind]["ours"]["arcs_started_over_5_m"],
                f"{reference['arcs_started_over_5_m']} of the ML road told its form; "
                f"{bound['expected_beyond_limit']:.1f} expected of an efficient estimator (Cramér-Rao)",
            )
        )
        rows.append(
            context(
                f"curvature {kind}: max_start_error_m of the ML road told its form",
                round(reference["max_start_error_m"], 2),
                f"ours {figures[kind]['ours']['max_start_error_m']:.3g}",
            )
        )
    rows.append(
        at_most(
            "curvature multi curve: max_step_error_m",
            figures["multi_curve"]["max_step_error_m"],
            curvature.MULTI_STEP_TARGET_M,
        )
    )
    rows.append(context("curvature: vertices/s", round(figures["throughput"]["vertices_per_s"])))
    return rows


def roads_rows(figures: dict) -> list[Row]:
    """Each family of constructed real-road geometry, dense and sparse, against its targets."""
    rows = [at_most(name, value, limit) for name, value, limit, _ in roads.verdicts(figures)]
    for family, samplings in figures.items():
        sparse = samplings["sparse"]
        rows.append(
            context(
                f"roads {family} sparse: start error p90 / max m",
                f"{sparse['p90_start_error_m']:.3g} / {sparse['max_start_error_m']:.3g}",
                f"{sparse['curves']} curves matched",
            )
        )
        rows.append(
            context(
                f"roads {family} sparse: start error median / p90 m the nodes allow",
                f"{sparse['bound_median_start_error_m']:.3g} / {sparse['bound_p90_start_error_m']:.3g}",
                "an efficient estimator told the road's form (Cramér-Rao)",
            )
        )
        rows.append(
            context(
                f"roads {family} sparse: start error median / p90 m of the reference",
                f"{sparse['reference_median_start_error_m']:.3g} / {sparse['reference_p90_start_error_m']:.3g}",
                "the maximum-likelihood road told the road's form, started from the truth",
            )
        )
        rows.append(
            context(
                f"roads {family} sparse: missed on ways with too few nodes",
                f"{sparse['missed_undetermined']} of {sparse['missed']}",
                "no more nodes than the road has numbers: the road is not determined",
            )
        )
        rows.append(
            context(
                f"roads {family} sparse: median radius error the nodes allow",
                f"{sparse['bound_median_radius_error']:.3g}",
                f"ours {sparse['median_radius_error']:.3g} (Cramér-Rao)",
            )
        )
    return rows


def warning_rows(figures: dict) -> list[Row]:
    single_us = figures["engine_single_median_us"]
    return [
        at_most("warning: engine, one vehicle, us", single_us, warning.TARGET_SINGLE_US),
        at_most(
            "warning: engine, batch of 1,000, us per vehicle",
            figures["engine_batch_per_vehicle_us"],
            warning.TARGET_BATCH_US,
        ),
        at_most(
            "FCW: batch of 1,000, us per vehicle", figures["fcw_batch_per_vehicle_us"], warning.TARGET_FCW_BATCH_US
        ),
    ]


def fcw_rows(figures: dict) -> list[Row]:
    return [
        at_most("FCW objects: one vehicle, 10 objects, us per frame", figures["single_us"], fcw.TARGET_SINGLE_US),
        context("FCW objects: one vehicle, 10 objects, map path, us per frame", round(figures["single_map_us"], 1)),
        at_most(
            "FCW objects: fleet of 1,000 x 10 objects, us per vehicle and frame",
            figures["batch_per_vehicle_us"],
            fcw.TARGET_BATCH_US,
        ),
        context(
            "FCW objects: fleet of 1,000 x 10 objects, map path, us per vehicle and frame",
            round(figures["batch_map_per_vehicle_us"], 2),
        ),
    ]


def fcw_traffic_rows(figures: dict) -> list[Row]:
    size = f"{figures['vehicle_hours']:.1f} equipped vehicle-h, Bad Hersfeld and the fleet road"
    situations = "; ".join(
        f"{name}: " + ", ".join(f"{count} {what}" for what, count in list(s["false_situations"].items())[:3])
        for name, s in figures["scenarios"].items()
    )
    return [
        at_most(
            f"FCW in traffic: false warnings per vehicle-hour ({size})",
            round(figures["false_per_vehicle_hour"], 3),
            fcw_traffic.TARGET_FALSE_PER_HOUR,
        ),
        at_most(
            "FCW in traffic: conflicts (TTC < 1 s or collision, system active) without a warning in time",
            figures["missed"],
            fcw_traffic.TARGET_MISSED,
        ),
        context("FCW in traffic: where the false warnings came (most frequent)", situations),
        context(
            "FCW in traffic: false warnings per vehicle-hour the standard requires (its least-demanding "
            "warning on the same run: the floor of any conforming system)",
            round(figures["references_false_per_vehicle_hour"][next(iter(fcw_traffic.REFERENCES))], 3),
        ),
        context(
            "FCW in traffic: false warnings per vehicle-hour by design choice (T_resp 1.2 s, preliminary warning)",
            round(figures["false_by_design_per_vehicle_hour"], 3),
        ),
    ]


def citymaps_rows(figures: dict) -> list[Row]:
    rows = []
    for city, found in figures.items():
        rows += [
            at_most(
                f"city maps, {city}: vertex corners >= 45 deg without a curve", found.get("missed >= 45 deg", 0), 0
            ),
            at_most(f"city maps, {city}: corners 30-45 deg without a curve", found.get("missed 30-45 deg", 0), 0),
            at_most(
                f"city maps, {city}: curves >= 20 deg where the road turns < 5 deg net",
                found.get("curves >= 20 deg on < 5 deg net", 0),
                0,
            ),
            at_most(f"city maps, {city}: curves above 360 deg", found.get("curves > 360 deg", 0), 0),
            context(
                f"city maps, {city}: curves, at the 5 m floor, artefacts found",
                f"{found.get('curves', 0):,}, {found.get('curves at the 5 m floor', 0)}, "
                + ", ".join(f"{k.split(': ')[1]} {v}" for k, v in found.items() if k.startswith("artefacts")),
            ),
            context(
                f"city maps, {city}: map report: floor curves (real corners / artefacts), artefacts, 1-node corners",
                " / ".join(str(found.get(f"report: floor curves, {k}", 0)) for k in ("real corners", "artefacts"))
                + f", {found.get('report: artefacts', 0)}, {found.get('report: single-node corners', 0)}",
            ),
        ]
    return rows


def matching_rows(figures: dict) -> list[Row]:
    return [
        at_most(
            f"matching: a fix continued in a batch of {figures['vehicles']:,} on Bad Hersfeld, CPU µs",
            figures["continued_cpu_us_per_fix"],
            matching.TARGET_US_PER_FIX,
            f"wall {figures['continued_us_per_fix']:g} µs at load average {figures['load_average']:g}; "
            f"first fix {figures['first_us_per_fix']:g} µs; lane graph built in {figures['graph_build_s']:g} s",
        ),
        context("matching: continued fixes on the true edge (σ 3 m)", figures["continued_on_true_edge"]),
    ]


def fleet_rows(figures: dict) -> list[Row]:
    return [
        at_most(
            f"fleet: single-fix p99 while pages of {figures['vehicles']:,} vehicles are read, same worker, ms",
            figures["fix_p99_reading_pages_ms"],
            fleet.FIX_P99_TARGET_MS,
            f"alone {figures['fix_p99_alone_ms']:g} ms; {figures['pages_read_per_s']:g} pages/s read meanwhile",
        ),
        context(
            "fleet: a page of 1,000 / 10,000 vehicles, ms",
            f"{figures['first_page_default_ms']:g} / {figures['first_page_max_ms']:g}",
        ),
        context(
            "fleet: a 1 x 1 m box / the first page of a box of 3 % of the fleet, ms",
            f"{figures['box_1m_ms']:g} / {figures['box_3pc_ms']:g}",
        ),
        context(
            "fleet: the whole fleet page by page (1,000 each)",
            f"{figures['walk_default_pages']} pages in {figures['walk_default_s']:g} s",
        ),
    ]


def hygiene_rows(figures: dict) -> list[Row]:
    return [
        at_most(
            "hygiene: /healthz p99 with 1,000 connections dripping headers and 32 saturating clients, ms",
            figures["healthz_dripping_saturating_p99_ms"],
            50,
            f"quiet {figures['healthz_quiet_p99_ms']:g} ms, "
            f"saturated alone {figures['healthz_saturating_p99_ms']:g} ms, "
            f"dripping alone {figures['healthz_dripping_p99_ms']:g} ms; longest dripping connection "
            f"{figures['healthz_dripping_open_s_max']} s",
        ),
        context(
            "hygiene: the same /healthz p99 of a bare ASGI app on plain uvicorn (the reference), ms",
            figures["reference_healthz_dripping_saturating_p99_ms"],
        ),
        at_most("hygiene: errors of the honest clients", figures["healthz_dripping_saturating_errors"], 0),
        at_most(
            "hygiene: log lines at descriptor exhaustion (128, 140 idle connections)",
            figures["exhaustion_log_lines"],
            10,
            f"recovered {figures['exhaustion_recovery_ms']:g} ms after they left; /healthz answered "
            f"{figures['exhaustion_healthz_status_held']} while held",
        ),
    ]


def cosim_rows(figures: dict) -> list[Row]:
    ms, ratio = figures["ms_per_step"], figures["ratio_to_bare"]
    components = ", ".join(f"{name} {value:.2f}" for name, value in figures["default_components_ms_per_step"].items())
    vehicles = f"{cosim.VEHICLES:,} vehicles"
    return [
        at_most(
            f"cosim: {vehicles}, evaluation and time series (x bare SUMO)",
            ratio["default"],
            cosim.TARGET_DEFAULT_RATIO,
            f"{ms['default']:.1f} vs {ms['bare']:.1f} ms/step of libsumo alone",
        ),
        at_most(
            f"cosim: {vehicles}, evaluation, events only (x bare SUMO)",
            ratio["events_only"],
            cosim.TARGET_EVENTS_RATIO,
            f"{ms['events_only']:.1f} ms/step",
        ),
        context(
            f"cosim: {vehicles}, reading only (x bare SUMO)",
            round(ratio["read_only"], 2),
            f"{ms['read_only']:.1f} ms/step: the least that reads every vehicle each step",
        ),
        at_most(
            f"cosim: evaluation overhead, {vehicles} (x the run without it)",
            figures["overhead"],
            cosim.TARGET_OVERHEAD,
            f"{ms['default']:.1f} vs {ms['without_evaluation']:.1f} ms/step; {figures['vehicles']} evaluated",
        ),
        context("cosim: default run by component, ms/step", components),
        at_most(
            f"cosim: both systems (csws,fcw), {vehicles} (overhead over the run without evaluation)",
            figures["both_systems_overhead"],
            cosim.TARGET_BOTH_SYSTEMS_OVERHEAD,
            f"{ms['both_systems']:.1f} vs {ms['without_evaluation']:.1f} ms/step",
        ),
        context(
            "cosim: FCW's own cost (both systems over the default run)",
            round(figures["fcw_over_default"], 2),
            "fcw ms/step: " + str(figures["both_systems_components_ms_per_step"].get("fcw")),
        ),
        *city_rows(figures["city"]),
    ]


def city_rows(city: dict) -> list[Row]:
    """The city run: 10,000 vehicles on Bad Hersfeld against bare SUMO, with peak memory."""
    ms, ratio, peak = city["ms_per_step"], city["ratio_to_bare"], city["peak_rss_mb"]
    vehicles = f"{cosim.CITY_VEHICLES:,} vehicles on Bad Hersfeld"
    components = ", ".join(f"{name} {value:.2f}" for name, value in city["default_components_ms_per_step"].items())
    return [
        at_most(
            f"cosim: {vehicles}, evaluation and time series (x bare SUMO)",
            ratio["default"],
            cosim.TARGET_DEFAULT_RATIO,
            f"{ms['default']:.1f} vs {ms['bare']:.1f} ms/step; {city['vehicles']:,} evaluated",
        ),
        at_most(
            f"cosim: {vehicles}, evaluation, events only (x bare SUMO)",
            ratio["events_only"],
            cosim.TARGET_EVENTS_RATIO,
            f"{ms['events_only']:.1f} ms/step",
        ),
        context(
            f"cosim: {vehicles}, peak memory MB (bare / default / events only)",
            f"{peak['bare']} / {peak['default']} / {peak['events_only']}",
            f"by component, ms/step: {components}",
        ),
    ]


def sweep_rows(figures: dict) -> list[Row]:
    context_text = f"{figures['cores']} cores, load average {figures['load_average_1min']:g} at the end"
    return [
        at_least(
            f"sweep: {figures['runs']} runs on 2 local workers, speed-up over 1",
            figures["speedup"],
            sweep.TARGET_SPEEDUP,
            f"{figures['two_workers_s']:g} vs {figures['one_worker_s']:g} s; {context_text}",
        ),
        at_most(
            "sweep: Dask's overhead over a plain loop, 1 worker, %",
            figures["overhead_percent"],
            sweep.TARGET_OVERHEAD_PERCENT,
            f"{figures['one_worker_s']:g} vs {figures['loop_s']:g} s; {figures['overhead_ms_per_task']:g} ms per task",
        ),
    ]


def _stages(stages_ms: dict) -> str:
    """A batch's stages (from its Server-Timing header) in one line."""
    return ", ".join(f"{name} {ms:.0f}" for name, ms in stages_ms.items() if name != "round_trip") + " ms"


def service_rows(figures: dict) -> list[Row]:
    trivial = f"vs {figures['trivial_rps']:.0f} req/s (trivial endpoint)"
    return [
        at_least(
            "service: single-query throughput ratio, one network",
            figures["single_ratio_one_network"],
            0.70,
            f"{figures['service_rps_one_network']:.0f} {trivial}",
        ),
        at_least(
            "service: single-query throughput ratio, default serve (x/y)",
            figures["single_ratio_default"],
            0.70,
            f"{figures['service_rps_default']:.0f} {trivial}",
        ),
        at_most(
            "service: batch of 10,000 by lane id, one network, server ms",
            figures["batch_lane_ms"],
            100.0,
            _stages(figures["batch_lane_stages_ms"]),
        ),
        at_most(
            "service: batch of 10,000 by x/y, default serve, server ms",
            figures["batch_xy_default_ms"],
            150.0,
            _stages(figures["batch_xy_default_stages_ms"]),
        ),
        at_most(
            f"service: first query on {figures['first_queries']:,} fresh Bad Hersfeld lanes, p99 ms",
            figures["first_query_ms_p99"],
            10.0,
            f"p50 {figures['first_query_ms_p50']:g}, max {figures['first_query_ms_max']:g} ms (server time)",
        ),
        context(
            "service: start-up s, default serve / Bad Hersfeld / default serve with 2 workers",
            f"{figures['startup_default_s']:g} / {figures['startup_real_s']:g} / "
            f"{figures['startup_default_2_workers_s']:g}",
            "profile cache filled",
        ),
        context(
            "service: memory per worker, 2 workers on the default serve, RSS / PSS MB",
            " + ".join(
                f"{rss} / {pss}" for rss, pss in zip(figures["worker_rss_mb"], figures["worker_pss_mb"], strict=False)
            ),
            "PSS shares the pages the workers share among them",
        ),
    ]


def real_network_rows(figures: dict) -> list[Row]:
    size = f"{figures['lanes']:,} lanes, {figures['curves']:,} curves"
    return [
        at_most(
            f"real network ({figures['lane_km']:g} lane-km): load s, fitted before",
            figures["cached_load_s"],
            roadmap.REAL_LOAD_TARGET_S,
            f"{size}; {figures['fit_load_s']:g} s when every chain is fitted",
        ),
        at_most("real network: first load s, every chain fitted", figures["fit_load_s"], roadmap.REAL_LOAD_TARGET_S),
        at_most(
            "real network: first look-ahead on a lane, max ms",
            figures["first_lookahead_ms_max"],
            roadmap.FIRST_LOOKAHEAD_TARGET_MS,
            f"p50 {figures['first_lookahead_ms_p50']:g} ms over {figures['first_lookaheads']} fresh lanes",
        ),
    ]


def grid_rows(figures: dict) -> list[Row]:
    load_s = round(figures["parse_s"] + figures["build_s"], 2)
    return [
        at_most(
            f"synthetic grid ({figures['lane_km']:g} lane-km): load s",
            load_s,
            osm.TARGETS["load_s"],
            f"{figures['lanes']:,} lanes",
        )
    ]


def osm_rows(figures: dict) -> list[Row]:
    return [at_most(f"OSM: {name}", figures[name], limit) for name, limit in osm.TARGETS.items()]


def load_rows(figures: dict) -> list[Row]:
    duration = f"{figures['clients']} clients, {figures['seconds']:g} s"
    return [
        context("load: throughput, req/s", figures["throughput_rps"], duration),
        context("load: latency p50 / p99, ms", f"{figures['latency_ms_p50']:g} / {figures['latency_ms_p99']:g}"),
        at_most(
            "load: /healthz p99 while saturated, ms",
            figures["healthz_ms_p99"],
            load.MAX_HEALTHZ_P99_MS,
            f"{figures['healthz_probes']} probes, one every {load.HEALTH_PERIOD_S:g} s",
        ),
        at_most("load: errors", figures["errors"], load.MAX_ERRORS, figures["first_error"] or ""),
        at_most(
            "load: memory growth, MB",
            figures["rss_growth_mb"],
            load.MAX_RSS_GROWTH_MB,
            f"{figures['rss_mb_start']:g} -> {figures['rss_mb_end']:g} MB; {figures['sessions_at_end']} of "
            f"{figures['vehicles']} sessions left",
        ),
    ]


def workers_rows(figures: dict) -> list[Row]:
    one, two = figures["queries_per_s_1_workers"], figures["queries_per_s_2_workers"]
    return [
        at_least(
            "load: single-query throughput 2 workers / 1 worker",
            figures["ratio"],
            load.MIN_WORKERS_RATIO,
            f"{two:.0f} vs {one:.0f} queries/s on {figures['service_cores_2_workers']:g} vs "
            f"{figures['service_cores_1_workers']:g} cores; {figures['connections']} lean connections on the "
            f"same machine ({figures['client_core_share']:g} of a core), load average "
            f"{figures['load_average_1min']:g}, {figures['seconds']:g} s",
        ),
        at_most("load: errors, 1 and 2 workers", figures["errors"], load.MAX_ERRORS, figures["first_error"] or ""),
    ]


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
