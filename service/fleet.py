"""The live fleet, a page at a time: where the vehicles with a live session are and what their latest answers said.

``GET /v1/fleet`` reads one page of the asking fleet's vehicles from the state store's index of
places (:meth:`service.store.StateStore.placed`): at most ``limit`` vehicles
(:data:`DEFAULT_PAGE_SIZE` unless asked, at most :data:`MAX_PAGE_SIZE`), in the order of their
ids, those in the bbox only when one is given, so a page costs what it holds and not what the
fleet holds. The answer's ``next_cursor`` asks for the next page (None on the last one); each
vehicle is on exactly one page of a walk from the first to the last, if it neither moves
into or out of the bbox nor appears or expires meanwhile. It shows the vehicles that any
worker or replica answered.

A page stays off the path of the fixes its worker answers: the store is read on the work thread
(which owns the store's connection) in pieces of :data:`READ_PIECE` vehicles, one round trip
each, so that fixes queued meanwhile are answered between two pieces; the sessions are decoded
and the answer written out on another thread.

A vehicle is placed on the road: at the lane position of its last match (the lane point, not
the raw fix), in the coordinates of its network's curves (lon/lat on geo-referenced networks,
else network metres), as stored with its session (:mod:`service.places`). A vehicle that never
matched has no place and is left out; one whose latest fix matched nothing stays where it last
matched, with state ``fault``.
"""

from __future__ import annotations

import base64
import binascii
import time
from collections.abc import Sequence
from typing import Any

import msgspec
from fastapi import Query
from fastapi.exceptions import RequestValidationError
from pydantic import BaseModel, Field
from starlette.concurrency import run_in_threadpool

from .curves import feature_collection
from .keys import shown_id, vehicle_key
from .networks import ServedNetwork
from .store import Box, PlacedSession, StateStore
from .vehicles import VehicleRegistry
from .work import WorkThread

__all__ = [
    "DEFAULT_PAGE_SIZE",
    "MAX_PAGE_SIZE",
    "READ_PIECE",
    "LIMIT_QUERY",
    "CURSOR_QUERY",
    "FleetPage",
    "FLEET_LINKS",
    "encode_cursor",
    "decode_cursor",
    "fleet_page",
]

#: Vehicles per page unless the request asks for another number.
DEFAULT_PAGE_SIZE = 1_000
#: The most vehicles a page holds: a page is decoded and written out in one go, on the worker that
#: also answers fixes, so its size bounds the time it holds them up.
MAX_PAGE_SIZE = 10_000
#: Vehicles read from the store per piece of work on the work thread (a few ms each).
READ_PIECE = 500
#: What a cursor starts with: its format, should it ever change.
_CURSOR_TAG = b"1:"

#: The ``limit`` parameter of ``GET /v1/fleet``.
LIMIT_QUERY = Query(
    default=DEFAULT_PAGE_SIZE,
    ge=1,
    le=MAX_PAGE_SIZE,
    description=f"the most vehicles in this page (default {DEFAULT_PAGE_SIZE:,}, at most {MAX_PAGE_SIZE:,})",
)
#: The ``cursor`` parameter of ``GET /v1/fleet``.
CURSOR_QUERY = Query(
    default=None,
    description="the next_cursor of the previous page (with the same bbox and network), to read the next one",
)


class FleetPage(BaseModel):
    """A page of the fleet: a GeoJSON FeatureCollection of points (one per vehicle, its id the vehicle's),
    in the order of the vehicles' ids, and the cursor of the next page."""

    type: str = Field(description="FeatureCollection")
    coordinates: str = Field(description="lon/lat or network metres (or 'per feature' across networks)")
    features: list[dict[str, Any]] = Field(
        description="per vehicle a Point with its id, network, system state and fault, the level, category, "
        "speed, timestamp and heading of its latest answer, its target curve and that curve's V_w, the "
        "service's Unix time of the answer (answered_at_s), and its lane with the lane's street name and road type"
    )
    next_cursor: str | None = Field(description="pass as cursor to read the next page; null on the last page")
    generated_s: float = Field(description="the service's Unix time when it wrote the page, s")


#: The OpenAPI links of a page: the next one, asked with its ``next_cursor`` (and the same bbox, network and
#: limit), which clients and stateful API testers follow.
FLEET_LINKS = {
    "NextPage": {
        "operationId": "getFleet",
        "parameters": {
            "cursor": "$response.body#/next_cursor",
            "bbox": "$request.query.bbox",
            "network": "$request.query.network",
            "limit": "$request.query.limit",
        },
        "description": "the next page of the same walk (none after the last page, whose next_cursor is null)",
    }
}


def encode_cursor(vehicle_id: str) -> str:
    """The cursor of the page after the vehicle ``vehicle_id`` (its id within its fleet): opaque, URL-safe."""
    return base64.urlsafe_b64encode(_CURSOR_TAG + vehicle_id.encode()).decode().rstrip("=")


def decode_cursor(cursor: str) -> str:
    """The vehicle id after which a cursor's page starts; a 422 naming the rule when it is no cursor."""
    try:
        raw = base64.urlsafe_b64decode(cursor + "=" * (-len(cursor) % 4))
        if raw.startswith(_CURSOR_TAG):
            return raw[len(_CURSOR_TAG) :].decode()
    except (binascii.Error, ValueError):
        pass
    raise RequestValidationError(
        [
            {
                "loc": ("query", "cursor"),
                "type": "value_error",
                "msg": "cursor must be the next_cursor of a page of GET /v1/fleet, unchanged",
                "input": cursor,
            }
        ]
    )


def _feature(
    found: PlacedSession, registry: VehicleRegistry, networks: Sequence[ServedNetwork], fleet: str
) -> dict[str, Any] | None:
    """A vehicle as a GeoJSON point at its place, with its latest answer (heading, target curve with its V_w,
    the service's time of the answer) and its lane's street name and road type; None for a session this
    service cannot take up."""
    record = registry.decode(found.session)
    if record is None or record.lane_id is None or record.latest is None:
        return None
    road_map = networks[registry.network_index[record.network]].road_map
    if not road_map.has_lane(record.lane_id):
        return None
    lane = road_map.lane(record.lane_id)
    position, latest, vehicle_id = [found.place.x, found.place.y], record.latest, shown_id(fleet, found.key)
    return {
        "type": "Feature",
        "id": vehicle_id,
        "bbox": [*position, *position],
        "geometry": {"type": "Point", "coordinates": position},
        "properties": {
            "vehicle_id": vehicle_id,
            "network": found.place.network,
            "state": record.state,  # string enums: written out as their values
            "fault": record.fault,
            "level": latest.level,
            "category": latest.category,
            "speed_kmh": latest.speed_kmh,
            "timestamp_s": latest.timestamp_s,
            "lane_id": record.lane_id,
            "street_name": lane.street_name,
            "road_type": lane.road_type,
            "heading_deg": latest.heading_deg,
            "curve_id": latest.curve_id,
            "warning_speed_kmh": latest.warning_speed_kmh,
            "answered_at_s": latest.answered_at_s,
        },
    }


async def _read(
    work: WorkThread, store: StateStore, prefix: str, after: str, count: int, names: list[str], bbox: Box | None
) -> list[PlacedSession]:
    """Up to ``count`` placed sessions after ``after`` from the store, on the work thread, in pieces of
    :data:`READ_PIECE`."""
    found: list[PlacedSession] = []
    while len(found) < count:
        wanted = min(READ_PIECE, count - len(found))
        piece = await work.run(store.placed, prefix, after, wanted, names, bbox)
        found += piece
        if len(piece) < wanted:
            break
        after = piece[-1].key
    return found


def _written_page(
    found: list[PlacedSession],
    limit: int,
    registry: VehicleRegistry,
    networks: Sequence[ServedNetwork],
    fleet: str,
    chosen: Sequence[int],
) -> bytes:
    """The page of the first ``limit`` of ``found`` as JSON (:class:`FleetPage`), its ``next_cursor`` set when
    ``found`` holds more."""
    page = found[:limit]
    features = [f for f in (_feature(each, registry, networks, fleet) for each in page) if f is not None]
    collection = feature_collection(features, [networks[i] for i in chosen])
    collection["generated_s"] = time.time()
    collection["next_cursor"] = encode_cursor(shown_id(fleet, page[-1].key)) if len(found) > limit else None
    return msgspec.json.encode(collection)


async def fleet_page(
    work: WorkThread,
    store: StateStore,
    registry: VehicleRegistry,
    networks: Sequence[ServedNetwork],
    fleet: str,
    bbox: Box | None,
    chosen: Sequence[int],
    after_id: str | None = None,
    limit: int = DEFAULT_PAGE_SIZE,
) -> bytes:
    """One page of the vehicles of ``fleet`` on the networks at ``chosen`` within ``bbox``, as the JSON of a
    GeoJSON FeatureCollection with the ``next_cursor`` of the page after it (:class:`FleetPage`).

    Parameters
    ----------
    work
        The work thread, which reads the store.
    store
        The state store, whose index of places is read.
    registry
        Decodes the sessions.
    networks
        The served networks.
    fleet
        The fleet that asks (``""`` on a service without keys).
    bbox
        min x, min y, max x, max y in each network's coordinates; None for everywhere.
    chosen
        The indices of the networks to show.
    after_id
        The page starts after this vehicle id (the previous page's cursor); None for the first page.
    limit
        The most vehicles in the page.

    Raises
    ------
    StoreUnavailable
        When the store cannot be read now.
    """
    after = "" if after_id is None else vehicle_key(fleet, after_id)
    names = [networks[i].name for i in chosen]
    found = await _read(work, store, vehicle_key(fleet, ""), after, limit + 1, names, bbox)
    return await run_in_threadpool(_written_page, found, limit, registry, networks, fleet, chosen)
