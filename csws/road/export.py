"""Exporting the curve index: one schema for every reader of it.

A curve of the index (:meth:`csws.road.roadmap.RoadMap.curves`) is exported two ways:

* as a record of :data:`CURVE_FIELDS` (lengths and angles rounded to the centimetre and the
  hundredth of a degree), for ``csws curves`` as an aligned table, JSON or CSV
  (:func:`write_curves`);
* as a GeoJSON Feature (:func:`curve_feature`): the road between the curve's start (3.4) and
  end (3.5) as a LineString, and as properties the same fields, the curve's id (``curve_id``:
  the road's curve, ``EDGE@POS``, the same on every lane of the road and the one the horizon and
  the warnings give; the feature's own id, ``LANE@POS``, names this lane's copy of it), the lane's
  street name and road type, its parts (the arcs and the pieces of its clothoids, marked
  ``spiral``) and the warning speeds V_w of every category at both levels (Tables 1-2) under
  the warning speed policy given. The OSM import's ``NAME.curves.geojson`` and the service's
  ``GET /v1/curves`` (and so the live map) are built by it, so the same curve has the same
  properties in both.

On a geo-referenced network coordinates are lon/lat (WGS84, as RFC 7946 requires) rounded to
1e-6 degrees (0.1 m); otherwise they are network metres rounded to the centimetre, which the
feature and the collection say in their ``coordinates`` member.
"""

from __future__ import annotations

import csv
import json
from typing import TYPE_CHECKING, Any, TextIO

import numpy as np

from csws.road.chains import LaneCurve, curve_id_of
from csws.standard import DEFAULT_POLICY, Category, Level, WarningSpeedPolicy, warning_speed

if TYPE_CHECKING:
    from csws.road.roadmap import RoadMap

__all__ = [
    "CURVE_FIELDS",
    "CURVE_FORMATS",
    "COORDINATES",
    "curve_record",
    "write_curves",
    "write_curve_table",
    "warning_speeds_kmh",
    "curve_feature",
    "curve_features",
    "curves_geojson",
]

#: Columns of the curve index (``csws curves``); the GeoJSON properties carry the same names.
CURVE_FIELDS = ("lane_id", "start_pos_m", "end_lane_id", "end_pos_m", "radius_m", "angle_deg", "direction")
#: The formats of :func:`write_curves`.
CURVE_FORMATS = ("table", "json", "csv")
#: How a feature's coordinates are given, by whether its network is geo-referenced.
COORDINATES = {True: "lon/lat (WGS84)", False: "network metres"}
#: Decimals of the exported coordinates: lon/lat to 1e-6 degrees (0.1 m), network metres to the centimetre.
_DECIMALS = {True: 6, False: 2}


def curve_record(lane_curve: LaneCurve) -> dict[str, str | float]:
    """The :data:`CURVE_FIELDS` of a curve, lengths and angles to the centimetre / hundredth degree."""
    curve = lane_curve.curve
    return {
        "lane_id": lane_curve.lane_id,
        "start_pos_m": round(lane_curve.start_pos_m, 2),
        "end_lane_id": lane_curve.end_lane_id,
        "end_pos_m": round(lane_curve.end_pos_m, 2),
        "radius_m": round(curve.min_radius_m, 2),
        "angle_deg": round(curve.angle_deg, 2),
        "direction": curve.direction,
    }


def write_curves(road_map: RoadMap, stream: TextIO, fmt: str = "table") -> None:
    """Write the curve index of ``road_map`` as ``"table"`` (aligned text), ``"json"`` or ``"csv"``
    with :data:`CURVE_FIELDS`.

    Raises
    ------
    ValueError
        For a format not in :data:`CURVE_FORMATS`.
    """
    if fmt not in CURVE_FORMATS:
        raise ValueError(f"unknown curve format {fmt!r}: use 'table', 'json' or 'csv'")
    records = [curve_record(lane_curve) for lane_curve in road_map.curves()]
    if fmt == "json":
        json.dump(records, stream, indent=2)
        stream.write("\n")
    elif fmt == "csv":
        writer = csv.DictWriter(stream, fieldnames=CURVE_FIELDS, lineterminator="\n")
        writer.writeheader()
        writer.writerows(records)
    else:
        write_curve_table(records, stream)


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


def warning_speeds_kmh(radius_m: float, policy: WarningSpeedPolicy) -> dict[str, dict[str, float]]:
    """V_w at ``radius_m`` for every category and both levels (Tables 1-2), km/h:
    ``{"M1": {"1": ..., "2": ...}, ...}``."""
    return {
        category.value: {
            str(int(level)): warning_speed(radius_m, category, level, policy)
            for level in (Level.LEVEL_1, Level.LEVEL_2)
        }
        for category in Category
    }


def _coordinates(road_map: RoadMap, lane_curve: LaneCurve) -> np.ndarray:
    """The curve's road as GeoJSON positions ``(m, 2)``: rounded lon/lat on a geo-referenced network, else metres."""
    xy = road_map.curve_shape(lane_curve)
    points = road_map.xy_to_lonlat_many(xy) if road_map.has_projection else xy
    return np.round(points, _DECIMALS[road_map.has_projection])


def curve_feature(road_map: RoadMap, lane_curve: LaneCurve, policy: WarningSpeedPolicy) -> dict[str, Any]:
    """One curve of ``road_map`` as a GeoJSON Feature with its ``bbox``, its id the curve's id, V_w under ``policy``."""
    coordinates = _coordinates(road_map, lane_curve)
    curve, lane = lane_curve.curve, road_map.lane(lane_curve.lane_id)
    return {
        "type": "Feature",
        "id": curve_id_of(lane_curve.lane_id, lane_curve.start_pos_m),
        "bbox": [*coordinates.min(axis=0).tolist(), *coordinates.max(axis=0).tolist()],
        "geometry": {"type": "LineString", "coordinates": coordinates.tolist()},
        "properties": {
            "coordinates": COORDINATES[road_map.has_projection],
            "curve_id": lane_curve.curve_id,
            "lane_id": lane_curve.lane_id,
            "street_name": lane.street_name,
            "road_type": lane.road_type,
            "start_pos_m": lane_curve.start_pos_m,
            "end_lane_id": lane_curve.end_lane_id,
            "end_pos_m": lane_curve.end_pos_m,
            "radius_m": curve.min_radius_m,
            "angle_deg": curve.angle_deg,
            "direction": curve.direction,
            **(road_map.curve_slopes(lane_curve) or {}),
            "warning_speed_kmh": warning_speeds_kmh(curve.min_radius_m, policy),
            "parts": [
                {
                    "part_index": index,
                    "length_m": part.end_s - part.start_s,
                    "radius_m": part.radius_m,
                    "spiral": part.spiral,
                    "warning_speed_kmh": warning_speeds_kmh(part.radius_m, policy),
                }
                for index, part in enumerate(curve.parts, start=lane_curve.first_part_index)
            ],
        },
    }


def curve_features(road_map: RoadMap, policy: WarningSpeedPolicy = DEFAULT_POLICY) -> list[dict[str, Any]]:
    """Every curve of the index of ``road_map`` as a GeoJSON Feature (:func:`curve_feature`)."""
    return [curve_feature(road_map, lane_curve, policy) for lane_curve in road_map.curves()]


def curves_geojson(road_map: RoadMap, policy: WarningSpeedPolicy = DEFAULT_POLICY) -> dict[str, Any]:
    """The curve index of ``road_map`` as a GeoJSON FeatureCollection (RFC 7946 on a geo-referenced network)."""
    return {
        "type": "FeatureCollection",
        "coordinates": COORDINATES[road_map.has_projection],
        "features": curve_features(road_map, policy),
    }
