"""``csws cosim``: drive a fleet through SUMO and record who was warned where.

Every step, the vehicles of a covered class that are due are evaluated at once (the library's
``evaluate_fleet`` and the FCW's fleet update, or one HTTP batch to a service: every vehicle at
every step, or with ``--evaluate scheduled`` in this process only from where a curve warning can
arise or another vehicle can come within the FCW's range, :mod:`csws.cosim.scheduling`), their
states and warnings are appended to the time series at the steps it keeps, level changes to the
warning events and curve entries above the warning speed to the entries
(:mod:`csws.cosim.recording`); the summary is rewritten at the end, also when the run is
interrupted or SUMO dies (then marked incomplete, with the reason).
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
import time
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import Any

from csws.cli.progress import Progress
from csws.fcw.settings import FcwSettings
from csws.standard import Category

from .cli import SYSTEMS
from .config import CosimConfig, Scenario, bundled_scenario, default_timeseries_every, scenario_from_args
from .driver import DriverResponse, DriverSettings
from .evaluators import Evaluator, FleetWarnings, LibraryEvaluator, ServiceError, ServiceEvaluator
from .fcw import FcwColumns, FleetFcw, respond_to_fcw
from .fcw_schedule import FcwSchedule, network_spread
from .geo import network_location
from .lanes_beside import LanesBeside
from .recording import Streams, Tracker, record_step
from .records import StepCosts, Summary, write_summary
from .schedule import WakeSchedule
from .scheduling import RunSchedule
from .summary import write_run_summary
from .sumo import FleetState, Simulation, SumoStopped, sumo_arguments

__all__ = ["SYSTEMS", "CosimConfig", "Scenario", "bundled_scenario", "scenario_from_args", "cosimulate", "main"]


def _evaluator(config: CosimConfig) -> Evaluator | None:
    """The library or the service, or None for a baseline run or one without the curve warning."""
    if not config.evaluate or "csws" not in config.systems:
        return None
    if config.service_url is not None:
        return ServiceEvaluator(config.service_url, api_key=config.service_api_key)
    from csws.engine import Engine, EngineSettings
    from csws.road.roadmap import RoadMap
    from csws.warning.rules import WarningSettings

    road_map = RoadMap.load(config.scenario.net)
    return LibraryEvaluator(
        Engine(road_map, EngineSettings(warning=WarningSettings(update_period_s=config.step_length_s)))
    )


def _drive(driver: DriverResponse, fleet: FleetState, warnings: FleetWarnings, step_s: float) -> dict[str, float]:
    """The driver-response model's speed commands of this step, per vehicle (m/s; -1 hands back)."""
    commands: dict[str, float] = {}
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


class _Run:
    """One co-simulation's parts from step to step: who answers, the drivers, the files and the counts.

    Parameters
    ----------
    config
        How to run; its output folder must exist.
    """

    def __init__(self, config: CosimConfig) -> None:
        self.config = config
        self.evaluator = _evaluator(config)
        self.summary = Summary(fcw_onsets=Counter() if config.fcw else None)
        self.tracker = Tracker()
        self.driver = DriverResponse(config.driver) if config.driver is not None else None
        self.geo = network_location(config.scenario.net)
        fcd = None if config.fcd is None else (config.fcd, config.step_length_s)
        self.streams = Streams.open(config.out, config.timeseries, config.fcw, geo=self.geo is not None, fcd=fcd)
        self.costs = StepCosts()
        self.simulation: Simulation | None = None
        self.forward: FleetFcw | None = None
        self.schedule: RunSchedule | None = None
        #: Vehicle-steps there were, and those with a curve warning on: a schedule evaluates the latter every step.
        self.vehicle_steps = self.warned_steps = 0
        self.step_s = config.step_length_s  # SUMO's own, read once when it starts
        self.bar = Progress("cosim", config.end_s, "sim s", decimals=1, enabled=config.progress)

    def start(self) -> Simulation:
        """Start SUMO (and the forward collision warning's reading of it)."""
        config, scenario = self.config, self.config.scenario
        sumo_args = sumo_arguments(
            scenario.config,
            scenario.net if scenario.config is None else None,
            scenario.routes,
            config.step_length_s,
            config.seed,
            config.end_s,
        )
        simulation = self.simulation = Simulation(
            sumo_args,
            config.interface,
            odometer=self.driver is not None,
            headings=config.fcd is not None,
            speed_bounds=config.scheduled,
        )
        forward = self.forward = FleetFcw(simulation.api) if config.fcw else None
        self.step_s = simulation.step_length_s
        if config.scheduled:
            curve = None
            if isinstance(self.evaluator, LibraryEvaluator):
                engine = self.evaluator.engine
                beside = LanesBeside(engine.lookahead) if engine.lookahead is not None else None
                curve = (WakeSchedule(self.step_s, engine.settings.warning, beside), self.evaluator)
            fcw = None
            if forward is not None:
                range_m = max(FcwSettings.for_category(category).range_m for category in Category)
                fcw_schedule = FcwSchedule(self.step_s, range_m, *network_spread(simulation.api.lane))
                fcw = (fcw_schedule, forward, simulation.fastest_lane_mps)
            self.schedule = RunSchedule(curve, fcw)
        return simulation

    def step(self, simulation: Simulation) -> bool:
        """Advance SUMO one step, evaluate, command and record it; False once ``end_s`` is reached."""
        config, costs = self.config, self.costs
        sampled = self.summary.steps % config.timeseries_every == 0
        # Without a time-series row (or FCD timestep) this step, x and y are read only for the vehicles with an event.
        positions = sampled and (config.timeseries != "none" or config.fcd is not None)
        schedule, step = self.schedule, self.summary.steps
        if schedule is not None:
            with costs.timed("schedule"):
                schedule.wake_due(step, everyone=positions)
        with costs.timed("sumo_step_and_read"):
            if schedule is None:
                fleet = simulation.step(positions)
            else:
                appearing = schedule.appearing if schedule.fcw else None
                fleet = simulation.step(positions, schedule.asleep, schedule.teleporting, appearing)
        self._forget(fleet.arrived)
        self.summary.skipped.update(fleet.skipped)
        if schedule is not None:
            with costs.timed("schedule"):
                schedule.read(fleet, simulation.departed_speed_bounds, simulation.vehicle_count)
        warnings, fcw = self._evaluate(fleet)
        commands = self._commands(fleet, warnings, fcw, self.step_s)
        for vehicle_id, speed_mps in commands.items():
            simulation.set_speed(vehicle_id, speed_mps)
        with costs.timed("recording"):
            position = None if positions or simulation.reads_positions else simulation.position
            record_step(
                fleet, warnings, fcw, commands, self.tracker, self.summary, self.streams, sampled, position, self.geo
            )
        if schedule is not None:
            with costs.timed("schedule"):
                schedule.sleep(fleet, warnings, fcw, self.driver)
        self.summary.vehicles.update(fleet.vehicle_id)
        self.vehicle_steps += simulation.vehicle_count
        self.warned_steps += len(warnings.level) - warnings.level.count(0)
        self.summary.steps += 1
        self.summary.last_time_s = fleet.time_s
        self.bar.update(self.step_s)
        return config.end_s is None or fleet.time_s < config.end_s

    def _forget(self, arrived: tuple[str, ...]) -> None:
        """Drop the vehicles that left from everything that remembers them."""
        for vehicle_id in arrived:
            self.tracker.forget(vehicle_id)
            if self.driver is not None:
                self.driver.forget(vehicle_id)
        for forgetting in (self.evaluator, self.forward, self.schedule):
            if forgetting is not None:
                forgetting.forget(arrived)

    def _evaluate(self, fleet: FleetState) -> tuple[FleetWarnings, FcwColumns | None]:
        """The step's curve warnings (none when not evaluated) and forward collision warnings (None when off)."""
        with self.costs.timed("evaluation"):
            if self.evaluator is not None and fleet.vehicle_id:
                warnings = self.evaluator(fleet)
            else:
                warnings = FleetWarnings.none(len(fleet.vehicle_id))
        fcw = None
        if self.forward is not None:
            with self.costs.timed("fcw"):
                # The curve warning's path ahead of each vehicle, where it computed one, assigns the objects' lanes.
                paths = getattr(self.evaluator, "paths_ahead", None) if fleet.vehicle_id else None
                asleep = self.schedule.fcw[0].wake_step if self.schedule and self.schedule.fcw else ()
                on_lane = [bool(lane) for lane in fleet.lane_id]
                fcw = self.forward(fleet.vehicle_id, fleet.category, on_lane, paths, asleep)
        return warnings, fcw

    def _commands(
        self, fleet: FleetState, warnings: FleetWarnings, fcw: FcwColumns | None, step_s: float
    ) -> dict[str, float]:
        """The driver-response model's speed commands of the step (none without the model)."""
        if self.driver is None:
            return {}
        commands = _drive(self.driver, fleet, warnings, step_s)
        if fcw is not None:
            respond_to_fcw(self.driver, fleet, fcw, step_s, commands)
        return commands

    def close(self) -> None:
        """Close the progress line, the files, SUMO and the evaluator."""
        self.bar.close()
        self.streams.close()
        if self.simulation is not None:
            self.simulation.close()
        if self.evaluator is not None:
            self.evaluator.close()


@contextmanager
def _interrupt_between_steps() -> Iterator[list[bool]]:
    """Hold a first Ctrl-C until the step under way is recorded; a second one stops at once.

    The yielded flag turns true on the first SIGINT; the loop raises ``KeyboardInterrupt``
    after the step, so the summary, the time series and the FCD export end at the same step.
    Off the main thread (where signals cannot be caught) Ctrl-C keeps its default meaning.
    """
    requested = [False]
    if threading.current_thread() is not threading.main_thread():
        yield requested
        return

    def hold(signum: int, frame: object) -> None:
        if requested[0]:
            raise KeyboardInterrupt
        requested[0] = True

    previous = signal.signal(signal.SIGINT, hold)
    try:
        yield requested
    finally:
        signal.signal(signal.SIGINT, previous)


def cosimulate(config: CosimConfig) -> dict[str, Any]:
    """Run one co-simulation into ``config.out``; its summary (also written to ``summary.json``).

    Raises
    ------
    SumoStopped
        When SUMO dies; the files hold everything up to the last complete step.
    KeyboardInterrupt
        When interrupted; likewise.
    """
    config.out.mkdir(parents=True, exist_ok=True)
    (config.out / "summary.json").unlink(missing_ok=True)  # a run that stops early must not leave an older one's
    run = _Run(config)
    status, started = "running", time.perf_counter()
    try:
        with _interrupt_between_steps() as interrupted:
            simulation = run.start()
            while simulation.expected_vehicles() > 0 and run.step(simulation):
                if interrupted[0]:
                    raise KeyboardInterrupt
            if interrupted[0]:
                raise KeyboardInterrupt
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
        run.close()
        content = _summary_content(config, run, status, time.perf_counter() - started)
        write_summary(config.out / "summary.json", content)
    return content


def _summary_content(config: CosimConfig, run: _Run, status: str, wall_s: float) -> dict[str, Any]:
    """The summary of one run with how it was run and where its time went."""
    scenario, summary = config.scenario, run.summary
    return {
        "format": "csws-cosim-summary/1",
        "status": status,
        "complete": status == "complete",
        "scenario": {
            "config": None if scenario.config is None else str(scenario.config),
            "net": str(scenario.net),
            "routes": [str(r) for r in scenario.routes],
            "geo_referenced": run.geo is not None,
        },
        "mode": "service" if config.service_url else "library" if config.evaluate else "baseline (no evaluation)",
        "service_url": config.service_url,
        "systems": list(config.systems),
        "interface": config.interface,
        "step_length_s": config.step_length_s,
        "driver_response": None if config.driver is None else vars(config.driver),
        "timeseries": {"format": config.timeseries, "every_steps": config.timeseries_every},
        "fcd": None if config.fcd is None else str(config.fcd),
        "evaluation": {
            "mode": "scheduled" if run.schedule is not None else "every step",
            "vehicle_steps_evaluated_share": None if run.schedule is None else run.schedule.evaluated_share(),
            "vehicle_steps_warned_share": run.warned_steps / run.vehicle_steps if run.vehicle_steps else None,
        },
        "wall_time_s": round(wall_s, 3),
        "ms_per_step": run.costs.ms_per_step(summary.steps),
        **summary.as_dict(),
    }


def _comparison(without: dict[str, Any], with_response: dict[str, Any]) -> dict[str, Any]:
    """How the fleet did with the driver-response model against without it."""

    def figures(summary: dict[str, Any]) -> dict[str, Any]:
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


def _print_summary(summary: dict[str, Any], out: Path) -> None:
    """A few lines on the terminal."""
    warnings = summary["warnings"]["by_level"]
    entries = summary["curve_entries_above_level1_warning_speed"]
    print(
        f"{summary['vehicles_evaluated']} vehicles over {summary['simulated_until_s']:g} s "
        f"({summary['mode']}): {warnings['level1']} level-1 and {warnings['level2']} level-2 warnings "
        f"({summary['warnings']['flickered']} flickered: off and on again for the same curve within "
        f"{summary['warnings']['flicker_window_s']:g} s), "
        f"{entries['total']} curve entries at or above the level-1 warning speed "
        f"({entries['more_than_1_kmh_above']} by more than 1 km/h)"
        + (
            ""
            if "fcw" not in summary
            else f"; forward collision: {summary['fcw']['by_level']['level1']} preliminary and "
            f"{summary['fcw']['by_level']['level2']} collision warnings"
        )
        + f"; output in {out}"
    )


def _runs(base: CosimConfig, driver_response: bool) -> list[CosimConfig]:
    """The run, or for ``--driver-response`` the two runs without and with the driver-response model,
    each in a folder (and with an FCD file) of its own."""
    if not driver_response:
        return [base]
    return [
        replace(base, out=base.out / "without_response", fcd=_per_run(base.fcd, "without_response")),
        replace(base, out=base.out / "with_response", driver=DriverSettings(), fcd=_per_run(base.fcd, "with_response")),
    ]


def _per_run(path: Path | None, run: str) -> Path | None:
    """The file of one run of ``--driver-response`` for a file given once: ``fcd.xml`` -> ``fcd.with_response.xml``."""
    return None if path is None else path.with_name(f"{path.stem}.{run}{path.suffix}")


def _api_key(args: argparse.Namespace) -> str | None:
    """The fleet's API key for ``--service``: ``--api-key-file``'s, else ``CSWS_API_KEY``'s; None without a service."""
    if args.service is None:
        return None
    return args.api_key if args.api_key is not None else os.environ.get("CSWS_API_KEY") or None


def main(args: argparse.Namespace) -> int:
    """The ``csws cosim`` command: 0 when the run completes, 1 (with one line on stderr) when SUMO
    or the service fails."""
    scenario = scenario_from_args(args)
    interface = "gui" if args.gui else "traci" if args.traci else "libsumo"
    base = CosimConfig(
        scenario=scenario,
        out=args.out,
        step_length_s=args.step_length,
        end_s=args.end,
        interface=interface,
        service_url=args.service,
        service_api_key=_api_key(args),
        seed=args.seed,
        progress=True,
        timeseries=args.timeseries,
        timeseries_every=args.timeseries_every or default_timeseries_every(args.step_length),
        systems=tuple(args.systems),
        fcd=args.fcd,
        evaluation=args.evaluate,
    )
    runs = _runs(base, args.driver_response)
    summaries: list[dict[str, Any]] = []
    started: list[CosimConfig] = []
    try:
        for config in runs:
            started.append(config)
            summaries.append(cosimulate(config))
            _print_summary(summaries[-1], config.out)
    except SumoStopped as exc:
        _write_plots(started, args.out)
        print(f"csws: error: SUMO stopped ({exc}); the files in {args.out} hold every step before", file=sys.stderr)
        return 1
    except ServiceError as exc:
        _write_plots(started, args.out)
        print(f"csws: error: {exc}; the files in {args.out} hold every step before", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        _write_plots(started, args.out)
        raise
    if args.driver_response:
        comparison = _comparison(*summaries)
        write_summary(
            args.out / "summary.json",
            {"format": "csws-cosim-comparison/1", "comparison": comparison, "runs": summaries},
        )
        print(f"comparison in {args.out / 'summary.json'}")
    _write_plots(started, args.out)
    return 0


def _write_plots(started: list[CosimConfig], out: Path) -> None:
    """Write ``summary.png`` and ``summary.md`` of the runs started that left their files, also when one
    of them was interrupted or failed (its status is in the table), and say where they are."""
    folders = {
        "with driver response" if c.driver else "without driver response": c.out
        for c in started
        if (c.out / "summary.json").is_file() and (c.out / "entries.csv").is_file()
    }
    if folders:
        write_run_summary(folders, out)
        print(f"summary plot in {out / 'summary.png'}, figures in {out / 'summary.md'}")
