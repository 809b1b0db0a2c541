"""Co-simulation cost against SUMO itself: 1,000 vehicles on the fleet road, 10,000 in a city.

Every run is a libsumo simulation timed whole (SUMO's start included), each in a fresh
process of its own, so that no run inherits another's warm caches:

* ``bare``: libsumo alone, ``simulationStep()`` only: the baseline of the ratios;
* ``read only``: csws reading every vehicle each step, no evaluation, no time series: the
  least a co-simulation that looks at every vehicle costs;
* ``without evaluation``: reading and the default time series (the older baseline, kept
  for continuity);
* ``default``: evaluation with the command's default time series (Parquet, one step per simulated
  second);
* ``events only``: evaluation, no time series (warning events, entries and summary), each vehicle
  evaluated only from where a curve warning can arise (``--evaluate scheduled``, the default);
* ``events every step``: the same with every vehicle evaluated at every step (``--evaluate every-step``);
* ``both systems``: the curve and the forward collision warning (``--systems csws,fcw``) with
  the default time series, and with events only (fleet road only);
* ``fcw read``: libsumo with the forward collision warning's read of every vehicle at every step and
  nothing else (small configuration): the floor of any evaluator driven through libsumo;
* ``ssm``: libsumo with SUMO's SSM device on every vehicle (TTC within 200 m, the FCW's range of
  concern), the cost the FCW is measured against: both systems' cost over bare SUMO at most half
  the SSM device's.

The fleet: the fleet network built with four lanes each way, 1,000 vehicles placed along
the road at t = 0, 30 s at 0.1 s steps. The city: Bad Hersfeld's network, 10,000 vehicles
of the fleet's mix placed at t = 0 on random walks through the roads every type may use,
30 s at 0.1 s steps: bare, default and events only, each with its peak memory (RSS).

Targets: the default run at most 1.5 times bare SUMO (fleet and city), the events-only run
at most 1.25 times; evaluation adds at most 50 % to the run without it, both systems at most
25 % (issue 16's target; FCW's own cost over the default run is shown beside it). The default runs'
summaries also give their milliseconds per step by component (SUMO's step with the read,
evaluation, recording).

Each run gives the share of its vehicle-steps that were evaluated. Run with ``python -m benchmarks.cosim``;
``python -m benchmarks.cosim --small`` runs the fleet road alone with 300 vehicles for 20 s (bare, bare
with SUMO's SSM device on every vehicle (TTC within 200 m, the FCW's range), events only, events every
step, the default run, and both systems with events only, scheduled and every step), a check that takes a
few minutes; it gives both systems' cost over bare SUMO as a share of the SSM device's (target at most
0.5), and the FCW alone scheduled and every step on the fleet road with 20 vehicles one every 15 s in one
direction for 300 s (sparse traffic, where the FCW's schedule lets vehicles sleep); and the share of
vehicle-steps any exact FCW schedule must evaluate on the small fleet (a vehicle ahead on its road whose
braking at its emergency deceleration could bring a warning at once). ``python -m benchmarks.cosim --city 10``
runs the city alone for 10 simulated seconds, with events only evaluated every step beside the scheduled run
(the schedule's own cost is its ``schedule`` component), and says whether their ``warnings.csv`` and
``entries.csv`` are the same bytes; ``python -m benchmarks.cosim --fleet`` the fleet road
alone with the curve warning's runs (bare, read only, default, events only scheduled and every step). Each run
also gives what it spends once, before its first step (``once_s``: the map's load): its whole time less the
summary's wall time.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import resource
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.command import arguments
from benchmarks.cosim_routes import city_routes_xml, sparse_routes_xml, start_routes_xml
from csws.cosim.config import default_timeseries_every
from csws.cosim.run import CosimConfig, Scenario, cosimulate
from csws.cosim.sensor import VehicleNumbers, read_vehicles, sensor_view
from csws.cosim.sumo import sumo_arguments
from csws.fcw.settings import FcwSettings
from csws.networks import networks_dir
from csws.networks.fleet import build_fleet_net
from csws.sumo.binaries import sumo_binary, sumo_home

VEHICLES = 1000
STEP_S = 0.1
DURATION_S = 30.0
LANES = 4
CITY_NET = networks_dir() / "badhersfeld.net.xml.gz"
CITY_VEHICLES = 10_000
CITY_DURATION_S = 30.0
TARGET_OVERHEAD = 0.5
#: The command's default time series: one step per simulated second.
DEFAULT_EVERY = default_timeseries_every(STEP_S)
TARGET_DEFAULT_RATIO = 1.5
TARGET_EVENTS_RATIO = 1.25
TARGET_BOTH_SYSTEMS_OVERHEAD = 0.25
#: The forward collision warning's cost over bare SUMO at most this share of SSM's (every vehicle with the device).
TARGET_FCW_OF_SSM_OVERHEAD = 0.5
#: The SSM device's range, m: the FCW's range of concern (4.3.2 a).
SSM_RANGE_M = 200.0
#: The sparse fleet of the small configuration: vehicles, one every this many seconds, simulated seconds.
SPARSE_VEHICLES, SPARSE_PERIOD_S, SPARSE_DURATION_S = 20, 15.0, 300.0
#: The small configuration (``--small``): vehicles and simulated seconds.
SMALL_VEHICLES = 300
SMALL_DURATION_S = 20.0


def _peak_rss_mb() -> float:
    """This process's peak resident memory, MB: its own memory's high-water mark (Linux's ``VmHWM``). The
    ``ru_maxrss`` of a spawned process keeps the larger resident size of the process it was forked from before
    its ``exec``: in ``python -m benchmarks``, whose process has grown by the modules before, every run then read
    the same 441 MB. ``ru_maxrss`` where ``/proc`` has no such line."""
    try:
        for line in Path("/proc/self/status").read_text(encoding="ascii").splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    except (OSError, ValueError, IndexError):
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _ssm_arguments(folder: Path) -> list[str]:
    """SUMO's SSM device on every vehicle, TTC over the FCW's range of concern (the ``ssm`` run's options)."""
    return [
        *("--device.ssm.probability", "1", "--device.ssm.measures", "TTC"),
        *("--device.ssm.range", f"{SSM_RANGE_M:g}", "--device.ssm.file", str(folder / "ssm.xml")),
    ]


def _bare_run(scenario: Scenario, duration_s: float, options: tuple[str, ...] = ()) -> dict:
    """libsumo alone (with SUMO ``options``): start, ``simulationStep()`` until the end, close (run in a
    process of its own)."""
    os.environ.setdefault("SUMO_HOME", str(sumo_home()))
    import libsumo

    arguments = [*sumo_arguments(None, scenario.net, scenario.routes, STEP_S, 0, duration_s), *options]
    started = time.perf_counter()
    libsumo.start([str(sumo_binary("sumo")), *arguments])
    steps = 0
    while libsumo.simulation.getMinExpectedNumber() > 0 and libsumo.simulation.getTime() < duration_s - 1e-9:
        libsumo.simulationStep()
        steps += 1
    libsumo.close()
    return {"seconds": time.perf_counter() - started, "steps": steps, "peak_rss_mb": _peak_rss_mb()}


def _fcw_read_run(scenario: Scenario, duration_s: float) -> dict:
    """libsumo with the forward collision warning's read of every vehicle at every step and nothing else
    (:func:`csws.cosim.sensor.read_vehicles`, a getter call per vehicle and value): the least any evaluator
    driven through libsumo that looks at every vehicle costs (run in a process of its own)."""
    os.environ.setdefault("SUMO_HOME", str(sumo_home()))
    import libsumo

    arguments = sumo_arguments(None, scenario.net, scenario.routes, STEP_S, 0, duration_s)
    numbers = VehicleNumbers()
    sizes: dict[str, tuple[float, float]] = {}
    roads: dict[str, int] = {}
    started = time.perf_counter()
    libsumo.start([str(sumo_binary("sumo")), *arguments])
    steps = 0
    while libsumo.simulation.getMinExpectedNumber() > 0 and libsumo.simulation.getTime() < duration_s - 1e-9:
        libsumo.simulationStep()
        read_vehicles(libsumo, numbers, sizes, roads)
        steps += 1
    libsumo.close()
    return {"seconds": time.perf_counter() - started, "steps": steps, "peak_rss_mb": _peak_rss_mb()}


def _csws_run(config: CosimConfig) -> dict:
    """One ``csws cosim`` run (in a process of its own): its time, summary and peak memory. libsumo is
    imported before the clock starts, as in the bare run; csws's own imports are timed."""
    os.environ.setdefault("SUMO_HOME", str(sumo_home()))
    import libsumo  # noqa: F401

    started = time.perf_counter()
    summary = cosimulate(config)
    return {
        "seconds": time.perf_counter() - started,
        "steps": summary["steps"],
        "summary": summary,
        "peak_rss_mb": _peak_rss_mb(),
    }


def _in_own_process(function, *arguments) -> dict:
    """``function(*arguments)`` in a fresh Python process (libsumo holds one simulation per process)."""
    with ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn")) as pool:
        return pool.submit(function, *arguments).result()


def _figures(runs: dict[str, dict]) -> dict:
    """ms per step of each run, their ratios to bare SUMO, peak memory, and the default run's components."""
    ms_per_step = {name: 1000.0 * run["seconds"] / run["steps"] for name, run in runs.items()}
    default = runs["default"]["summary"]
    return {
        "vehicles": default["vehicles_evaluated"],
        "steps": default["steps"],
        "ms_per_step": ms_per_step,
        "ratio_to_bare": {name: value / ms_per_step["bare"] for name, value in ms_per_step.items() if name != "bare"},
        "peak_rss_mb": {name: round(run["peak_rss_mb"]) for name, run in runs.items()},
        "evaluated_share": {
            name: run["summary"]["evaluation"]["vehicle_steps_evaluated_share"]
            for name, run in runs.items()
            if "summary" in run
        },
        "warned_share": {
            name: run["summary"]["evaluation"]["vehicle_steps_warned_share"]
            for name, run in runs.items()
            if "summary" in run
        },
        "once_s": {
            name: run["seconds"] - run["summary"]["wall_time_s"] for name, run in runs.items() if "summary" in run
        },
        "default_components_ms_per_step": default["ms_per_step"],
        "components_ms_per_step": {
            name: run["summary"]["ms_per_step"] for name, run in runs.items() if "summary" in run
        },
    }


def _fleet_scenario(work: Path, vehicles: int) -> Scenario:
    """The fleet road with ``vehicles`` vehicles placed at t = 0."""
    net = build_fleet_net(work / "fleet4.net.xml", lanes=LANES)
    routes = work / "bench.rou.xml"
    routes.write_text(start_routes_xml(vehicles), encoding="utf-8")
    return Scenario(None, net, (routes,))


def small_run() -> dict:
    """The small configuration: the fleet road with :data:`SMALL_VEHICLES` for :data:`SMALL_DURATION_S`."""
    with tempfile.TemporaryDirectory(prefix="csws-bench-cosim-") as folder:
        work = Path(folder)
        scenario = _fleet_scenario(work, SMALL_VEHICLES)
        common: dict[str, Any] = {"scenario": scenario, "step_length_s": STEP_S, "end_s": SMALL_DURATION_S}
        runs = {"bare": _in_own_process(_bare_run, scenario, SMALL_DURATION_S)}
        runs["ssm"] = _in_own_process(_bare_run, scenario, SMALL_DURATION_S, tuple(_ssm_arguments(work)))
        runs["fcw_read"] = _in_own_process(_fcw_read_run, scenario, SMALL_DURATION_S)
        both: dict[str, Any] = {"systems": ("csws", "fcw"), "timeseries": "none"}
        configs = {
            "default": CosimConfig(out=work / "default", timeseries_every=DEFAULT_EVERY, **common),
            "events_only": CosimConfig(out=work / "events", timeseries="none", **common),
            "events_every_step": CosimConfig(
                out=work / "events-every", timeseries="none", evaluation="every-step", **common
            ),
            "both_systems_events": CosimConfig(out=work / "both", **both, **common),
            "both_systems_every_step": CosimConfig(out=work / "both-every", evaluation="every-step", **both, **common),
        }
        runs |= {name: _in_own_process(_csws_run, config) for name, config in configs.items()}
        wake = _in_own_process(_wake_floor_run, scenario, SMALL_DURATION_S)
        return _figures(runs) | _fcw_of_ssm(runs) | {"sparse_fcw": _sparse_fcw(work), "fcw_wake_floor": wake}


def _wake_floor_run(scenario: Scenario, duration_s: float) -> dict:
    """The share of vehicle-steps that any exact FCW schedule must evaluate: those with a vehicle ahead on the
    same road (any lane: SUMO changes lanes within a step; and in the vehicle's own lane) near enough that its
    braking at its type's emergency deceleration from the next step would bring a_req (3.22, a target that stops
    first) to the preliminary threshold at once: clearance <= v T + v^2 / (2 a_pre) - v_L^2 / (2 d_emergency).
    Every SUMO vehicle is a subject, viewed as the co-simulation does without map paths (run in its own process)."""
    os.environ.setdefault("SUMO_HOME", str(sumo_home()))
    import libsumo

    settings = FcwSettings()
    numbers, sizes, roads = VehicleNumbers(), dict[str, tuple[float, float]](), dict[str, int]()
    emergency_mps2: dict[int, float] = {}
    counts = {"vehicle_steps": 0, "any_lane": 0, "own_lane": 0}
    libsumo.start(
        [str(sumo_binary("sumo")), *sumo_arguments(None, scenario.net, scenario.routes, STEP_S, 0, duration_s)]
    )
    while libsumo.simulation.getMinExpectedNumber() > 0 and libsumo.simulation.getTime() < duration_s - 1e-9:
        libsumo.simulationStep()
        vehicles = read_vehicles(libsumo, numbers, sizes, roads)
        for vehicle_id, number in zip(vehicles.vehicle_id, vehicles.number.tolist(), strict=True):
            if number not in emergency_mps2:
                emergency_mps2[number] = float(libsumo.vehicle.getEmergencyDecel(vehicle_id))
        subjects = np.arange(len(vehicles.vehicle_id))
        view = sensor_view(vehicles, subjects, settings.range_m)
        speed_mps = vehicles.speed_mps[view.subject]
        leader_mps = np.maximum(speed_mps + view.relative_speed_mps, 0.0)
        braking_mps2 = np.array([emergency_mps2[n] for n in vehicles.number[view.seen].tolist()])
        reach_m = (
            speed_mps * settings.reaction_time_s
            + speed_mps**2 / (2.0 * settings.preliminary_a_req_mps2)
            - leader_mps**2 / (2.0 * braking_mps2)
        )
        near = (view.x_m <= reach_m) & (vehicles.road[view.seen] == vehicles.road[view.subject])
        counts["vehicle_steps"] += subjects.size
        counts["any_lane"] += np.unique(view.subject[near]).size
        counts["own_lane"] += np.unique(view.subject[near & (view.lane == 0)]).size
    libsumo.close()
    return {name: counts[name] / max(counts["vehicle_steps"], 1) for name in ("any_lane", "own_lane")}


def _sparse_fcw(work: Path) -> dict:
    """The FCW alone, events only, on the fleet road with :data:`SPARSE_VEHICLES` one every
    :data:`SPARSE_PERIOD_S` in one direction: ms per step and the share evaluated, scheduled and every step."""
    routes = work / "sparse.rou.xml"
    routes.write_text(sparse_routes_xml(SPARSE_VEHICLES, SPARSE_PERIOD_S), encoding="utf-8")
    scenario = Scenario(None, build_fleet_net(work / "sparse.net.xml", lanes=LANES), (routes,))
    common: dict[str, Any] = {"scenario": scenario, "step_length_s": STEP_S, "end_s": SPARSE_DURATION_S}
    figures = {}
    for evaluation in ("scheduled", "every-step"):
        config = CosimConfig(
            out=work / f"sparse-{evaluation}", systems=("fcw",), timeseries="none", evaluation=evaluation, **common
        )
        run = _in_own_process(_csws_run, config)
        figures[evaluation] = {
            "ms_per_step": 1000.0 * run["seconds"] / run["steps"],
            "evaluated_share": run["summary"]["evaluation"]["vehicle_steps_evaluated_share"],
            "components_ms_per_step": run["summary"]["ms_per_step"],
        }
    return figures


def _fcw_of_ssm(runs: dict[str, dict]) -> dict:
    """Both systems' cost over bare SUMO (events only, scheduled and every step) as a share of the SSM device's,
    beside the FCW's read alone's (the floor of a libsumo-driven FCW) and the curve warning alone's: whole runs
    (csws's map load included), and per step (the runs' steps alone: their ``ms_per_step`` components less
    bare SUMO's ms per step), with the FCW component's own share; and both systems' floor, the curve warning's
    share per step and the FCW's read's added (what both cost before the FCW computes anything)."""
    ms = {name: 1000.0 * run["seconds"] / run["steps"] for name, run in runs.items()}
    ssm_ms = ms["ssm"] - ms["bare"]
    names = [
        name
        for name in ("fcw_read", "events_only", "both_systems", "both_systems_events", "both_systems_every_step")
        if name in runs
    ]
    stepping = {name: sum(runs[name]["summary"]["ms_per_step"].values()) for name in names if "summary" in runs[name]}
    per_step = {name: (value - ms["bare"]) / ssm_ms for name, value in stepping.items()}
    floor = {}
    if "fcw_read" in runs and "events_only" in per_step:
        floor["both_systems_floor_of_ssm_overhead"] = per_step["events_only"] + (ms["fcw_read"] - ms["bare"]) / ssm_ms
    return floor | {
        "fcw_of_ssm_overhead": {name: (ms[name] - ms["bare"]) / ssm_ms for name in names},
        "fcw_of_ssm_overhead_per_step": per_step,
        "fcw_component_of_ssm_overhead": {
            name: runs[name]["summary"]["ms_per_step"]["fcw"] / ssm_ms
            for name in stepping
            if "fcw" in runs[name]["summary"]["ms_per_step"]
        },
    }


def _curve_configs(work: Path, common: dict[str, Any]) -> dict[str, CosimConfig]:
    """The fleet road's runs of the curve warning alone: reading only, default, events only (scheduled and
    every step)."""
    return {
        "read_only": CosimConfig(out=work / "read", evaluate=False, timeseries="none", **common),
        "default": CosimConfig(out=work / "default", timeseries_every=DEFAULT_EVERY, **common),
        "events_only": CosimConfig(out=work / "events", timeseries="none", **common),
        "events_every_step": CosimConfig(
            out=work / "events-every", timeseries="none", evaluation="every-step", **common
        ),
    }


def fleet_run() -> dict:
    """The fleet road alone, the curve warning's runs only (``--fleet``): bare SUMO, reading only, default,
    events only scheduled and every step."""
    with tempfile.TemporaryDirectory(prefix="csws-bench-cosim-") as folder:
        work = Path(folder)
        scenario = _fleet_scenario(work, VEHICLES)
        common: dict[str, Any] = {"scenario": scenario, "step_length_s": STEP_S, "end_s": DURATION_S}
        runs = {"bare": _in_own_process(_bare_run, scenario, DURATION_S)}
        runs |= {name: _in_own_process(_csws_run, config) for name, config in _curve_configs(work, common).items()}
        return _figures(runs)


def _fleet_figures(work: Path) -> dict:
    """The fleet road: 1,000 vehicles, every kind of run."""
    scenario = _fleet_scenario(work, VEHICLES)
    common: dict[str, Any] = {"scenario": scenario, "step_length_s": STEP_S, "end_s": DURATION_S}
    runs = {"bare": _in_own_process(_bare_run, scenario, DURATION_S)}
    runs["ssm"] = _in_own_process(_bare_run, scenario, DURATION_S, tuple(_ssm_arguments(work)))
    sampled: dict[str, Any] = {"timeseries_every": DEFAULT_EVERY}
    configs = _curve_configs(work, common) | {
        "without_evaluation": CosimConfig(out=work / "baseline", evaluate=False, **sampled, **common),
        "both_systems": CosimConfig(out=work / "both", systems=("csws", "fcw"), **sampled, **common),
        "both_systems_events": CosimConfig(
            out=work / "both-events", systems=("csws", "fcw"), timeseries="none", **common
        ),
    }
    runs |= {name: _in_own_process(_csws_run, config) for name, config in configs.items()}
    figures = _figures(runs)
    seconds = {name: run["seconds"] for name, run in runs.items()}
    figures["overhead"] = seconds["default"] / seconds["without_evaluation"] - 1.0
    figures["both_systems_overhead"] = seconds["both_systems"] / seconds["without_evaluation"] - 1.0
    figures["fcw_over_default"] = seconds["both_systems"] / seconds["default"] - 1.0
    figures["both_systems_components_ms_per_step"] = runs["both_systems"]["summary"]["ms_per_step"]
    return figures | _fcw_of_ssm(runs)


def _city_figures(work: Path, duration_s: float = CITY_DURATION_S, every_step: bool = False) -> dict:
    """Bad Hersfeld: 10,000 vehicles for ``duration_s``, bare, default and events only (and with ``every_step``
    events only with every vehicle evaluated at every step, the schedule's comparison)."""
    routes = work / "city.rou.xml"
    routes.write_text(city_routes_xml(CITY_NET, CITY_VEHICLES), encoding="utf-8")
    scenario = Scenario(None, CITY_NET, (routes,))
    common: dict[str, Any] = {"scenario": scenario, "step_length_s": STEP_S, "end_s": duration_s}
    configs = {
        "default": CosimConfig(out=work / "city-default", timeseries_every=DEFAULT_EVERY, **common),
        "events_only": CosimConfig(out=work / "city-events", timeseries="none", **common),
    }
    if every_step:
        configs["events_every_step"] = CosimConfig(
            out=work / "city-events-every", timeseries="none", evaluation="every-step", **common
        )
    runs = {"bare": _in_own_process(_bare_run, scenario, duration_s)}
    runs |= {name: _in_own_process(_csws_run, config) for name, config in configs.items()}
    figures = _figures(runs)
    if every_step:
        scheduled, every = configs["events_only"].out, configs["events_every_step"].out
        figures["same_events_as_every_step"] = all(
            (scheduled / name).read_bytes() == (every / name).read_bytes() for name in ("warnings.csv", "entries.csv")
        )
    return figures


def run() -> dict:
    """The fleet road's and the city's figures."""
    with tempfile.TemporaryDirectory(prefix="csws-bench-cosim-") as work:
        return {**_fleet_figures(Path(work)), "city": _city_figures(Path(work))}


def _print(figures: dict) -> None:
    """One line per run: ms per step, ratio to bare SUMO, peak memory; the default run's components."""
    print(f"{figures['vehicles']} vehicles, {figures['steps']} steps of {STEP_S:g} s")
    for name, value in figures["ms_per_step"].items():
        ratio = figures["ratio_to_bare"].get(name)
        print(
            f"{name:<20}{value:>8.2f} ms/step"
            + (f"  {ratio:.2f} x bare SUMO" if ratio else "")
            + f"  peak {figures['peak_rss_mb'][name]} MB"
            + (
                f"  {figures['evaluated_share'][name]:.1%} of vehicle-steps evaluated"
                if figures["evaluated_share"].get(name) is not None
                else ""
            )
            + (
                f", {figures['warned_share'][name]:.1%} with a curve warning on"
                if figures["warned_share"].get(name) is not None
                else ""
            )
        )
    for name, components in figures["components_ms_per_step"].items():
        print(
            f"{name} by component, ms/step:",
            components,
            f"once per run (the map's load): {figures['once_s'][name]:.2f} s",
        )


def _print_of_ssm(figures: dict) -> None:
    """Each run's cost over bare SUMO as a share of the SSM device's: whole run, per step, the FCW's own."""
    per_step, fcw = figures["fcw_of_ssm_overhead_per_step"], figures["fcw_component_of_ssm_overhead"]
    for name, share in figures["fcw_of_ssm_overhead"].items():
        print(
            f"{name}: {share:.2f} of the SSM device's overhead (target <= {TARGET_FCW_OF_SSM_OVERHEAD:g})"
            + (f", per step {per_step[name]:.2f}" if name in per_step else "")
            + (f", the FCW's own {fcw[name]:.2f}" if name in fcw else "")
        )
    if "both_systems_floor_of_ssm_overhead" in figures:
        print(
            f"both systems' floor (curve warning per step + the FCW's read): "
            f"{figures['both_systems_floor_of_ssm_overhead']:.2f} of the SSM device's overhead"
        )


def _add_arguments(parser: argparse.ArgumentParser) -> None:
    """The small configuration, or the city alone (for how many simulated seconds)."""
    parser.add_argument("--small", action="store_true", help="300 vehicles, with SSM and the FCW's floors")
    parser.add_argument(
        "--fleet", action="store_true", help="the fleet road alone, the curve warning's runs only (no SSM, no FCW)"
    )
    parser.add_argument(
        "--city",
        type=float,
        metavar="SECONDS",
        help="the city alone for SECONDS simulated seconds, with events only evaluated every step beside scheduled "
        "(and their warnings.csv and entries.csv compared)",
    )


def main() -> None:
    """Print each figure beside its target (``--small``: the small configuration's)."""
    options = arguments("benchmarks.cosim", __doc__, _add_arguments)
    if options.city is not None:
        with tempfile.TemporaryDirectory(prefix="csws-bench-cosim-") as work:
            city = _city_figures(Path(work), options.city, every_step=True)
        _print(city)
        same = "the same bytes" if city["same_events_as_every_step"] else "DIFFER"
        print("warnings.csv and entries.csv of events only, scheduled and every step:", same)
        return
    if options.fleet:
        _print(fleet_run())
        return
    if options.small:
        figures = small_run()
        _print(figures)
        _print_of_ssm(figures)
        print("sparse road, FCW alone, events only:", figures["sparse_fcw"])
        print(
            "vehicle-steps any exact FCW schedule evaluates (a vehicle ahead on its road whose emergency braking "
            f"could warn at once): {figures['fcw_wake_floor']['any_lane']:.0%} with one in any lane, "
            f"{figures['fcw_wake_floor']['own_lane']:.0%} in its own"
        )
        return
    figures = run()
    _print(figures)
    print(f"evaluation overhead {figures['overhead']:.0%} (target <= {TARGET_OVERHEAD:.0%})")
    print(
        f"both systems' overhead {figures['both_systems_overhead']:.0%} "
        f"(target <= {TARGET_BOTH_SYSTEMS_OVERHEAD:.0%}), "
        f"FCW over the default run {figures['fcw_over_default']:.0%}"
    )
    _print_of_ssm(figures)
    print("city:")
    _print(figures["city"])


if __name__ == "__main__":
    main()
