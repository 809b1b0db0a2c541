"""The rows of the test procedure (7.5): which track, which speed, which warnings are due where.

Every row comes from the standard's tables as transcribed (``csws.data.standard_tables``)
and from the bundled test tracks' index (``networks/index.json``):

* Table 5 (7.5.2.1) and Table 6 (7.5.2.2): a single curve, one test speed, one warning
  level due at S_w before the curve;
* Table 7 (7.5.3.1): curve 1 first; the vehicle brakes at 4.9 m/s^2 to the curve-2 speed
  once it is within curve 1's level-2 S_w; four warnings due;
* Tables 8 (7.5.3.2) and 9 (7.5.3.3): curve 2 warned first, two or four warnings due;
* our own negative rows: 3 km/h below each warning speed of a single curve, no warning of
  that level at all.

Rows of the merged column "M3, N, O" are run once per category (M3, N and O). Each row is
run on every track that implements it (left and right turning, and the one S-curve).
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from dataclasses import dataclass
from functools import cache

from csws.data import standard_tables
from csws.networks import networks_dir
from csws.standard import Category, Column, Level, warning_speed

__all__ = [
    "NEGATIVE_MARGIN_KMH",
    "Check",
    "Row",
    "procedure_rows",
    "track_names",
]

#: The negative rows drive this far below a warning speed (km/h): no warning of that level is due.
NEGATIVE_MARGIN_KMH = 3.0
#: Deceleration of Table 7's test (7.5.3.1.1), m/s^2.
TABLE7_DECEL_MPS2 = 4.9


@dataclass(frozen=True)
class Check:
    """One warning a run is judged on.

    Attributes
    ----------
    curve_number
        The curve (1 or 2 in driving order; 1 on a single-curve track) the distance is measured to.
    level
        The warning level.
    table_distance_m
        The table's S_w: the warning must be on from the first step closer than this. None for
        a negative check (no warning of ``level`` anywhere).
    label
        How the standard names it, e.g. ``"curve 2, level 1"``.
    """

    curve_number: int
    level: Level
    table_distance_m: float | None
    label: str

    @property
    def negative(self) -> bool:
        """Whether the check requires the absence of the warning."""
        return self.table_distance_m is None


@dataclass(frozen=True)
class Row:
    """One row of the test procedure, for one vehicle category.

    Attributes
    ----------
    row_id
        Stable identifier, e.g. ``"T5-R40-M1-V51"``, ``"T9-M3-test1"``, ``"NEG-R120-N-L2"``.
    table
        5, 6, 7, 8 or 9; 0 for our negative rows.
    clause
        The clause that defines the test.
    category
        The vehicle category the system is told.
    test
        Test number of Tables 8 and 9, else None.
    radius_m
        Radius of each curve in driving order, m.
    speed_kmh
        Test speed V, km/h.
    final_speed_kmh
        Table 7: the curve-2 speed the vehicle brakes to; else None.
    decel_trigger_m
        Table 7: the distance to curve 1 at which braking starts (curve 1's level-2 S_w); else None.
    checks
        The warnings judged, in the table's order.
    tracks
        Names of the bundled networks the row runs on.
    """

    row_id: str
    table: int
    clause: str
    category: Category
    test: int | None
    radius_m: tuple[float, ...]
    speed_kmh: float
    final_speed_kmh: float | None
    decel_trigger_m: float | None
    checks: tuple[Check, ...]
    tracks: tuple[str, ...]

    @property
    def column(self) -> Column:
        """The tables' column of the row's category."""
        return self.category.column

    @property
    def decel_mps2(self) -> float | None:
        """Table 7's deceleration, m/s^2; None for the constant-speed rows."""
        return TABLE7_DECEL_MPS2 if self.final_speed_kmh is not None else None

    @property
    def negative(self) -> bool:
        """Whether this is one of our negative rows."""
        return self.table == 0

    def warning_speed_kmh(self, check: Check) -> float:
        """V_w of a check's curve and level for this row's category (Tables 1-2)."""
        return warning_speed(self.radius_m[check.curve_number - 1], self.category, check.level)


@cache
def _index() -> tuple[dict, ...]:
    """The bundled networks' index entries."""
    return tuple(json.loads((networks_dir() / "index.json").read_text("utf-8"))["networks"])


def track_names(
    table: int, column: str | None = None, test: int | None = None, radius_m: float | None = None
) -> tuple[str, ...]:
    """The bundled tracks of a table row: single curves by radius (Table 3), multi curves by table, column and test."""
    if table in (5, 6, 0):
        found = [n["name"] for n in _index() if n["table"] == 3 and n["radius_m"] == [radius_m]]
    else:
        found = [n["name"] for n in _index() if n["table"] == table and n["category"] == column and n["test"] == test]
    if not found:
        raise ValueError(f"no bundled track for table {table}, column {column}, test {test}, radius {radius_m}")
    return tuple(found)


def _categories(column: str) -> tuple[Category, ...]:
    """The categories of a column of the tables: M3, N and O for the merged one."""
    return tuple(c for c in Category if c.column.value == column)


def _single_rows(tables: dict, table: int, level: Level) -> Iterable[Row]:
    """Tables 5 and 6: one row per radius, category and test speed."""
    key = "table5_single_curve_level1_tests" if table == 5 else "table6_single_curve_level2_tests"
    clause = "7.5.2.1" if table == 5 else "7.5.2.2"
    for radius, columns in tables[key].items():
        if radius.startswith("_"):
            continue
        for column, cells in columns.items():
            for category in _categories(column):
                for speed_kmh, distance_m in cells:
                    yield Row(
                        row_id=f"T{table}-R{radius}-{category}-V{speed_kmh:g}",
                        table=table,
                        clause=clause,
                        category=category,
                        test=None,
                        radius_m=(float(radius),),
                        speed_kmh=float(speed_kmh),
                        final_speed_kmh=None,
                        decel_trigger_m=None,
                        checks=(Check(1, level, float(distance_m), f"curve, level {int(level)}"),),
                        tracks=track_names(table, radius_m=float(radius)),
                    )


def _multi_checks(distances: dict) -> tuple[Check, ...]:
    """The checks of a multi-curve row from its ``S_w_m`` cells (``curve2_level1`` -> curve 2, level 1),
    in table order."""
    checks = []
    for name, distance_m in distances.items():
        curve, level = name.split("_")
        number, level_number = int(curve.removeprefix("curve")), int(level.removeprefix("level"))
        checks.append(Check(number, Level(level_number), float(distance_m), f"curve {number}, level {level_number}"))
    return tuple(checks)


def _table7_rows(tables: dict) -> Iterable[Row]:
    """Table 7: curve 1 first, braking to the curve-2 speed within curve 1's level-2 S_w."""
    table = tables["table7_multi_curve_curve1_first"]
    track = table["track"]
    for column in tables["categories"]:
        cells = table[column]
        for category in _categories(column):
            yield Row(
                row_id=f"T7-{category}",
                table=7,
                clause="7.5.3.1",
                category=category,
                test=None,
                radius_m=(float(track["R1_m"]), float(track["R2_m"])),
                speed_kmh=float(cells["V_curve1_kmh"]),
                final_speed_kmh=float(cells["V_curve2_kmh"]),
                decel_trigger_m=float(cells["S_w_m"]["curve1_level2"]),
                checks=_multi_checks(cells["S_w_m"]),
                tracks=track_names(7),
            )


def _table89_rows(tables: dict, table: int) -> Iterable[Row]:
    """Tables 8 and 9: curve 2 warned first, one row per column's test and category."""
    key = next(k for k in tables if k.startswith(f"table{table}_"))
    clause = "7.5.3.2" if table == 8 else "7.5.3.3"
    for column in tables["categories"]:
        for cells in tables[key][column]:
            for category in _categories(column):
                yield Row(
                    row_id=f"T{table}-{category}-test{cells['test']}",
                    table=table,
                    clause=clause,
                    category=category,
                    test=int(cells["test"]),
                    radius_m=(float(cells["R1_m"]), float(tables[key]["R2_m"])),
                    speed_kmh=float(cells["V_kmh"]),
                    final_speed_kmh=None,
                    decel_trigger_m=None,
                    checks=_multi_checks(cells["S_w_m"]),
                    tracks=track_names(table, column, int(cells["test"])),
                )


def _negative_rows(tables: dict) -> Iterable[Row]:
    """3 km/h below every warning speed of the single curves: no warning of that level."""
    for row in tables["table3_single_curve_track"]:
        radius_m = float(row["radius_m"])
        for category in Category:
            for level in (Level.LEVEL_1, Level.LEVEL_2):
                speed_kmh = warning_speed(radius_m, category, level) - NEGATIVE_MARGIN_KMH
                yield Row(
                    row_id=f"NEG-R{radius_m:g}-{category}-L{int(level)}",
                    table=0,
                    clause="6.1",
                    category=category,
                    test=None,
                    radius_m=(radius_m,),
                    speed_kmh=speed_kmh,
                    final_speed_kmh=None,
                    decel_trigger_m=None,
                    checks=(Check(1, level, None, f"no level {int(level)} at V_w - {NEGATIVE_MARGIN_KMH:g} km/h"),),
                    tracks=track_names(0, radius_m=radius_m),
                )


def procedure_rows() -> list[Row]:
    """Every row of 7.5 (Tables 5-9) for every category, then our negative rows."""
    tables = standard_tables()
    return [
        *_single_rows(tables, 5, Level.LEVEL_1),
        *_single_rows(tables, 6, Level.LEVEL_2),
        *_table7_rows(tables),
        *_table89_rows(tables, 8),
        *_table89_rows(tables, 9),
        *_negative_rows(tables),
    ]
