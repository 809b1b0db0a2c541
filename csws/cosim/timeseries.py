"""The time series of a co-simulation: every evaluated vehicle at every recorded step.

``csws cosim --timeseries FORMAT`` chooses how it is kept:

* ``parquet`` (the default): the folder ``timeseries/`` of Parquet files
  ``part-00000.parquet``, ``part-00001.parquet``, ... in the column types of
  :data:`TIMESERIES_SCHEMA`. Rows are gathered in columns and written
  :data:`PART_ROWS` at a time, each part under a temporary name and then renamed, so every
  file in the folder is whole. pyarrow (``pyarrow.parquet.read_table("timeseries")``, installed
  with csws), pandas, polars and DuckDB (``read_parquet('timeseries/*.parquet')``) read the
  folder as one table. On a geo-referenced network ``lon`` and ``lat`` follow ``y_m``. An
  interrupted run, or one whose SUMO died, writes what it has gathered before it ends; a
  run killed outright loses the rows not yet written (at most one part).
* ``csv``: ``timeseries.csv``, appended at every step in whole rows (the same columns,
  numbers written exactly), so a run killed outright leaves every step before the kill.
* ``none``: no time series; the warning events, curve entries and summary are still kept.

``--timeseries-every N`` keeps every N-th step (the first included).

Parquet is written in columns by pyarrow, several times faster than a CSV row writer, and
holds the numbers as numbers (a few times smaller than the CSV text).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Protocol

import pyarrow as pa
import pyarrow.parquet as pq

from .fcw import FCW_TIMESERIES_FIELDS
from .records import GEO_COLUMNS, TIMESERIES_COLUMNS, TIMESERIES_FORMATS, CsvStream

__all__ = [
    "TIMESERIES_FORMATS",
    "TIMESERIES_SCHEMA",
    "PART_ROWS",
    "TimeseriesWriter",
    "timeseries_schema",
    "open_timeseries",
]

#: The Parquet columns: the CSV's, typed. A vehicle without a warning has no target (null).
TIMESERIES_SCHEMA = pa.schema(
    [
        ("time_s", pa.float64()),
        ("vehicle_id", pa.string()),
        ("category", pa.string()),
        ("lane_id", pa.string()),
        ("lane_pos_m", pa.float64()),
        ("x_m", pa.float64()),
        ("y_m", pa.float64()),
        ("speed_kmh", pa.float64()),
        ("state", pa.string()),
        ("level", pa.int8()),
        ("target_curve_id", pa.string()),
        ("target_part_index", pa.int32()),
        ("target_distance_m", pa.float64()),
        ("target_warning_speed_kmh", pa.float64()),
        ("commanded_speed_kmh", pa.float64()),
    ]
)

#: Rows of one Parquet part: about 70 s of a 1,000-vehicle fleet at 0.1 s steps, some 20 MB
#: of memory while gathered.
PART_ROWS = 500_000

assert tuple(TIMESERIES_SCHEMA.names) == TIMESERIES_COLUMNS


class TimeseriesWriter(Protocol):
    """Takes the time-series rows of one step at a time, as columns in :data:`TIMESERIES_COLUMNS` order."""

    def append(self, columns: Sequence[Sequence]) -> None: ...

    def close(self) -> None: ...


def timeseries_schema(fcw: bool = False, geo: bool = False) -> pa.Schema:
    """The time series' columns: :data:`TIMESERIES_SCHEMA`, on a geo-referenced network with ``lon`` and
    ``lat`` (degrees, null where x and y were not read) after ``y_m``, and with the forward collision
    warning its columns at the end (:data:`csws.cosim.fcw.FCW_TIMESERIES_FIELDS`)."""
    fields = list(TIMESERIES_SCHEMA)
    if geo:
        after = TIMESERIES_SCHEMA.get_field_index("y_m") + 1
        fields[after:after] = [pa.field(name, pa.float64()) for name in GEO_COLUMNS]
    if fcw:
        fields += [pa.field(name, pa.type_for_alias(kind)) for name, kind in FCW_TIMESERIES_FIELDS]
    return pa.schema(fields)


class _ParquetParts:
    """The time series as a folder of whole Parquet parts (see the module's description)."""

    def __init__(self, folder: Path, schema: pa.Schema) -> None:
        folder.mkdir(parents=True, exist_ok=True)
        for stale in folder.glob("part-*.parquet"):
            stale.unlink()
        self.folder = folder
        self.schema = schema
        self._columns: list[list] = [[] for _ in schema]
        self._rows = 0
        self._parts = 0

    def append(self, columns: Sequence[Sequence]) -> None:
        for gathered, values in zip(self._columns, columns, strict=False):
            gathered.extend(values)
        self._rows += len(columns[0])
        if self._rows >= PART_ROWS:
            self._write_part()

    def close(self) -> None:
        if self._rows or not self._parts:
            self._write_part()  # an empty run still leaves one (empty) part with the schema

    def _write_part(self) -> None:
        table = pa.table(
            [pa.array(values, type=field.type) for values, field in zip(self._columns, self.schema, strict=False)],
            schema=self.schema,
        )
        path = self.folder / f"part-{self._parts:05d}.parquet"
        partial = path.with_suffix(".parquet.partial")
        pq.write_table(table, partial)
        os.replace(partial, path)
        self._parts += 1
        self._columns = [[] for _ in self.schema]
        self._rows = 0


class _CsvTimeseries:
    """The time series as ``timeseries.csv``, appended at every step."""

    def __init__(self, path: Path, columns: Sequence[str]) -> None:
        self._stream = CsvStream(path, columns)

    def append(self, columns: Sequence[Sequence]) -> None:
        self._stream.append(zip(*columns, strict=False))

    def close(self) -> None:
        self._stream.close()


class _NoTimeseries:
    """No time series."""

    def append(self, columns: Sequence[Sequence]) -> None:
        pass

    def close(self) -> None:
        pass


def open_timeseries(out: Path, timeseries_format: str, fcw: bool = False, geo: bool = False) -> TimeseriesWriter:
    """The writer of a run's time series in ``out`` in one of :data:`TIMESERIES_FORMATS`, with the
    forward collision warning's columns when ``fcw`` and lon/lat when ``geo`` (:func:`timeseries_schema`)."""
    schema = timeseries_schema(fcw, geo)
    if timeseries_format == "parquet":
        return _ParquetParts(out / "timeseries", schema)
    if timeseries_format == "csv":
        return _CsvTimeseries(out / "timeseries.csv", schema.names)
    if timeseries_format == "none":
        return _NoTimeseries()
    raise ValueError(
        f"unknown time-series format {timeseries_format!r}; expected one of {', '.join(TIMESERIES_FORMATS)}"
    )
