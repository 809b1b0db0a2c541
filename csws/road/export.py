"""Exporting the curve index: the columns of ``csws curves`` and their aligned text table."""

from __future__ import annotations

from typing import TextIO

__all__ = ["CURVE_FIELDS", "write_curve_table"]

#: Columns of the curve index (``csws curves``).
CURVE_FIELDS = ("lane_id", "start_pos_m", "end_lane_id", "end_pos_m", "min_radius_m", "angle_deg", "direction")


def write_curve_table(records: list[dict[str, str | float]], stream: TextIO) -> None:
    """Write curve records as an aligned text table: ids left-aligned, numbers right-aligned."""
    cells = [list(CURVE_FIELDS)] + [[f"{record[name]}" for name in CURVE_FIELDS] for record in records]
    widths = [max(len(row[column]) for row in cells) for column in range(len(CURVE_FIELDS))]
    for row in cells:
        padded = [
            cell.ljust(width) if name in ("lane_id", "end_lane_id", "direction") else cell.rjust(width)
            for cell, width, name in zip(row, widths, CURVE_FIELDS, strict=False)
        ]
        stream.write("  ".join(padded).rstrip() + "\n")
