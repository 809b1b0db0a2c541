"""The curves of a served network as a GeoJSON FeatureCollection.

One feature per curve of a road (:meth:`csws.road.roadmap.RoadMap.curves`): its geometry
(the road between the curve's start and end, through any node inside it), the lanes and
lane positions of its ends, street name and road type,
minimum radius, angle, direction, parts (its arcs and the pieces of its clothoids,
marked ``spiral``) and the warning speeds V_w of every category at both levels
(Tables 1-2). On a geo-referenced network coordinates are lon/lat (WGS84,
as RFC 7946 requires); otherwise they are network metres, which the collection says
in its ``coordinates`` member.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from fastapi import Query
from fastapi.exceptions import RequestValidationError

from csws.ahead.horizon import curve_id_of
from csws.standard import Category, Level, WarningSpeedPolicy, warning_speed

from .networks import ServedNetwork

#: How a feature's coordinates are given, by whether its network is geo-referenced.
_COORDINATES = {True: "lon/lat (WGS84)", False: "network metres"}

__all__ = [
    "BBOX_QUERY",
    "NETWORK_QUERY",
    "warning_speeds_kmh",
    "curve_features",
    "in_bbox",
    "parse_bbox",
    "choose_networks",
    "feature_collection",
]


def warning_speeds_kmh(radius_m: float, policy: WarningSpeedPolicy) -> dict[str, dict[str, float]]:
    """V_w at ``radius_m`` for every category and both levels, km/h: ``{"M1": {"1": ..., "2": ...}, ...}``."""
    return {
        category.value: {
            str(int(level)): warning_speed(radius_m, category, level, policy)
            for level in (Level.LEVEL_1, Level.LEVEL_2)
        }
        for category in Category
    }


def _coordinates(network: ServedNetwork, xy: np.ndarray) -> list[list[float]]:
    """Points as GeoJSON positions: lon/lat on a geo-referenced network, else network metres."""
    if network.road_map.has_projection:
        return [list(map(float, network.road_map.xy_to_lonlat(x, y))) for x, y in xy]
    return xy.tolist()


def curve_features(network: ServedNetwork) -> list[dict[str, Any]]:
    """Every curve of the network as a GeoJSON Feature (with its ``bbox``)."""
    policy = network.engine.settings.warning.policy
    features = []
    for lane_curve in network.road_map.curves():
        coordinates = _coordinates(network, network.road_map.curve_shape(lane_curve))
        xs, ys = zip(*coordinates, strict=False)
        curve = lane_curve.curve
        lane = network.road_map.lane(lane_curve.lane_id)
        features.append(
            {
                "type": "Feature",
                "id": f"{network.name}/{curve_id_of(lane_curve.lane_id, lane_curve.start_pos_m)}",
                "bbox": [min(xs), min(ys), max(xs), max(ys)],
                "geometry": {"type": "LineString", "coordinates": coordinates},
                "properties": {
                    "network": network.name,
                    "coordinates": _COORDINATES[network.road_map.has_projection],
                    "curve_id": curve_id_of(lane_curve.lane_id, lane_curve.start_pos_m),
                    "lane_id": lane_curve.lane_id,
                    "street_name": lane.street_name,
                    "road_type": lane.road_type,
                    "start_pos_m": lane_curve.start_pos_m,
                    "end_lane_id": lane_curve.end_lane_id,
                    "end_pos_m": lane_curve.end_pos_m,
                    "radius_m": curve.min_radius_m,
                    "angle_deg": curve.angle_deg,
                    "direction": curve.direction,
                    "warning_speed_kmh": warning_speeds_kmh(curve.min_radius_m, policy),
                    "parts": [
                        {
                            "part_index": index,
                            "length_m": part.end_s - part.start_s,
                            "radius_m": part.radius_m,
                            "spiral": part.spiral,
                            "warning_speed_kmh": warning_speeds_kmh(part.radius_m, policy),
                        }
                        for index, part in enumerate(curve.parts)
                    ],
                },
            }
        )
    return features


def in_bbox(feature: dict[str, Any], bbox: tuple[float, float, float, float] | None) -> bool:
    """Whether a feature's bounding box meets ``bbox`` (min x, min y, max x, max y); always without one."""
    if bbox is None:
        return True
    west, south, east, north = feature["bbox"]
    return not (east < bbox[0] or west > bbox[2] or north < bbox[1] or south > bbox[3])


#: The ``bbox`` parameter of the map's routes (read with :func:`parse_bbox`).
BBOX_QUERY = Query(
    default=None,
    examples=["850,-50,1200,400"],
    description="min_x,min_y,max_x,max_y: lon/lat on geo-referenced networks, else network metres",
)
#: The ``network`` parameter of the map's routes (checked with :func:`choose_networks`).
NETWORK_QUERY = Query(default=None, description="only this network")


def parse_bbox(text: str | None) -> tuple[float, float, float, float] | None:
    """``min_x,min_y,max_x,max_y`` as numbers; a 422 when it is not that."""
    if text is None:
        return None
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 4 or not all(map(lambda v: v == v and abs(v) != float("inf"), values)):
        raise RequestValidationError(
            [
                {
                    "loc": ("query", "bbox"),
                    "type": "value_error",
                    "msg": "bbox must be four finite numbers: min_x,min_y,max_x,max_y",
                }
            ]
        )
    if values[0] > values[2] or values[1] > values[3]:
        raise RequestValidationError(
            [
                {
                    "loc": ("query", "bbox"),
                    "type": "value_error",
                    "msg": "bbox minimum must not exceed its maximum: min_x,min_y,max_x,max_y",
                }
            ]
        )
    return values


def choose_networks(networks: Sequence[ServedNetwork], name: str | None) -> list[int]:
    """The indices of the networks a request names: ``name``'s, or all without one; a 422 for an unknown name."""
    chosen = [i for i, n in enumerate(networks) if name is None or n.name == name]
    if not chosen:
        raise RequestValidationError(
            [{"loc": ("query", "network"), "type": "value_error", "msg": f"unknown network {name!r}"}]
        )
    return chosen


def feature_collection(features: list[dict[str, Any]], networks: list[ServedNetwork]) -> dict[str, Any]:
    """A FeatureCollection, saying which coordinates it uses (each feature says it too)."""
    kinds = {_COORDINATES[n.road_map.has_projection] for n in networks}
    return {
        "type": "FeatureCollection",
        "coordinates": kinds.pop() if len(kinds) == 1 else "per feature",
        "features": features,
    }
