"""The live map: ``GET /map``, the roads it draws (``GET /v1/roads``) and the fleet on it (``GET /v1/fleet``).

The page (``service/static/map.html``, ``map.css``, ``map.js``) is Leaflet, vendored from its npm package
with its licence (``service/static/leaflet/``): no tile server, no CDN, so it works on a host
without Internet access. It draws the served network's roads, its curves in the view
(``GET /v1/curves?bbox=...``) coloured by radius, and the live vehicles, asked for once
a second, told apart by colour and shape, faded after a silence, with a list of those warned now;
the view and the selected vehicle are kept in the address (docs/service.md, "The live map").
On a service with API keys the page itself is open (it holds no data) and sends the
key given after ``#key=`` in its address with every request for data.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from importlib.resources import files
from typing import Any

import msgspec
import shapely
from starlette.middleware.gzip import GZipMiddleware

from csws.osm.importer import map_report_path

from .curves import feature_collection, in_bbox, network_curve_features
from .networks import ServedNetwork

__all__ = ["ROAD_TOLERANCE_M", "CompressedGets", "road_features", "MapData"]

#: Roads are drawn simplified to within this distance of their lanes, m.
ROAD_TOLERANCE_M = 1.0

#: The page; ``{networks}`` becomes the served networks' names and coordinates.
_PAGE = files("service").joinpath("static", "map.html").read_text("utf-8")


def road_features(network: ServedNetwork) -> list[dict[str, Any]]:
    """The roads of a network as GeoJSON LineStrings: the rightmost lane of every edge that is not
    inside a junction, simplified to :data:`ROAD_TOLERANCE_M`, lon/lat rounded to 1e-6 deg (0.1 m)
    on a geo-referenced network, else metres rounded to 0.1 m."""
    road_map = network.road_map
    features = []
    for lane_id in road_map.lane_ids:
        lane = road_map.lane(lane_id)
        if lane.function == "internal" or lane.index != 0:
            continue
        xy = shapely.get_coordinates(
            shapely.simplify(shapely.LineString(road_map.lane_shape(lane_id)), ROAD_TOLERANCE_M)
        )
        coordinates = road_map.xy_to_lonlat_many(xy).round(6) if road_map.has_projection else xy.round(1)
        features.append(
            {
                "type": "Feature",
                "id": lane.edge_id,
                "geometry": {"type": "LineString", "coordinates": coordinates.tolist()},
                "properties": {"street_name": lane.street_name, "road_type": lane.road_type},
            }
        )
    return features


class CompressedGets:
    """ASGI middleware: answers to ``GET`` requests gzipped for clients that accept it (the map's roads
    and curves, the docs' scripts shrink to a fifth); other requests pass untouched, so a fleet's
    batches spend no time compressing."""

    def __init__(self, app: Any) -> None:
        self.app = app
        self.gzip = GZipMiddleware(app, minimum_size=1024, compresslevel=6)

    async def __call__(self, scope: Any, receive: Any, send: Any) -> None:
        if scope["type"] == "http" and scope["method"] == "GET":
            await self.gzip(scope, receive, send)
        else:
            await self.app(scope, receive, send)


class MapData:
    """What the map routes draw, made once per network on first use: the page naming the served
    networks (and whether each has a map report, ``GET /v1/report``), the curves' features
    (:func:`service.curves.network_curve_features`) and the roads' JSON.

    The caches are filled on the service's work thread only (:mod:`service.work`).
    """

    def __init__(self, networks: Sequence[ServedNetwork]) -> None:
        self.networks = list(networks)
        names = json.dumps(
            [
                {
                    "name": n.name,
                    "geo_referenced": n.road_map.has_projection,
                    "report": map_report_path(n.path).is_file(),
                }
                for n in networks
            ]
        )
        self.page = _PAGE.replace("{networks}", names.replace("</", "<\\/"))
        self._curves: dict[int, list[dict[str, Any]]] = {}
        self._roads: dict[int, bytes] = {}

    def curves(self, chosen: Sequence[int], bbox: tuple[float, float, float, float] | None) -> bytes:
        """The JSON FeatureCollection of the curves of the networks ``chosen`` that meet ``bbox``."""
        features = []
        for index in chosen:
            if index not in self._curves:
                self._curves[index] = network_curve_features(self.networks[index])
            features += [feature for feature in self._curves[index] if in_bbox(feature, bbox)]
        return msgspec.json.encode(feature_collection(features, [self.networks[i] for i in chosen]))

    def roads(self, index: int) -> bytes:
        """The JSON FeatureCollection of the roads of network ``index`` (:func:`road_features`)."""
        if index not in self._roads:
            network = self.networks[index]
            self._roads[index] = msgspec.json.encode(feature_collection(road_features(network), [network]))
        return self._roads[index]
