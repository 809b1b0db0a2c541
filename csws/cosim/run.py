"""``csws cosim``: drive a fleet through SUMO and record who was warned where.

Every step, every vehicle of a covered class is evaluated at once (the library's
``evaluate_fleet``, or one HTTP batch to a service), its state and warning are appended
to the time series, level changes to the warning events and curve entries above the
warning speed to the entries; the summary is rewritten at the end, also when the run is
interrupted or SUMO dies (then marked incomplete, with the reason).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from xml.etree import ElementTree

from csws.cli.progress import Progress
from csws.standard import mps_to_kmh

from .cli import SYSTEMS
from .driver import DriverResponse, DriverSettings
from .evaluators import Evaluator, FleetWarnings, LibraryEvaluator, ServiceError, ServiceEvaluator
from .fcw import FCW_EVENT_COLUMNS, FcwColumns, FleetFcw, fcw_events, respond_to_fcw
from .records import (
    ENTRY_COLUMNS,
    EVENT_COLUMNS,
    CsvStream,
    StepCosts,
    Summary,
    event_of,
    level1_excess_kmh,
    write_summary,
)
from .summary import write_run_summary
from .sumo import FleetState, Simulation, SumoStopped, sumo_arguments
from .timeseries import TimeseriesWriter, open_timeseries

__all__ = ["SYSTEMS", "CosimConfig", "Scenario", "bundled_scenario", "scenario_from_args", "cosimulate", "main"]


@dataclass(frozen=True)
class Scenario:
    """A SUMO scenario: a configuration, or a network with route files.

    Attributes
    ----------
    config
        A ``.sumocfg``, or None.
    net
        The network (read from the configuration when one is given).
    routes
        Route files beyond the configuration's.
    """

    config: Path | None
    net: Path
    routes: tuple[Path, ...] = ()


@dataclass(frozen=True)
class CosimConfig:
    """How to run a co-simulation.

    Attributes
    ----------
    scenario
        What to simulate.
    out
        Output folder.
    step_length_s
        SUMO's step length, s (also the engine's update period).
    end_s
        Stop at this simulation time, s; None runs until every vehicle has arrived.
    interface
        ``libsumo``, ``traci`` or ``gui``.
    service_url
        Ask this csws service instead of the library.
    driver
        The driver-response model, or None.
    seed
        SUMO's random seed.
    evaluate
        False runs SUMO and reads the fleet without asking for warnings (a baseline).
    progress
        Show how far the run is on stderr (:class:`csws.cli.progress.Progress`).
    timeseries
        How the time series is kept: ``parquet``, ``csv`` or ``none`` (:mod:`csws.cosim.timeseries`).
    timeseries_every
        Keep every this many steps in the time series.
    systems
        The warning systems evaluated: ``csws`` (curve speed warning) and ``fcw`` (forward
        collision warning, :mod:`csws.cosim.fcw`), either or both.
    """

    scenario: Scenario
    out: Path
    step_length_s: float = 0.1
    end_s: float | None = None
    interface: str = "libsumo"
    service_url: str | None = None
    driver: DriverSettings | None = None
    seed: int = 0
    evaluate: bool = True
    progress: bool = False
    timeseries: str = "parquet"
    timeseries_every: int = 1
    systems: tuple[str, ...] = ("csws",)

    def __post_init__(self) -> None:
        if not self.systems or not set(self.systems) <= set(SYSTEMS):
            raise ValueError(f"--systems takes one or both of {', '.join(SYSTEMS)}, got {','.join(self.systems)!r}")
        if "fcw" in self.systems and self.service_url is not None:
            raise ValueError(
                "the forward collision warning is evaluated in this process only: drop --service, "
                "or run --systems csws with it"
            )

    @property
    def fcw(self) -> bool:
        """Whether the forward collision warning is evaluated."""
        return self.evaluate and "fcw" in self.systems


def bundled_scenario() -> Scenario:
    """The fleet on the bundled fleet network (``networks/fleet_scenario/fleet.sumocfg``)."""
    from csws.networks.fleet import FLEET_NAME, fleet_dir

    return _config_scenario(fleet_dir() / f"{FLEET_NAME}.sumocfg")


def _config_scenario(config: Path) -> Scenario:
    """A scenario from a ``.sumocfg``: its network is read from it, relative to its folder."""
    if not config.is_file():
        raise ValueError(f"no such SUMO configuration: {config}")
    try:
        root = ElementTree.parse(config).getroot()
    except ElementTree.ParseError as exc:
        raise ValueError(f"{config} is not a SUMO configuration: {exc}") from None
    net = root.find("./input/net-file")
    if net is None or not net.get("value"):
        raise ValueError(f"{config} names no net-file")
    return Scenario(config, (config.parent / net.get("value")).resolve())


def scenario_from_args(args: argparse.Namespace) -> Scenario:
    """The scenario the command line asks for; the bundled fleet by default."""
    routes = tuple(args.routes or ())
    for path in routes:
        if not path.is_file():
            raise ValueError(f"no such route file: {path}")
    if args.sumocfg is not None:
        if args.net is not None:
            raise ValueError("give either --sumocfg or --net, not both")
        return replace(_config_scenario(args.sumocfg), routes=routes)
    if args.net is not None:
        if not args.net.is_file():
            raise ValueError(f"no such network: {args.net}")
        if not routes:
            raise ValueError("--net needs --routes (or use --sumocfg)")
        return Scenario(None, args.net, routes)
    scenario = bundled_scenario()
    if args.vehicles is None:
        return scenario
    from csws.networks.fleet import fleet_routes_xml

    args.out.mkdir(parents=True, exist_ok=True)
    generated = args.out / "fleet.rou.xml"
    generated.write_text(fleet_routes_xml(args.vehicles, period_s=args.vehicles, seed=args.seed), encoding="utf-8")
    return Scenario(None, scenario.net, (generated,))


def _evaluator(config: CosimConfig) -> Evaluator | None:
    """The library or the service, or None for a baseline run or one without the curve warning."""
    if not config.evaluate or "csws" not in config.systems:
        return None
    if config.service_url is not None:
        return ServiceEvaluator(config.service_url)
    from csws.engine import Engine, EngineSettings
    from csws.road.roadmap import RoadMap
    from csws.warning.rules import WarningSettings

    road_map = RoadMap.load(config.scenario.net)
    return LibraryEvaluator(
        Engine(road_map, EngineSettings(warning=WarningSettings(update_period_s=config.step_length_s)))
    )


@dataclass
class _Streams:
    """The run's output files."""

    timeseries: TimeseriesWriter
    warnings: CsvStream
    entries: CsvStream

    @classmethod
    def open(cls, out: Path, timeseries_format: str, fcw: bool) -> _Streams:
        return cls(
            open_timeseries(out, timeseries_format, fcw),
            CsvStream(out / "warnings.csv", EVENT_COLUMNS + (FCW_EVENT_COLUMNS if fcw else ())),
            CsvStream(out / "entries.csv", ENTRY_COLUMNS),
        )

    def close(self) -> None:
        for stream in (self.timeseries, self.warnings, self.entries):
            stream.close()


@dataclass
class _Tracker:
    """What the run remembers per vehicle between steps: last level, the curve of its last
    onset or change, when its warning last went off, curve parts entered."""

    levels: dict[str, int] = field(default_factory=dict)
    curves: dict[str, str | None] = field(default_factory=dict)
    ended_s: dict[str, float] = field(default_factory=dict)
    entered: dict[str, set] = field(default_factory=dict)
    fcw_levels: dict[str, int] = field(default_factory=dict)

    def forget(self, vehicle_id: str) -> None:
        self.levels.pop(vehicle_id, None)
        self.fcw_levels.pop(vehicle_id, None)
        self.curves.pop(vehicle_id, None)
        self.ended_s.pop(vehicle_id, None)
        self.entered.pop(vehicle_id, None)


def _record_step(
    fleet: FleetState,
    warnings: FleetWarnings,
    fcw: FcwColumns | None,
    commands: dict[str, float],
    tracker: _Tracker,
    summary: Summary,
    streams: _Streams,
    sampled: bool,
    position: Callable[[str], tuple[float, float]] | None = None,
) -> None:
    """Append one step to the files and the summary.

    Every vehicle gets a time-series row when the step is ``sampled``, given column-wise;
    only the warned vehicles (and those whose level changed) are looked at one by one. With
    the forward collision warning (``fcw``), its columns and events go beside the curve warning's.
    ``position`` gives a vehicle's x, y where the step was read without them (an event's row needs them).
    """
    count = len(fleet.vehicle_id)
    speeds_kmh = mps_to_kmh(fleet.speed_mps).tolist()
    lane_pos, xs, ys = fleet.lane_pos_m.tolist(), fleet.x_m.tolist(), fleet.y_m.tolist()

    def place(i: int) -> tuple[float, float]:
        return (xs[i], ys[i]) if position is None else position(fleet.vehicle_id[i])

    t = fleet.time_s
    target = warnings.target
    commanded_kmh = [None] * count
    if commands:
        row_of = {vehicle_id: i for i, vehicle_id in enumerate(fleet.vehicle_id)}
        for vehicle_id, command in commands.items():
            commanded_kmh[row_of[vehicle_id]] = None if command < 0 else mps_to_kmh(command)
    if sampled:
        streams.timeseries.append(
            (
                [t] * count,
                fleet.vehicle_id,
                fleet.category,
                fleet.lane_id,
                lane_pos,
                xs,
                ys,
                speeds_kmh,
                warnings.state,
                warnings.level,
                target.curve_id,
                target.part_index,
                target.distance_m,
                target.warning_speed_kmh,
                commanded_kmh,
                *(fcw.columns() if fcw else ()),
            )
        )
    levels, pad = tracker.levels, (None,) * len(FCW_EVENT_COLUMNS) if fcw else ()
    changed = [
        i
        for i, (vehicle_id, level) in enumerate(zip(fleet.vehicle_id, warnings.level, strict=False))
        if level != levels.get(vehicle_id, 0)
    ]
    events = []
    for i in changed:
        vehicle_id, category, level, curve_id = (
            fleet.vehicle_id[i],
            fleet.category[i],
            warnings.level[i],
            target.curve_id[i],
        )
        previous = levels.get(vehicle_id, 0)
        event = event_of(previous, level)
        levels[vehicle_id] = level
        if event == "end":
            tracker.ended_s[vehicle_id] = t
        else:
            if event == "onset" and t - tracker.ended_s.get(vehicle_id, -math.inf) <= summary.flicker_window_s:
                summary.add_soon_again(category, tracker.curves.get(vehicle_id) == curve_id)
            tracker.curves[vehicle_id] = curve_id
        if level > previous:
            summary.add_onset(category, level, curve_id)
            summary.warned_vehicles.add(vehicle_id)
        events.append(
            (
                t,
                vehicle_id,
                category,
                event,
                level,
                previous,
                curve_id,
                target.part_index[i],
                target.radius_m[i],
                target.distance_m[i],
                target.warning_speed_kmh[i],
                speeds_kmh[i],
                fleet.lane_id[i],
                lane_pos[i],
                *place(i),
                *pad,
            )
        )
    entries = []
    for i, curve_id, part_index, radius_m, level in warnings.entries:
        vehicle_id, category = fleet.vehicle_id[i], fleet.category[i]
        entered = tracker.entered.setdefault(vehicle_id, set())
        if (curve_id, part_index) in entered:
            continue
        entered.add((curve_id, part_index))
        level1_kmh, excess_kmh = level1_excess_kmh(speeds_kmh[i], category, radius_m)
        summary.add_entry(category, excess_kmh)
        entries.append(
            (t, vehicle_id, category, curve_id, part_index, radius_m, speeds_kmh[i], level1_kmh, excess_kmh, level)
        )
    if fcw:
        events += fcw_events(fleet, fcw, tracker.fcw_levels, summary, (speeds_kmh, lane_pos, place))
    streams.warnings.append(events)
    streams.entries.append(entries)


def _drive(driver: DriverResponse, fleet: FleetState, warnings: FleetWarnings, step_s: float) -> dict[str, float]:
    """The driver-response model's speed commands of this step, per vehicle (m/s; -1 hands back)."""
    commands = {}
    target = warnings.target
    for i, (vehicle_id, level) in enumerate(zip(fleet.vehicle_id, warnings.level, strict=False)):
        if level == 0 and vehicle_id not in driver.drivers:
            continue
        command = driver.commands(
            fleet.time_s,
            step_s,
            vehicle_id,
            level,
            target.warning_speed_kmh[i],
            target.distance_m[i],
            float(fleet.speed_mps[i]),
            float(fleet.odometer_m[i]),
        )
        if command is not None:
            commands[vehicle_id] = command
    return commands


def cosimulate(config: CosimConfig) -> dict:
    """Run one co-simulation into ``config.out``; its summary (also written to ``summary.json``).

    Raises
    ------
    SumoStopped
        When SUMO dies; the files hold everything up to the last complete step.
    KeyboardInterrupt
        When interrupted; likewise.
    """
    config.out.mkdir(parents=True, exist_ok=True)
    evaluator = _evaluator(config)
    scenario = config.scenario
    sumo_args = sumo_arguments(
        scenario.config,
        scenario.net if scenario.config is None else None,
        scenario.routes,
        config.step_length_s,
        config.seed,
        config.end_s,
    )
    summary, tracker = Summary(fcw_onsets=Counter() if config.fcw else None), _Tracker()
    driver = DriverResponse(config.driver) if config.driver is not None else None
    streams = _Streams.open(config.out, config.timeseries, config.fcw)
    costs = StepCosts()
    status, started = "running", time.perf_counter()
    simulation = None
    bar = Progress("cosim", config.end_s, "sim s", decimals=1, enabled=config.progress)
    try:
        simulation = Simulation(sumo_args, config.interface, odometer=driver is not None)
        forward = FleetFcw(simulation.api) if config.fcw else None
        step_s = simulation.step_length_s
        while simulation.expected_vehicles() > 0:
            sampled = summary.steps % config.timeseries_every == 0
            # Without a time-series row this step, x and y are read only for the vehicles with an event.
            positions = sampled and config.timeseries != "none"
            with costs.timed("sumo_step_and_read"):
                fleet = simulation.step(positions)
            for vehicle_id in fleet.arrived:
                tracker.forget(vehicle_id)
                if driver is not None:
                    driver.forget(vehicle_id)
            for forgetting in (evaluator, forward):
                if forgetting is not None:
                    forgetting.forget(fleet.arrived)
            summary.skipped.update(fleet.skipped)
            with costs.timed("evaluation"):
                if evaluator is not None and fleet.vehicle_id:
                    warnings = evaluator(fleet)
                else:
                    warnings = FleetWarnings.none(len(fleet.vehicle_id))
            fcw = None
            if forward is not None:
                with costs.timed("fcw"):
                    fcw = forward(fleet.vehicle_id, fleet.lane_id, fleet.speed_mps)
            commands = _drive(driver, fleet, warnings, step_s) if driver is not None else {}
            if fcw is not None and driver is not None:
                respond_to_fcw(driver, fleet, fcw, step_s, commands)
            for vehicle_id, speed_mps in commands.items():
                simulation.set_speed(vehicle_id, speed_mps)
            with costs.timed("recording"):
                _record_step(
                    fleet,
                    warnings,
                    fcw,
                    commands,
                    tracker,
                    summary,
                    streams,
                    sampled,
                    None if positions or simulation.reads_positions else simulation.position,
                )
            summary.vehicles.update(fleet.vehicle_id)
            summary.steps += 1
            summary.last_time_s = fleet.time_s
            bar.update(step_s)
            if config.end_s is not None and fleet.time_s >= config.end_s:
                break
        status = "complete"
    except SumoStopped as exc:
        status = f"SUMO stopped: {exc}"
        raise
    except KeyboardInterrupt:
        status = "interrupted"
        raise
    except ServiceError as exc:
        status = f"service failed: {exc}"
        raise
    finally:
        bar.close()
        streams.close()
        if simulation is not None:
            simulation.close()
        if evaluator is not None:
            evaluator.close()
        content = _summary_content(config, summary, status, time.perf_counter() - started, costs)
        write_summary(config.out / "summary.json", content)
    return content


def _summary_content(config: CosimConfig, summary: Summary, status: str, wall_s: float, costs: StepCosts) -> dict:
    """The summary of one run with how it was run and where its time went."""
    scenario = config.scenario
    return {
        "format": "csws-cosim-summary/1",
        "status": status,
        "complete": status == "complete",
        "scenario": {
            "config": None if scenario.config is None else str(scenario.config),
            "net": str(scenario.net),
            "routes": [str(r) for r in scenario.routes],
        },
        "mode": "service" if config.service_url else "library" if config.evaluate else "baseline (no evaluation)",
        "service_url": config.service_url,
        "systems": list(config.systems),
        "interface": config.interface,
        "step_length_s": config.step_length_s,
        "driver_response": None if config.driver is None else vars(config.driver),
        "timeseries": {"format": config.timeseries, "every_steps": config.timeseries_every},
        "wall_time_s": round(wall_s, 3),
        "ms_per_step": costs.ms_per_step(summary.steps),
        **summary.as_dict(),
    }


def _comparison(without: dict, with_response: dict) -> dict:
    """How the fleet did with the driver-response model against without it."""

    def figures(summary: dict) -> dict:
        entries = summary["curve_entries_above_level1_warning_speed"]
        return {
            "warnings_by_level": summary["warnings"]["by_level"],
            "warnings_flickered": summary["warnings"]["flickered"],
            "warnings_on_again_for_another_curve": summary["warnings"]["on_again_for_another_curve"],
            "curve_entries_above_level1": entries["total"],
            "curve_entries_more_than_1_kmh_above_level1": entries["more_than_1_kmh_above"],
            "max_excess_kmh": entries["max_excess_kmh"],
        }

    return {"without_response": figures(without), "with_response": figures(with_response)}


def _print_summary(summary: dict, out: Path) -> None:
    """A few lines on the terminal."""
    warnings = summary["warnings"]["by_level"]
    entries = summary["curve_entries_above_level1_warning_speed"]
    print(
        f"{summary['vehicles_evaluated']} vehicles over {summary['simulated_until_s']:g} s "
        f"({summary['mode']}): {warnings['level1']} level-1 and {warnings['level2']} level-2 warnings "
        f"({summary['warnings']['flickered']} flickered: off and on again for the same curve within "
        f"{summary['warnings']['flicker_window_s']:g} s), {entries['total']} curve entries above the level-1 warning speed "
        f"({entries['more_than_1_kmh_above']} by more than 1 km/h)"
        + (
            ""
            if "fcw" not in summary
            else f"; forward collision: {summary['fcw']['by_level']['level1']} preliminary and "
            f"{summary['fcw']['by_level']['level2']} collision warnings"
        )
        + f"; output in {out}"
    )


def main(args: argparse.Namespace) -> int:
    """The ``csws cosim`` command: 0 when the run completes, 1 (with one line on stderr) when SUMO or the service fails."""
    scenario = scenario_from_args(args)
    interface = "gui" if args.gui else "traci" if args.traci else "libsumo"
    base = CosimConfig(
        scenario=scenario,
        out=args.out,
        step_length_s=args.step_length,
        end_s=args.end,
        interface=interface,
        service_url=args.service,
        seed=args.seed,
        progress=True,
        timeseries=args.timeseries,
        timeseries_every=args.timeseries_every,
        systems=tuple(args.systems),
    )
    runs = (
        [base]
        if not args.driver_response
        else [
            replace(base, out=args.out / "without_response"),
            replace(base, out=args.out / "with_response", driver=DriverSettings()),
        ]
    )
    summaries = []
    try:
        for config in runs:
            summaries.append(cosimulate(config))
            _print_summary(summaries[-1], config.out)
    except SumoStopped as exc:
        print(f"csws: error: SUMO stopped ({exc}); the files in {args.out} hold every step before", file=sys.stderr)
        return 1
    except ServiceError as exc:
        print(f"csws: error: {exc}; the files in {args.out} hold every step before", file=sys.stderr)
        return 1
    if args.driver_response:
        comparison = _comparison(*summaries)
        write_summary(
            args.out / "summary.json",
            {"format": "csws-cosim-comparison/1", "comparison": comparison, "runs": summaries},
        )
        print(f"comparison in {args.out / 'summary.json'}")
    write_run_summary(
        {"with driver response" if c.driver else "without driver response": c.out for c in runs}, args.out
    )
    print(f"summary plot in {args.out / 'summary.png'}, figures in {args.out / 'summary.md'}")
    return 0
