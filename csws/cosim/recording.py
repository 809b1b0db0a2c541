"""Recording a co-simulation step by step: the time series, the warning events and the curve entries.

Every vehicle gets a time-series row when the step is sampled, given column-wise; only the
warned vehicles (and those whose level changed) are looked at one by one. With the forward
collision warning, its columns and events go beside the curve warning's.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from csws.standard import mps_to_kmh

from .evaluators import FleetWarnings
from .fcd import FcdWriter
from .fcw import FCW_EVENT_COLUMNS, FcwColumns, fcw_events
from .geo import NetworkLocation
from .records import (
    ENTRY_COLUMNS,
    EVENT_COLUMNS,
    CsvStream,
    StepValues,
    Summary,
    event_of,
    level1_excess_kmh,
    with_geo,
)
from .sumo import FleetState
from .timeseries import TimeseriesWriter, open_timeseries

__all__ = ["Streams", "Tracker", "record_step"]


@dataclass
class Streams:
    """The run's output files."""

    timeseries: TimeseriesWriter
    warnings: CsvStream
    entries: CsvStream
    fcd: FcdWriter | None = None

    @classmethod
    def open(
        cls,
        out: Path,
        timeseries_format: str,
        fcw: bool,
        geo: bool = False,
        fcd: tuple[Path, float] | None = None,
    ) -> Streams:
        """Create the files in ``out``, with the FCW columns when ``fcw`` and lon/lat when ``geo``; and
        the FCD export when ``fcd`` gives its file and SUMO's step length, s."""
        return cls(
            open_timeseries(out, timeseries_format, fcw, geo),
            CsvStream(out / "warnings.csv", with_geo(EVENT_COLUMNS, geo) + (FCW_EVENT_COLUMNS if fcw else ())),
            CsvStream(out / "entries.csv", with_geo(ENTRY_COLUMNS, geo)),
            None if fcd is None else FcdWriter(*fcd),
        )

    def close(self) -> None:
        """Close every file."""
        for stream in (self.timeseries, self.warnings, self.entries, self.fcd):
            if stream is not None:
                stream.close()


@dataclass
class Tracker:
    """What the run remembers per vehicle between steps: last level, the curve of its last
    onset or change, when its warning last went off, curve parts entered."""

    levels: dict[str, int] = field(default_factory=dict)
    curves: dict[str, str | None] = field(default_factory=dict)
    ended_s: dict[str, float] = field(default_factory=dict)
    entered: dict[str, set[tuple[str, int]]] = field(default_factory=dict)
    fcw_levels: dict[str, int] = field(default_factory=dict)

    def forget(self, vehicle_id: str) -> None:
        """Drop a vehicle that left."""
        self.levels.pop(vehicle_id, None)
        self.fcw_levels.pop(vehicle_id, None)
        self.curves.pop(vehicle_id, None)
        self.ended_s.pop(vehicle_id, None)
        self.entered.pop(vehicle_id, None)


def record_step(
    fleet: FleetState,
    warnings: FleetWarnings,
    fcw: FcwColumns | None,
    commands: dict[str, float],
    tracker: Tracker,
    summary: Summary,
    streams: Streams,
    sampled: bool,
    position: Callable[[str], tuple[float, float]] | None = None,
    geo: NetworkLocation | None = None,
) -> None:
    """Append one step to the files and the summary.

    The time series (and the FCD export) gets the step when it is ``sampled``; ``warnings.csv`` its level changes
    (with the forward collision warning's, given ``fcw``); ``entries.csv`` its first entries into
    curve parts. ``position`` gives a vehicle's x, y where the step was read without them (an
    event's row needs them); ``geo`` adds lon and lat to every row (the files must have been
    opened with them).
    """
    step = StepValues.of(fleet, position, geo)
    if sampled:
        streams.timeseries.append(_timeseries_columns(step, warnings, fcw, commands))
        if streams.fcd is not None:
            streams.fcd.append(step, warnings, None if fcw is None else fcw.level)
    events = _warning_events(step, warnings, tracker, summary, pad=len(FCW_EVENT_COLUMNS) if fcw else 0)
    entries = _curve_entries(step, warnings, tracker, summary)
    if fcw:
        events += fcw_events(fcw, tracker.fcw_levels, summary, step)
    streams.warnings.append(events)
    streams.entries.append(entries)


def _timeseries_columns(
    step: StepValues, warnings: FleetWarnings, fcw: FcwColumns | None, commands: dict[str, float]
) -> tuple[Sequence[Any], ...]:
    """The step's time-series columns, every vehicle in the fleet's order."""
    fleet, target = step.fleet, warnings.target
    count = len(fleet.vehicle_id)
    return (
        [fleet.time_s] * count,
        fleet.vehicle_id,
        fleet.category,
        fleet.lane_id,
        step.lane_pos_m,
        step.x_m,
        step.y_m,
        *((step.lon, step.lat) if step.geo is not None else ()),
        step.speeds_kmh,
        warnings.state,
        warnings.level,
        target.curve_id,
        target.part_index,
        target.distance_m,
        target.warning_speed_kmh,
        _commanded_kmh(fleet, commands),
        *(fcw.columns() if fcw else ()),
    )


def _commanded_kmh(fleet: FleetState, commands: dict[str, float]) -> list[float | None]:
    """The speed commanded to each vehicle this step, km/h; None where SUMO drives it."""
    commanded_kmh: list[float | None] = [None] * len(fleet.vehicle_id)
    if commands:
        row_of = {vehicle_id: i for i, vehicle_id in enumerate(fleet.vehicle_id)}
        for vehicle_id, command in commands.items():
            commanded_kmh[row_of[vehicle_id]] = None if command < 0 else mps_to_kmh(command)
    return commanded_kmh


def _warning_events(
    step: StepValues, warnings: FleetWarnings, tracker: Tracker, summary: Summary, pad: int
) -> list[tuple[Any, ...]]:
    """The ``warnings.csv`` rows of the step's curve-warning level changes, counted in ``summary``;
    ``pad`` empty FCW columns end each row."""
    fleet, target, levels = step.fleet, warnings.target, tracker.levels
    events = []
    for i, (vehicle_id, level) in enumerate(zip(fleet.vehicle_id, warnings.level, strict=False)):
        previous = levels.get(vehicle_id, 0)
        event = event_of(previous, level)
        if event is None:
            continue
        levels[vehicle_id] = level
        _count_change(fleet, i, event, level, previous, target.curve_id[i], tracker, summary)
        curve = (
            target.curve_id[i],
            target.part_index[i],
            target.radius_m[i],
            target.distance_m[i],
            target.warning_speed_kmh[i],
        )
        events.append(step.event_row(i, event, level, previous, curve, (None,) * pad))
    return events


def _count_change(
    fleet: FleetState,
    row: int,
    event: str,
    level: int,
    previous: int,
    curve_id: str | None,
    tracker: Tracker,
    summary: Summary,
) -> None:
    """Count one level change: onsets by level, warnings that came on again soon (a flicker when for
    the same curve), and remember when it went off and for which curve it was last on."""
    vehicle_id, category, time_s = fleet.vehicle_id[row], fleet.category[row], fleet.time_s
    if event == "end":
        tracker.ended_s[vehicle_id] = time_s
    else:
        if event == "onset" and time_s - tracker.ended_s.get(vehicle_id, -math.inf) <= summary.flicker_window_s:
            summary.add_soon_again(category, tracker.curves.get(vehicle_id) == curve_id)
        tracker.curves[vehicle_id] = curve_id
    if level > previous:
        summary.add_onset(category, level, curve_id)
        summary.warned_vehicles.add(vehicle_id)


def _curve_entries(
    step: StepValues, warnings: FleetWarnings, tracker: Tracker, summary: Summary
) -> list[tuple[Any, ...]]:
    """The ``entries.csv`` rows of the curve parts vehicles are inside for the first time at or above the
    part's level-1 warning speed (Table 1), counted in ``summary``.

    A vehicle inside a part at or above V_w always triggers it (6.1: S = 0 <= S_w), so every such
    entry is among ``warnings.entries``; the triggers there below V_w are levels the release rule
    keeps on (:mod:`csws.warning.release`: the margin lets a level stay on down to 1 km/h below V_w,
    the hold for 1 s), and are no entries: that vehicle went in at a speed the standard accepts.
    """
    fleet = step.fleet
    entries = []
    for i, curve_id, part_index, radius_m, level in warnings.entries:
        vehicle_id, category = fleet.vehicle_id[i], fleet.category[i]
        entered = tracker.entered.setdefault(vehicle_id, set())
        if (curve_id, part_index) in entered:
            continue
        speed_kmh = step.speeds_kmh[i]
        level1_kmh, excess_kmh = level1_excess_kmh(speed_kmh, category, radius_m)
        if excess_kmh < 0.0:
            continue
        entered.add((curve_id, part_index))
        summary.add_entry(category, excess_kmh)
        entries.append(
            (
                fleet.time_s,
                vehicle_id,
                category,
                curve_id,
                part_index,
                radius_m,
                speed_kmh,
                level1_kmh,
                excess_kmh,
                level,
                fleet.lane_id[i],
                step.lane_pos_m[i],
                *step.place(i),
            )
        )
    return entries
