"""Traccar's position forwarding, taken as it is sent: one forwarded position becomes one query.

Traccar (``forward.type=json``) POSTs each decoded position with its device as
``{"position": {...}, "device": {...}}``: latitude/longitude in degrees, ``speed`` in knots,
``course`` in degrees clockwise from north, ``fixTime`` in ISO 8601, ``valid`` and ``outdated``
flags, ``accuracy`` in metres (0 where the device gave none), and free ``attributes``. The
mapping:

* vehicle id: ``device.uniqueId`` (the device's identifier, e.g. its IMEI), or ``device.name``
  when the route is asked with ``?vehicle_id=name``;
* category (GB/T 15089): the device attribute ``cswsCategory`` (``M1``, ``M2``, ``M3``, ``N``,
  ``O``) if set, else from Traccar's device category (:data:`TRACCAR_CATEGORIES`), else the
  category set with ``PUT /v1/vehicles/{id}``; a device with none of these is a 422 that says so;
* speed: knots to km/h; heading: ``course`` (none when the position has no course); timestamp:
  ``fixTime``, its age at arrival (under :data:`MAX_AGE_S`) given to the latency allowance;
  accuracy: ``accuracy`` when above 0.

Positions Traccar marks invalid (``valid: false``, no satellite fix) or outdated (``outdated:
true``, a repeat of an old fix) are not evaluated: a warning from them would be about where the
vehicle was, not where it is. The route answers them 202 with the reason, so Traccar does not
retry them.
"""

from __future__ import annotations

from datetime import datetime
from enum import StrEnum
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from csws.standard import Category

from .decoding import DecodedPosition, DecodedQuery
from .schemas import MAX_SPEED_KMH, VEHICLE_ID_PATTERN

__all__ = [
    "KNOT_KMH",
    "MAX_AGE_S",
    "TRACCAR_CATEGORIES",
    "Ignored",
    "IdSource",
    "TraccarDevice",
    "TraccarForward",
    "TraccarPosition",
    "query_of",
]

#: One knot in km/h (Traccar's speeds are knots).
KNOT_KMH = 1.852
#: A position older than this when it arrives is not given to the latency allowance, s: a device
#: clock that is off, or a position Traccar sends late, would otherwise push the warning forward.
MAX_AGE_S = 30.0
#: Traccar's device categories that name a vehicle of the standard's scope, and their GB/T 15089
#: category: cars M1; vans, pickups, trucks, tractors (road tractors) and cranes N; buses and
#: trolleybuses M3. Other categories (people, bicycles, boats, planes, ...) name none.
TRACCAR_CATEGORIES = {
    "car": Category.M1,
    "van": Category.N,
    "pickup": Category.N,
    "truck": Category.N,
    "tractor": Category.N,
    "crane": Category.N,
    "bus": Category.M3,
    "trolleybus": Category.M3,
}
#: The device attribute that sets the category directly.
CATEGORY_ATTRIBUTE = "cswsCategory"


class IdSource(StrEnum):
    """Which device field is the vehicle id."""

    UNIQUE_ID = "uniqueId"
    NAME = "name"


class TraccarPosition(BaseModel):
    """The fields of a Traccar position that csws reads; the others are accepted and left alone."""

    model_config = ConfigDict(extra="ignore")

    latitude: float = Field(ge=-90.0, le=90.0, description="degrees (WGS84)")
    longitude: float = Field(ge=-180.0, le=180.0, description="degrees (WGS84)")
    speed: float = Field(default=0.0, ge=0.0, le=MAX_SPEED_KMH / KNOT_KMH, description="knots")
    course: float | None = Field(default=None, ge=0.0, le=360.0, description="degrees clockwise from north")
    fixTime: datetime | None = Field(default=None, description="when the fix was taken (ISO 8601)")
    valid: bool = Field(default=True, description="false: the device had no valid fix")
    outdated: bool = Field(default=False, description="true: the device repeated an old position")
    accuracy: float | None = Field(default=None, ge=0.0, description="metres; 0 where the device gave none")


class TraccarDevice(BaseModel):
    """The fields of a Traccar device that csws reads."""

    model_config = ConfigDict(extra="ignore")

    uniqueId: str = Field(min_length=1, description="the device's identifier")
    name: str | None = None
    category: str | None = Field(default=None, description="Traccar's device category (car, truck, bus, ...)")
    attributes: dict[str, Any] = Field(default_factory=dict)


class TraccarForward(BaseModel):
    """What Traccar's JSON position forwarding sends: a position and its device."""

    model_config = ConfigDict(
        extra="ignore",
        json_schema_extra={
            "examples": [
                {
                    "position": {
                        "latitude": 50.8682,
                        "longitude": 9.7071,
                        "speed": 27.0,
                        "course": 90.0,
                        "fixTime": "2026-11-26T02:00:00.000+00:00",
                        "valid": True,
                        "outdated": False,
                        "accuracy": 4.0,
                    },
                    "device": {"uniqueId": "866123456789012", "name": "truck-18", "category": "truck"},
                }
            ]
        },
    )

    position: TraccarPosition
    device: TraccarDevice


class Ignored(BaseModel):
    """A forwarded position that was not evaluated, and why."""

    ignored: Literal["invalid", "outdated"] = Field(description="why it was not evaluated")
    message: str


def _category(device: TraccarDevice) -> Category | None:
    """The device's category: its ``cswsCategory`` attribute, else from Traccar's category; None if neither says."""
    explicit = device.attributes.get(CATEGORY_ATTRIBUTE)
    if isinstance(explicit, str):
        try:
            return Category.parse(explicit)
        except ValueError:
            return None
    return TRACCAR_CATEGORIES.get((device.category or "").lower())


def query_of(forward: TraccarForward, id_source: IdSource, now_s: float) -> DecodedQuery | Ignored:
    """The query of a forwarded position, or why it is not evaluated.

    Raises
    ------
    ValueError
        If the device's id (by ``id_source``) is missing or not a valid vehicle id.
    """
    position, device = forward.position, forward.device
    if not position.valid:
        return Ignored(ignored="invalid", message="Traccar marks the position invalid (no valid fix)")
    if position.outdated:
        return Ignored(ignored="outdated", message="Traccar marks the position outdated (a repeat of an old fix)")
    vehicle_id = device.uniqueId if id_source is IdSource.UNIQUE_ID else device.name
    if not vehicle_id or len(vehicle_id) > 128 or "/" in vehicle_id or "\x00" in vehicle_id:
        raise ValueError(f"device.{id_source.value} must be a vehicle id (1-128 characters, {VEHICLE_ID_PATTERN})")
    timestamp_s = position.fixTime.timestamp() if position.fixTime is not None else None
    age_s = now_s - timestamp_s if timestamp_s is not None else None
    return DecodedQuery(
        vehicle_id=vehicle_id,
        category=_category(device),
        speed_kmh=position.speed * KNOT_KMH,
        position=DecodedPosition(lon=position.longitude, lat=position.latitude),
        heading_deg=position.course % 360.0 if position.course is not None else None,
        accuracy_m=min(position.accuracy, 1000.0) if position.accuracy else None,
        timestamp_s=timestamp_s,
        age_s=age_s if age_s is not None and 0.0 <= age_s <= MAX_AGE_S else None,
    )
