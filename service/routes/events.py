"""``GET /v1/events``: a fleet's warning events as a live stream; ``GET /v1/vehicles/{id}/events``: a vehicle's history.

The stream is Server-Sent Events (``text/event-stream``) read from the state store's outbox
(:mod:`service.events`, :meth:`service.store.StateStore.events_after`): whichever worker or replica
serves it sends every event of the caller's fleet after the cursor once, in outbox order, each with
its cursor as its ``id:``. It starts after the ``Last-Event-ID`` header (what a browser's
``EventSource`` sends when it reconnects), else after ``?after=``, else at the oldest event retained.
It looks for new events every :data:`POLL_S` (an event is sent within about that of its answer),
sends a comment every :data:`KEEP_ALIVE_S` while there are none, and ends after ``?wait_s=`` (a bounded
request: a client reconnects, ``EventSource`` by itself after the ``retry:`` the stream gives). The
reads of the store run on the work thread, never on the event loop.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import AsyncIterator
from typing import Annotated, Any

import msgspec
from fastapi import APIRouter, Header, Query
from fastapi.exceptions import RequestValidationError
from fastapi.responses import Response, StreamingResponse
from pydantic import BaseModel, Field

from ..deps import CallerDep, StoreDep, WorkDep
from ..keys import vehicle_key
from ..store import StateStore, StoredEvent, StoreUnavailable
from ..work import WorkThread
from .common import KEYED, STORE
from .vehicles import VehicleId

__all__ = ["router", "POLL_S", "KEEP_ALIVE_S", "MAX_WAIT_S", "RETRY_MS", "EventDocument", "VehicleEvents"]

router = APIRouter(tags=["events"])

#: How often a stream looks for new events, s: an event reaches a client within about this of its answer.
POLL_S = 0.02
#: A stream without events sends a comment this often, s, so that proxies keep it open.
KEEP_ALIVE_S = 2.5
#: The longest a stream lasts, s (``?wait_s=``); its default.
MAX_WAIT_S = 5.0
DEFAULT_WAIT_S = 5.0
#: How long a browser's ``EventSource`` waits before it reconnects, ms (the stream's ``retry:``).
RETRY_MS = 500
#: The most events one read of the outbox takes, and one history page holds.
MAX_EVENTS = 1000
#: A cursor, as both stores write them (SQLite: the outbox key; Redis: a stream entry's id).
CURSOR_PATTERN = r"^[0-9]{1,20}(-[0-9]{1,20})?$"


class EventPosition(BaseModel):
    """Where the vehicle was placed: network metres, and lon/lat on a geo-referenced network."""

    x: float
    y: float
    lon: float | None
    lat: float | None


class EventDocument(BaseModel):
    """One warning event (docs/events.md)."""

    fleet: str = Field(description="the vehicle's fleet ('' on a service without API keys)")
    vehicle_id: str = Field(description="the vehicle, as its fleet calls it")
    seq: int = Field(ge=1, description="the event's number among its vehicle's, from 1 without gaps")
    kind: str = Field(
        description="curve_onset, curve_level, curve_release, fcw, state or matching_fault (docs/events.md)"
    )
    time: float = Field(description="the fix's timestamp, else when the service answered, s since the epoch")
    level: int = Field(ge=0, le=2, description="the curve warning's level after the event; for fcw the FCW's")
    state: str = Field(description="the system state after the event: off, standby, active or fault")
    network: str | None = Field(description="the served network the vehicle was placed on")
    curve_id: str | None = Field(description="the target curve (3.12)")
    object_id: int | None = Field(description="the forward collision warning's target object (fcw)")
    v_w_kmh: float | None = Field(description="the target curve's warning speed V_w, km/h")
    s_w_m: float | None = Field(description="the target curve's warning distance S_w, m")
    position: EventPosition | None = Field(description="where the vehicle was placed")
    street: str | None = Field(description="the street of its lane")
    fault_code: str | None = Field(description="the fault's code (5.4) in the fault state")


class VehicleEvents(BaseModel):
    """A vehicle's retained events from a time on."""

    vehicle_id: str
    events: list[EventDocument]


#: The 200 of the stream, documented as what it is.
_STREAM_RESPONSE: dict[int | str, dict[str, Any]] = {
    200: {
        "description": "Server-Sent Events: `id: CURSOR` and `data: EVENT` (one JSON EventDocument) per event, "
        "comments as keep-alives, then the end after wait_s",
        "content": {
            "text/event-stream": {
                "schema": {
                    "type": "object",
                    "description": "one Server-Sent Event: its id the event's cursor, its data one EventDocument",
                    "properties": {
                        "id": {"type": "string", "pattern": CURSOR_PATTERN},
                        "event": {"type": "string", "enum": ["message"]},
                        "data": {
                            "type": "string",
                            "contentMediaType": "application/json",
                            "contentSchema": {"$ref": "#/components/schemas/EventDocument"},
                        },
                    },
                    "required": ["id", "data"],
                }
            }
        },
    }
}


def _frame(event: StoredEvent) -> bytes:
    """One event as Server-Sent Events send it."""
    return b"id: " + event.cursor.encode() + b"\ndata: " + event.body + b"\n\n"


async def _read(work: WorkThread, store: StateStore, fleet: str, after: str | None) -> list[StoredEvent]:
    """The fleet's next events after ``after``, read on the work thread."""
    events: list[StoredEvent] = await work.run(store.events_after, fleet, after, MAX_EVENTS)
    return events


async def _stream(
    work: WorkThread, store: StateStore, fleet: str, first: list[StoredEvent], after: str | None, wait_s: float
) -> AsyncIterator[bytes]:
    """The stream: the events already read, then new ones as they come, until ``wait_s`` passed or the store
    cannot be read (the client resumes from the last ``id:``)."""
    end_s = time.monotonic() + wait_s
    yield f"retry: {RETRY_MS}\n\n".encode()
    events, quiet_since_s = first, time.monotonic()
    while True:
        if events:
            yield b"".join(_frame(event) for event in events)
            after, quiet_since_s = events[-1].cursor, time.monotonic()
        elif time.monotonic() - quiet_since_s >= KEEP_ALIVE_S:
            yield b": keep-alive\n\n"
            quiet_since_s = time.monotonic()
        if time.monotonic() >= end_s:
            return  # even behind: the client reads on from its last id
        if len(events) < MAX_EVENTS:
            await asyncio.sleep(min(POLL_S, max(0.0, end_s - time.monotonic())))
        try:
            events = await _read(work, store, fleet, after)
        except StoreUnavailable:
            return


@router.get(
    "/v1/events",
    summary="The caller's fleet's warning events as they happen (Server-Sent Events)",
    response_class=StreamingResponse,
    responses={**_STREAM_RESPONSE, **KEYED, **STORE},
)
async def events(
    principal: CallerDep,
    store: StoreDep,
    work: WorkDep,
    after: Annotated[
        str | None, Query(pattern=CURSOR_PATTERN, description="resume after this cursor (an event's id)")
    ] = None,
    wait_s: Annotated[float, Query(ge=0.0, le=MAX_WAIT_S, description="end the stream after this long, s")] = (
        DEFAULT_WAIT_S
    ),
    last_event_id: Annotated[
        str | None,
        Header(alias="Last-Event-ID", pattern=CURSOR_PATTERN, description="resume after this cursor (EventSource)"),
    ] = None,
) -> StreamingResponse:
    """The warning events of the caller's fleet after the cursor (``Last-Event-ID``, else ``after``, else the
    oldest retained), in outbox order, each once, then the new ones as they are written, for ``wait_s``."""
    cursor = last_event_id if last_event_id is not None else after
    try:
        first = await _read(work, store, principal.fleet, cursor)
    except ValueError as exc:
        where = ("header", "Last-Event-ID") if last_event_id is not None else ("query", "after")
        raise RequestValidationError([{"loc": where, "msg": str(exc), "type": "value_error"}]) from None
    return StreamingResponse(
        _stream(work, store, principal.fleet, first, cursor, wait_s),
        media_type="text/event-stream",
        headers={"Cache-Control": "no-store", "X-Accel-Buffering": "no"},
    )


@router.get(
    "/v1/vehicles/{vehicle_id}/events",
    summary="A vehicle's warning events from a time on (its history)",
    response_model=None,
    responses={200: {"model": VehicleEvents}, **KEYED, **STORE},
)
async def vehicle_events(
    principal: CallerDep,
    vehicle_id: VehicleId,
    store: StoreDep,
    work: WorkDep,
    since: Annotated[
        float, Query(ge=0.0, le=1e11, description="the earliest event time, s since the epoch (events at it included)")
    ] = 0.0,
    limit: Annotated[int, Query(ge=1, le=MAX_EVENTS, description="the most events answered")] = 100,
) -> Response:
    """The retained events of a vehicle of the caller's fleet whose time is ``since`` or later, by time, at most
    ``limit`` (none for a vehicle without events); page on from the last one's time, leaving out the ``seq``
    already seen."""
    found: list[StoredEvent] = await work.run(
        store.vehicle_events, vehicle_key(principal.fleet, vehicle_id), since, limit
    )
    body = b'{"vehicle_id":%s,"events":[%s]}' % (msgspec.json.encode(vehicle_id), b",".join(e.body for e in found))
    return Response(body, media_type="application/json")
