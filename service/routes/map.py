"""The map: ``GET /map`` (the live map's page), ``/v1/curves``, ``/v1/horizon``, ``/v1/roads``, ``/v1/report`` and
``/v1/fleet``.

The page (:mod:`service.map`) holds no data and needs no key; the data routes need the caller's key
and answer only its fleet's vehicles. ``/v1/report`` gives a network's map report (:mod:`csws.osm.report`), the
``NAME.report.geojson`` that ``csws import-osm`` or ``csws map-report`` wrote beside it.
"""

from __future__ import annotations

from typing import Annotated, NamedTuple

from fastapi import APIRouter, Depends, HTTPException, Query
from fastapi.exceptions import RequestValidationError
from fastapi.responses import HTMLResponse, Response
from pydantic import ValidationError

from csws.osm.importer import map_report_path
from csws.standard import Category

from .. import horizon
from ..curves import BBOX_QUERY, NETWORK_QUERY, choose_networks, parse_bbox
from ..deps import CallerDep, MapDataDep, NetworksDep, RegistryDep, ServiceDep, StoreDep, WorkDep
from ..fleet import CURSOR_QUERY, FLEET_LINKS, LIMIT_QUERY, FleetPage, decode_cursor, fleet_page
from ..horizon import DEFAULT_HORIZON_M
from ..networks import MAX_HORIZON_M
from ..schemas import Message
from ..schemas import Query as PositionQuery
from .common import KEYED, STORE, json_response

__all__ = ["router", "HorizonRequest", "horizon_query"]

#: The data routes: a key on a service with keys; the state store's 503 where they read vehicles.
router = APIRouter(tags=["map"])


class HorizonRequest(NamedTuple):
    """What ``GET /v1/horizon`` asks: a position (as a query of no vehicle) and how far ahead to look, m."""

    query: PositionQuery
    length_m: float


@router.get("/map", include_in_schema=False)
async def live_map(data: MapDataDep) -> HTMLResponse:
    """The live map's page."""
    return HTMLResponse(data.page)


@router.get("/v1/curves", summary="The curves of the served networks as GeoJSON", responses=KEYED)
async def curves(
    _principal: CallerDep,
    networks: NetworksDep,
    data: MapDataDep,
    work: WorkDep,
    bbox: str | None = BBOX_QUERY,
    network: str | None = NETWORK_QUERY,
) -> Response:
    """The curves of the chosen networks that meet the bbox, with the properties of the OSM import's curve index."""
    box, chosen = parse_bbox(bbox), choose_networks(networks, network)
    return Response(await work.run(data.curves, chosen, box), media_type="application/json")


async def horizon_query(
    x: Annotated[float | None, Query(allow_inf_nan=False, description="network x, m")] = None,
    y: Annotated[float | None, Query(allow_inf_nan=False, description="network y, m")] = None,
    lon: Annotated[float | None, Query(allow_inf_nan=False, description="longitude, degrees")] = None,
    lat: Annotated[float | None, Query(allow_inf_nan=False, description="latitude, degrees")] = None,
    heading_deg: Annotated[float | None, Query(allow_inf_nan=False, description="degrees from north")] = None,
    lane_id: Annotated[str | None, Query(description="lane id (no map matching)")] = None,
    lane_pos_m: Annotated[float | None, Query(allow_inf_nan=False, description="lane position, m")] = None,
    route: Annotated[str | None, Query(description="route edge ids, comma-separated")] = None,
    network: Annotated[str | None, Query(description="the served network (default: best match)")] = None,
    length_m: Annotated[
        float, Query(gt=0, le=MAX_HORIZON_M, allow_inf_nan=False, description="how far ahead, m")
    ] = DEFAULT_HORIZON_M,
) -> HorizonRequest:
    """The position of a horizon request as a query of no vehicle, and how far ahead to look; a 422 naming the
    parameters it lacks."""
    given = {k: v for k, v in {"x": x, "y": y, "lon": lon, "lat": lat}.items() if v is not None}
    try:
        query = PositionQuery.model_validate(
            {
                "vehicle_id": "horizon",
                "category": Category.M1,
                "speed_kmh": 0.0,
                "position": given or None,
                "heading_deg": heading_deg,
                "lane_id": lane_id,
                "lane_pos_m": lane_pos_m,
                "route": route.split(",") if route else None,
                "network": network,
            }
        )
    except ValidationError as exc:
        errors = [{**e, "loc": ("query", *e["loc"])} for e in exc.errors(include_url=False)]
        raise RequestValidationError(errors) from None
    return HorizonRequest(query, length_m)


@router.get(
    "/v1/horizon", summary="The road ahead of a position: radius profile and CPOIs", responses={**KEYED, **STORE}
)
async def road_ahead(
    _principal: CallerDep,
    asked: Annotated[HorizonRequest, Depends(horizon_query)],
    service: ServiceDep,
    registry: RegistryDep,
    work: WorkDep,
) -> Response:
    """Where the position matches a lane, and the road ahead of it up to length_m."""
    return json_response(await work.run(horizon.road_ahead, service, registry, asked.query, asked.length_m))


@router.get(
    "/v1/roads",
    summary="The roads of a served network as GeoJSON, simplified for drawing",
    responses={**KEYED, **STORE},
)
async def roads(
    _principal: CallerDep,
    networks: NetworksDep,
    data: MapDataDep,
    work: WorkDep,
    network: Annotated[str, Query(description="the network")],
) -> Response:
    """The roads of one network: the rightmost lane of each edge, simplified to within 1 m."""
    (index,) = choose_networks(networks, network)
    return Response(await work.run(data.roads, index), media_type="application/json")


@router.get(
    "/v1/report",
    summary="The map report of a served network as GeoJSON: what its map shows wrong or doubtful, place by place",
    responses={**KEYED, 404: {"model": Message, "description": "the network has no map report beside it"}},
)
async def map_report(
    _principal: CallerDep,
    networks: NetworksDep,
    work: WorkDep,
    network: Annotated[str, Query(description="the network")],
) -> Response:
    """The network's ``NAME.report.geojson``: map artefacts, curves at the radius floor, corners mapped by a single
    node, ways dropped or cut by the extract's border, each with its OSM way id, size and reason."""
    (index,) = choose_networks(networks, network)
    path = map_report_path(networks[index].path)
    try:
        body = await work.run(path.read_bytes)
    except FileNotFoundError:
        raise HTTPException(
            404, f"network {network!r} has no map report: write one with csws map-report {networks[index].path.name}"
        ) from None
    return Response(body, media_type="application/geo+json")


@router.get(
    "/v1/fleet",
    summary="Where the fleet's live vehicles are and what their latest answers said, a page at a time",
    operation_id="getFleet",
    responses={200: {"model": FleetPage, "links": FLEET_LINKS}, **KEYED, **STORE},
)
async def fleet(
    principal: CallerDep,
    networks: NetworksDep,
    registry: RegistryDep,
    store: StoreDep,
    work: WorkDep,
    bbox: str | None = BBOX_QUERY,
    network: str | None = NETWORK_QUERY,
    limit: int = LIMIT_QUERY,
    cursor: str | None = CURSOR_QUERY,
) -> Response:
    """The live vehicles of the caller's fleet in the bbox, with their latest answers, in the order of their ids:
    at most limit of them, the cursor of the next page (null on the last), and the service's time
    (``generated_s``, Unix time, s) against which the map ages each vehicle's ``answered_at_s``."""
    box, chosen = parse_bbox(bbox), choose_networks(networks, network)
    after_id = None if cursor is None else decode_cursor(cursor)
    page = await fleet_page(work, store, registry, networks, principal.fleet, box, chosen, after_id, limit)
    return Response(page, media_type="application/json")
