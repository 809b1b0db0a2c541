"""What a co-simulation writes: per-vehicle time series, warning events, curve entries, summary.

The CSV files are streamed: each step's rows are appended with one ``write`` of whole
lines, so a run that is interrupted or whose SUMO dies leaves files that parse and end
at a complete row. Numbers are written with Python's ``repr`` (no rounding), so two runs
can be compared exactly.

* the time series, every evaluated vehicle at every recorded step, in Parquet or CSV
  (:mod:`csws.cosim.timeseries`);
* ``warnings.csv``: every change of a vehicle's warning level (onset, change, end);
* ``entries.csv``: every entry into a curve part at or above the level-1 warning speed;
* ``summary.json`` (see :class:`Summary`).

On a geo-referenced network every file with ``x_m`` and ``y_m`` has ``lon`` and ``lat``
(degrees, WGS84) right after them (:func:`with_geo`, :mod:`csws.cosim.geo`); on others it has
no such columns.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import time
from collections import Counter, defaultdict
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from csws.standard import Level, mps_to_kmh, warning_speed

from .geo import NetworkLocation
from .sumo import FleetState

__all__ = [
    "TIMESERIES_COLUMNS",
    "TIMESERIES_FORMATS",
    "EVENT_COLUMNS",
    "ENTRY_COLUMNS",
    "CsvStream",
    "GEO_COLUMNS",
    "StepValues",
    "StepCosts",
    "Summary",
    "level1_excess_kmh",
    "write_summary",
    "event_of",
    "with_geo",
    "write_whole",
]

#: How a run's time series can be kept (:mod:`csws.cosim.timeseries`).
TIMESERIES_FORMATS = ("parquet", "csv", "none")
TIMESERIES_COLUMNS = (
    "time_s",
    "vehicle_id",
    "category",
    "lane_id",
    "lane_pos_m",
    "x_m",
    "y_m",
    "speed_kmh",
    "state",
    "level",
    "target_curve_id",
    "target_part_index",
    "target_distance_m",
    "target_warning_speed_kmh",
    "commanded_speed_kmh",
)
EVENT_COLUMNS = (
    "time_s",
    "vehicle_id",
    "category",
    "event",
    "level",
    "previous_level",
    "curve_id",
    "part_index",
    "radius_m",
    "distance_m",
    "warning_speed_kmh",
    "speed_kmh",
    "lane_id",
    "lane_pos_m",
    "x_m",
    "y_m",
)
ENTRY_COLUMNS = (
    "time_s",
    "vehicle_id",
    "category",
    "curve_id",
    "part_index",
    "radius_m",
    "speed_kmh",
    "level1_warning_speed_kmh",
    "excess_kmh",
    "level",
    "lane_id",
    "lane_pos_m",
    "x_m",
    "y_m",
)
#: The columns a geo-referenced network adds right after ``y_m``: longitude and latitude, degrees (WGS84).
GEO_COLUMNS = ("lon", "lat")


def with_geo(columns: Sequence[str], geo: bool) -> tuple[str, ...]:
    """``columns`` with :data:`GEO_COLUMNS` right after ``y_m`` when ``geo`` (a geo-referenced network)."""
    columns = tuple(columns)
    if not geo:
        return columns
    after = columns.index("y_m") + 1
    return columns[:after] + GEO_COLUMNS + columns[after:]


@dataclass(frozen=True)
class StepValues:
    """One step's per-vehicle values that the rows of its files repeat, as plain lists.

    Attributes
    ----------
    fleet
        The step as SUMO gave it.
    speeds_kmh, lane_pos_m, x_m, y_m
        Per vehicle, in the fleet's order (x and y are NaN where the step was read without them).
    position
        A vehicle's x and y from SUMO, m, where the step was read without them; None otherwise.
    geo
        The network's geo-reference, None when it has none.
    lon, lat
        Per vehicle, degrees, with ``geo`` (None where x and y were not read); empty without.
    """

    fleet: FleetState
    speeds_kmh: list[float]
    lane_pos_m: list[float]
    x_m: list[float]
    y_m: list[float]
    position: Callable[[str], tuple[float, float]] | None = None
    geo: NetworkLocation | None = None
    lon: list[float | None] = field(default_factory=list)
    lat: list[float | None] = field(default_factory=list)

    @classmethod
    def of(
        cls,
        fleet: FleetState,
        position: Callable[[str], tuple[float, float]] | None = None,
        geo: NetworkLocation | None = None,
    ) -> StepValues:
        """The values of ``fleet`` as lists (one conversion per column and step), lon/lat too with ``geo``."""
        speeds_kmh = mps_to_kmh(fleet.speed_mps).tolist()
        lon, lat = geo.lonlat(fleet.x_m, fleet.y_m) if geo is not None else ([], [])
        x_m, y_m = fleet.x_m.tolist(), fleet.y_m.tolist()
        return cls(fleet, speeds_kmh, fleet.lane_pos_m.tolist(), x_m, y_m, position, geo, lon, lat)

    def place(self, row: int) -> tuple[float | None, ...]:
        """Where the vehicle at ``row`` is: x and y, m, and with a geo-reference lon and lat, degrees."""
        x_m, y_m = self.x_m[row], self.y_m[row]
        if self.position is not None and not math.isfinite(x_m):
            x_m, y_m = self.position(self.fleet.vehicle_id[row])
        if self.geo is None:
            return x_m, y_m
        if self.lon[row] is not None:
            return x_m, y_m, self.lon[row], self.lat[row]
        if not (math.isfinite(x_m) and math.isfinite(y_m)):
            return x_m, y_m, None, None
        return (x_m, y_m, *self.geo.xy_to_lonlat(x_m, y_m))

    def event_row(
        self, row: int, event: str, level: int, previous: int, curve: Sequence[Any], extra: Sequence[Any] = ()
    ) -> tuple[Any, ...]:
        """A ``warnings.csv`` row of the vehicle at ``row``: :data:`EVENT_COLUMNS` (with lon and lat given a
        geo-reference) with the ``curve`` columns (curve id to warning speed) given, then ``extra`` columns."""
        fleet = self.fleet
        return (
            fleet.time_s,
            fleet.vehicle_id[row],
            fleet.category[row],
            event,
            level,
            previous,
            *curve,
            self.speeds_kmh[row],
            fleet.lane_id[row],
            self.lane_pos_m[row],
            *self.place(row),
            *extra,
        )


def write_whole(fd: int, text: str) -> None:
    """Append ``text`` to the open file ``fd`` in UTF-8, all of it (``os.write`` may write part)."""
    data = text.encode("utf-8")
    while data:
        written = os.write(fd, data)
        data = data[written:]


class CsvStream:
    """A CSV file appended one block of whole rows at a time (one ``os.write`` per block).

    Rows go through the C :mod:`csv` writer: None is an empty cell, floats are written
    with ``repr`` and cells holding a comma, a quote or a line break are quoted.
    """

    def __init__(self, path: Path, columns: Sequence[str]) -> None:
        self.path = path
        self.columns = tuple(columns)
        self._buffer = io.StringIO()
        self._writer = csv.writer(self._buffer, lineterminator="\n")
        self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        self.append([self.columns])

    def append(self, rows: Iterable[Sequence[Any]]) -> None:
        """Append rows (each a sequence in column order)."""
        self._writer.writerows(rows)
        write_whole(self._fd, self._buffer.getvalue())
        self._buffer.seek(0)
        self._buffer.truncate()

    def close(self) -> None:
        """Close the file."""
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1


@dataclass
class StepCosts:
    """Where a run's wall time goes, summed per component over its steps, s."""

    seconds: defaultdict[str, float] = field(default_factory=lambda: defaultdict(float))

    @contextmanager
    def timed(self, component: str) -> Iterator[None]:
        """Add the time spent in the ``with`` block to ``component``."""
        started = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[component] += time.perf_counter() - started

    def ms_per_step(self, steps: int) -> dict[str, float]:
        """Each component's mean milliseconds per step."""
        return {component: round(1000.0 * total / max(steps, 1), 3) for component, total in self.seconds.items()}


@dataclass
class Summary:
    """Counts kept while the run goes: warnings by level, category and curve; warnings that
    flickered; curve entries above V_w.

    A warning of level L is counted when a vehicle's level rises to L. A warning flickered
    when it comes on again within ``flicker_window_s`` of going off for the same curve (the
    curve of its last onset or change); one that comes on that soon for another curve is
    counted apart: a new curve that needs a lower speed, not a flicker. A curve entry is the
    first step at which a vehicle is inside a curve part at or above the part's level-1 warning
    speed (Table 1 at the part's radius): a triggering CPOI at distance 0 whose level 6.1
    requires, not one the release rule keeps on below V_w. ``entries_above_level1`` counts
    every such entry; ``entries_above_level1_margin`` those more than ``margin_kmh`` above
    the level-1 warning speed.
    """

    margin_kmh: float = 1.0
    flicker_window_s: float = 2.0
    onsets: Counter[int] = field(default_factory=Counter)
    flickers: Counter[str] = field(default_factory=Counter)
    next_curve_soon: Counter[str] = field(default_factory=Counter)
    onsets_by_category: defaultdict[str, Counter[int]] = field(default_factory=lambda: defaultdict(Counter))
    onsets_by_curve: defaultdict[str, Counter[int]] = field(default_factory=lambda: defaultdict(Counter))
    entries_above_level1: Counter[str] = field(default_factory=Counter)
    entries_above_level1_margin: Counter[str] = field(default_factory=Counter)
    max_excess_kmh: float = 0.0
    vehicles: set[str] = field(default_factory=set)
    warned_vehicles: set[str] = field(default_factory=set)
    skipped: Counter[str] = field(default_factory=Counter)
    steps: int = 0
    last_time_s: float = 0.0
    fcw_onsets: Counter[int] | None = None
    fcw_warned_vehicles: set[str] = field(default_factory=set)

    def add_onset(self, category: str, level: int, curve_id: str | None) -> None:
        """A vehicle's level rose to ``level``."""
        self.onsets[level] += 1
        self.onsets_by_category[category][level] += 1
        if curve_id is not None:
            self.onsets_by_curve[curve_id][level] += 1

    def add_soon_again(self, category: str, same_curve: bool) -> None:
        """A vehicle's warning came on again within :attr:`flicker_window_s` of going off,
        for the same curve (a flicker) or for another."""
        (self.flickers if same_curve else self.next_curve_soon)[category] += 1

    def add_entry(self, category: str, excess_kmh: float) -> None:
        """A vehicle entered a curve part ``excess_kmh`` above its level-1 warning speed."""
        self.entries_above_level1[category] += 1
        if excess_kmh > self.margin_kmh:
            self.entries_above_level1_margin[category] += 1
        self.max_excess_kmh = max(self.max_excess_kmh, excess_kmh)

    def add_fcw_onset(self, vehicle_id: str, level: int) -> None:
        """A vehicle's forward collision warning rose to ``level`` (with ``fcw_onsets`` set: FCW is on)."""
        if self.fcw_onsets is None:
            raise ValueError("this summary counts no forward collision warnings (fcw_onsets is None)")
        self.fcw_onsets[level] += 1
        self.fcw_warned_vehicles.add(vehicle_id)

    def as_dict(self) -> dict[str, Any]:
        """The summary as JSON-ready data; ``fcw`` only when the forward collision warning was on."""
        by_level = lambda counter: {f"level{level}": counter.get(level, 0) for level in (1, 2)}  # noqa: E731
        fcw = (
            {}
            if self.fcw_onsets is None
            else {"fcw": {"by_level": by_level(self.fcw_onsets), "vehicles_warned": len(self.fcw_warned_vehicles)}}
        )
        return {
            "steps": self.steps,
            "simulated_until_s": self.last_time_s,
            "vehicles_evaluated": len(self.vehicles),
            "vehicles_warned": len(self.warned_vehicles),
            "vehicles_not_evaluated_by_class": dict(self.skipped),
            "warnings": {
                "by_level": by_level(self.onsets),
                "by_category": {c: by_level(n) for c, n in sorted(self.onsets_by_category.items())},
                "by_curve": {c: by_level(n) for c, n in sorted(self.onsets_by_curve.items())},
                "flickered": sum(self.flickers.values()),
                "flickered_by_category": dict(sorted(self.flickers.items())),
                "on_again_for_another_curve": sum(self.next_curve_soon.values()),
                "flicker_window_s": self.flicker_window_s,
            },
            "curve_entries_above_level1_warning_speed": {
                "total": sum(self.entries_above_level1.values()),
                "by_category": dict(sorted(self.entries_above_level1.items())),
                f"more_than_{self.margin_kmh:g}_kmh_above": sum(self.entries_above_level1_margin.values()),
                "max_excess_kmh": self.max_excess_kmh,
            },
            **fcw,
        }


def level1_excess_kmh(speed_kmh: float, category: str, radius_m: float) -> tuple[float, float]:
    """Level-1 warning speed of a curve part (Table 1) and how far ``speed_kmh`` is above it."""
    level1_kmh = warning_speed(radius_m, category, Level.LEVEL_1)
    return level1_kmh, speed_kmh - level1_kmh


def write_summary(path: Path, content: dict[str, Any]) -> None:
    """Write ``summary.json`` (replaced whole, so it is never half written)."""
    partial = path.with_suffix(".json.partial")
    partial.write_text(json.dumps(content, indent=1) + "\n", encoding="utf-8")
    os.replace(partial, path)


def event_of(previous_level: int, level: int) -> str | None:
    """The event a level change is: ``onset``, ``change`` or ``end``; None without a change."""
    if level == previous_level:
        return None
    if previous_level == 0:
        return "onset"
    return "end" if level == 0 else "change"
