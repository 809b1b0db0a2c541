"""The rows of the library's benchmarks in the one table of ``python -m benchmarks``: curvature, roads, the
warning, the FCW, city maps, matching, co-simulation, fleet studies and road-map loads, each figure beside its
target.
"""

from __future__ import annotations

from benchmarks import (
    cosim,
    curvature,
    fcw,
    fcw_traffic,
    matching,
    osm,
    roadmap,
    roads,
    sweep,
    warning,
)
from benchmarks.rows import Row, at_least, at_most, context


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
        *ssm_rows(figures),
        *city_rows(figures["city"]),
    ]


def ssm_rows(figures: dict) -> list[Row]:
    """Both systems' cost over bare SUMO as a share of SUMO's SSM device's on every vehicle (the fleet road)."""
    ms, shares = figures["ms_per_step"], figures["fcw_of_ssm_overhead"]
    ssm = f"SSM {ms['ssm']:.1f} vs bare {ms['bare']:.1f} ms/step (TTC within {cosim.SSM_RANGE_M:g} m)"
    return [
        at_most(
            f"cosim: both systems, {label}, {cosim.VEHICLES:,} vehicles (share of the SSM device's overhead)",
            round(shares[name], 2),
            cosim.TARGET_FCW_OF_SSM_OVERHEAD,
            f"{ms[name]:.1f} ms/step; {ssm}",
        )
        for name, label in (("both_systems", "time series"), ("both_systems_events", "events only"))
    ] + [
        context(
            "cosim: share of vehicle-steps evaluated (default / events only / both systems)",
            " / ".join(f"{share:.0%}" for share in shares_evaluated(figures)),
            warned_text(figures["warned_share"]["events_only"]),
        ),
        context(
            f"cosim: {cosim.VEHICLES:,} vehicles, peak memory MB (bare / default / events only)",
            " / ".join(str(figures["peak_rss_mb"][name]) for name in ("bare", "default", "events_only")),
        ),
    ]


def warned_text(share: float | None) -> str:
    """What any exact schedule evaluates: the vehicle-steps with a curve warning on (each evaluated every step)."""
    return "" if share is None else f"{share:.0%} with a curve warning on (any schedule evaluates those every step)"


def shares_evaluated(figures: dict) -> list[float]:
    """The share of vehicle-steps the scheduled runs evaluated: default, events only, both systems."""
    share = figures["evaluated_share"]
    return [share[name] or 1.0 for name in ("default", "events_only", "both_systems")]


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
        context(
            f"cosim: {vehicles}, share of vehicle-steps evaluated (default / events only)",
            " / ".join(f"{city['evaluated_share'][name] or 1.0:.0%}" for name in ("default", "events_only")),
            warned_text(city["warned_share"]["events_only"]),
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
