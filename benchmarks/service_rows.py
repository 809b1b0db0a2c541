"""The rows of the service's benchmarks in the one table of ``python -m benchmarks``: single queries and
batches, connection hygiene, fleet pages and the load tests, each figure beside its target.
"""

from __future__ import annotations

from benchmarks import (
    fleet,
    load,
    service,
)
from benchmarks.rows import Row, at_least, at_most, context


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


def _stages(stages_ms: dict) -> str:
    """A batch's stages (from its Server-Timing header) in one line."""
    return ", ".join(f"{name} {ms:.0f}" for name, ms in stages_ms.items() if name != "round_trip") + " ms"


def outbox_rows(figures: dict) -> list[Row]:
    """The cost of the warning events' outbox: drives whose warnings start and end (single: on a tenth of the
    answers; batch: a tenth of the vehicles changing speed every tick) and the worst case (every answer, every
    vehicle), against the same vehicles driving steadily (events only where a warning changes by itself)."""
    load_average = f"load average {figures['outbox_load_average']:g}"
    steady_batch, steady_rps = figures["outbox_batch_steady_ms"], figures["outbox_single_rps_steady"]
    return [
        at_most(
            "service: outbox, batch of 10,000 with 1/10 of the vehicles changing speed / steady",
            figures["outbox_batch_ratio_some"],
            1.10,
            f"{figures['outbox_batch_some_ms']:g} vs {steady_batch:g} ms, "
            f"{figures['outbox_batch_some_events_per_tick']} vs {figures['outbox_batch_steady_events_per_tick']} "
            f"events a tick; {load_average}",
        ),
        at_least(
            "service: outbox, single queries with events on 1/10 of the answers / steady",
            figures["outbox_single_ratio_some"],
            0.90,
            f"{figures['outbox_single_rps_some']:.0f} vs {steady_rps:.0f} req/s; {load_average}",
        ),
        context(
            "service: outbox, every vehicle changing speed / steady: batch, single",
            f"{figures['outbox_batch_ratio_every']:g}, {figures['outbox_single_ratio_every']:g}",
            f"{figures['outbox_batch_every_ms']:g} ms ({figures['outbox_batch_every_events_per_tick']} events), "
            f"{figures['outbox_single_rps_every']:.0f} req/s; write stage "
            f"{figures['outbox_batch_every_stages_ms']['write']:g} vs "
            f"{figures['outbox_batch_steady_stages_ms']['write']:g} ms",
        ),
    ]


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
        *outbox_rows(figures),
        context(
            "service: POST /v1/traccar, Traccar-forwarded positions per second, sequential, Bad Hersfeld",
            figures["traccar_positions_per_s"],
            f"{service.TRACCAR_DEVICES} devices x {service.TRACCAR_ROUNDS} rounds, one keep-alive connection",
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
