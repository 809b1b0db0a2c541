"""The live map: ``GET /map``, the roads it draws (``GET /v1/roads``) and the fleet on it (``GET /v1/fleet``).

The page (``service/static/map.html``, ``map.js``) is Leaflet, vendored from its npm package
with its licence (``service/static/leaflet/``): no tile server, no CDN, so it works on a host
without Internet access. It draws the served network's roads, its curves in the view
(``GET /v1/curves?bbox=...``) coloured by minimum radius, and the live vehicles, asked for once
a second. On a service with API keys the page itself is open (it holds no data) and sends the
key given after ``#key=`` in its address with every request for data.
"""

from __future__ import annotations

import json
from collections.abc import Awaitable, Callable, Sequence
from importlib.resources import files
from typing import Any

import msgspec
import shapely
from fastapi import FastAPI, Request
from fastapi import Query as QueryParam
from fastapi.responses import HTMLResponse, Response
from starlette.middleware.gzip import GZipMiddleware

from .curves import BBOX_QUERY, NETWORK_QUERY, choose_networks, feature_collection, parse_bbox
from .fleet import fleet_features
from .keys import principal, vehicle_key
from .networks import ServedNetwork
from .store import StateStore
from .vehicles import VehicleRegistry

__all__ = ["ROAD_TOLERANCE_M", "CompressedGets", "road_features", "add_map_routes"]

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


def _json(content: Any) -> Response:
    return Response(msgspec.json.encode(content), media_type="application/json")


def add_map_routes(
    app: FastAPI,
    networks: Sequence[ServedNetwork],
    registry: VehicleRegistry,
    store: StateStore,
    off_loop: Callable[..., Awaitable[Any]],
    responses: dict[int, Any],
) -> None:
    """Add ``/map``, ``/v1/roads`` and ``/v1/fleet`` to ``app``, and gzip its answers to ``GET`` requests.

    Parameters
    ----------
    off_loop
        Runs a function on the service's work thread (:class:`service.work.WorkThread`).
    responses
        What the data routes may answer besides a 200 and a 422 (a 401 with keys, a 503 of the store).
    """
    names = json.dumps([{"name": n.name, "geo_referenced": n.road_map.has_projection} for n in networks])
    page = _PAGE.replace("{networks}", names.replace("</", "<\\/"))
    roads_cache: dict[int, bytes] = {}
    app.add_middleware(CompressedGets)

    @app.get("/map", include_in_schema=False)
    async def live_map() -> HTMLResponse:
        return HTMLResponse(page)

    @app.get(
        "/v1/roads",
        summary="The roads of a served network as GeoJSON, simplified for drawing",
        tags=["map"],
        responses=responses,
    )
    async def roads(network: str = QueryParam(description="the network")) -> Response:
        (index,) = choose_networks(networks, network)

        def collection() -> bytes:
            if index not in roads_cache:
                roads_cache[index] = msgspec.json.encode(
                    feature_collection(road_features(networks[index]), [networks[index]])
                )
            return roads_cache[index]

        return Response(await off_loop(collection), media_type="application/json")

    @app.get(
        "/v1/fleet",
        summary="Where the fleet's live vehicles are and what their latest answers said",
        tags=["map"],
        responses=responses,
    )
    async def fleet(
        request: Request,
        bbox: str | None = BBOX_QUERY,
        network: str | None = NETWORK_QUERY,
    ) -> Response:
        box, chosen = parse_bbox(bbox), choose_networks(networks, network)
        asking = principal(request).fleet
        prefix = vehicle_key(asking, "")

        def collection() -> dict[str, Any]:
            return fleet_features(store.sessions(prefix), registry, networks, asking, box, chosen)

        return _json(await off_loop(collection))
