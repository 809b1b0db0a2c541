"""The curves of a served network as a GeoJSON FeatureCollection, and the map routes' query parameters.

One feature per curve of a road, built by the library's one curve export
(:func:`csws.road.export.curve_feature`, V_w under the network engine's warning speed policy),
so it carries the same properties as the OSM import's ``NAME.curves.geojson``; the service adds
the ``network`` it belongs to, and its id is the curve's id within that network.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from fastapi import Query
from fastapi.exceptions import RequestValidationError

from csws.road.export import COORDINATES, curve_features

from .networks import ServedNetwork

__all__ = [
    "BBOX_QUERY",
    "NETWORK_QUERY",
    "network_curve_features",
    "in_bbox",
    "parse_bbox",
    "choose_networks",
    "feature_collection",
]


def network_curve_features(network: ServedNetwork) -> list[dict[str, Any]]:
    """Every curve of a served network as a GeoJSON Feature (with its ``bbox``), its id ``NETWORK/CURVE_ID``."""
    features = curve_features(network.road_map, network.engine.settings.warning.policy)
    for feature in features:
        feature["id"] = f"{network.name}/{feature['id']}"
        feature["properties"] = {"network": network.name, **feature["properties"]}
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
    kinds = {COORDINATES[n.road_map.has_projection] for n in networks}
    return {
        "type": "FeatureCollection",
        "coordinates": kinds.pop() if len(kinds) == 1 else "per feature",
        "features": features,
    }
