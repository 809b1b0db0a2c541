"""The HTTP contract as pydantic models: what a query looks like (the answers: :mod:`service.answer_schemas`).

Queries are validated strictly (numbers as JSON numbers, never strings or booleans; finite;
within their ranges; known categories) so that bad
input gets an HTTP 422 that names the query and the field. The service decodes bodies
with structs made from these models (:mod:`service.decoding`), which apply the same
constraints and the same checks (:func:`check_position`, :func:`check_located`).
"""

from __future__ import annotations

import difflib
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, TypeAdapter, field_validator, model_validator

from csws.standard import Category

#: Most queries one batch may hold: one fleet tick of a telematics backend.
MAX_BATCH = 10_000
#: Highest speed a query may report, km/h.
MAX_SPEED_KMH = 250.0
#: Most objects of the forward sensor one query may carry (a radar's or camera's track list).
MAX_OBJECTS = 32
#: Highest sensor object id (:data:`csws.fcw.objects.MAX_OBJECT_ID`: ids are taken in [0, 2^31)).
MAX_OBJECT_ID = 2**31 - 1
#: A vehicle id: 1 to 128 characters, none of them ``/`` (it would leave the path ``/v1/vehicles/{id}``)
#: or U+0000 (no store keeps it); the one rule for ids in bodies and in paths.
VEHICLE_ID_PATTERN = r"^[^/\x00]+$"


def check_position(position: Any) -> None:
    """A position is x and y (network metres) or lon and lat (degrees); ValueError otherwise.

    Takes anything with the fields of :class:`Position` (the model, or its decoding struct).
    """
    no_x, no_lon = position.x is None, position.lon is None
    if no_x != (position.y is None) or no_lon != (position.lat is None) or no_x == no_lon:
        given = [name for name in ("x", "y", "lon", "lat") if getattr(position, name) is not None]
        raise ValueError(
            f"a position is either x and y (network metres) or lon and lat (degrees), got {given or 'nothing'}"
        )


def check_objects(objects: Any) -> Any:
    """A query's objects have distinct ids, and each at most one of accel_mps2 and relative_accel_mps2;
    ValueError naming the ids otherwise. Returns ``objects``.

    Takes a list of anything with the fields of :class:`SensorObject` (the models, or their decoding structs).
    """
    if not objects:
        return objects
    ids = {obj.id for obj in objects}
    if len(ids) != len(objects):
        listed = [obj.id for obj in objects]
        duplicates = sorted({i for i in listed if listed.count(i) > 1})
        raise ValueError(f"object ids must be distinct within a query, got duplicate id(s) {duplicates}")
    both = [obj.id for obj in objects if obj.accel_mps2 is not None and obj.relative_accel_mps2 is not None]
    if both:
        raise ValueError(f"give accel_mps2 or relative_accel_mps2, not both (object id(s) {both})")
    return objects


def check_query(query: Any) -> None:
    """:func:`check_located` and :func:`check_objects` of a query (its decoding struct's checks)."""
    check_located(query)
    check_objects(query.objects)


def check_located(query: Any) -> None:
    """A query has a position, or a lane id with a lane position, or both; ValueError otherwise.

    Takes anything with the fields of :class:`Query` (the model, or its decoding struct).
    """
    if query.lane_id is None and query.position is None:
        raise ValueError("a query needs a position or a lane_id with lane_pos_m")
    if (query.lane_id is None) != (query.lane_pos_m is None):
        raise ValueError("lane_id and lane_pos_m go together: give both or neither")


class Position(BaseModel):
    """A fix: ``x``, ``y`` in network metres, or ``lon``, ``lat`` in degrees on geo-referenced networks."""

    model_config = ConfigDict(
        extra="forbid",
        allow_inf_nan=False,
        json_schema_extra={"examples": [{"x": 600.0, "y": 0.4}, {"lon": 9.7071, "lat": 50.8682}]},
    )

    x: float | None = Field(default=None, strict=True, description="network x, m")
    y: float | None = Field(default=None, strict=True, description="network y, m")
    lon: float | None = Field(default=None, ge=-180.0, le=180.0, strict=True, description="longitude, degrees (WGS84)")
    lat: float | None = Field(default=None, ge=-90.0, le=90.0, strict=True, description="latitude, degrees (WGS84)")

    @model_validator(mode="after")
    def _one_pair(self) -> Position:
        check_position(self)
        return self

    @property
    def is_geographic(self) -> bool:
        """Whether the fix is lon/lat."""
        return self.lon is not None


class ForwardTarget(BaseModel):
    """What the on-board forward sensor measures of the target vehicle (GB/T 33577 3.7-3.12): the
    service then answers the forward collision warning beside the curve warning."""

    model_config = ConfigDict(
        extra="forbid",
        allow_inf_nan=False,
        json_schema_extra={"examples": [{"range_m": 30.0, "range_rate_mps": -12.0, "target_accel_mps2": 0.0}]},
    )

    range_m: float = Field(ge=0.0, le=500.0, strict=True, description="clearance x_c to the target's rear, m")
    range_rate_mps: float = Field(
        ge=-100.0, le=100.0, strict=True, description="v_r = v_TV - v_SV, m/s (negative while closing)"
    )
    target_accel_mps2: float = Field(default=0.0, ge=-15.0, le=15.0, strict=True, description="a_TV, m/s^2")
    subject_accel_mps2: float = Field(default=0.0, ge=-15.0, le=15.0, strict=True, description="a_SV, m/s^2")
    driver_braking: bool = Field(default=False, strict=True, description="the driver brakes (4.5.4: T_resp = 0)")
    measured: bool = Field(
        default=True, strict=True, description="false when the sensor has no valid measurement: the FCW state is fault"
    )


class SensorObject(BaseModel):
    """One object of the forward sensor's track list, in the vehicle's frame (x ahead, y to the left; GB/T 33577
    3.7-3.12): the service then selects the target itself and keeps the warning's state between queries."""

    model_config = ConfigDict(
        allow_inf_nan=False,
        extra="forbid",
        json_schema_extra={
            "examples": [
                {"id": 7, "x_m": 35.0, "y_m": 0.2, "relative_speed_mps": -12.0, "accel_mps2": 0.0, "width_m": 1.8}
            ]
        },
    )

    id: int = Field(ge=0, le=MAX_OBJECT_ID, strict=True, description="the sensor's track id, distinct in a query")
    x_m: float = Field(
        ge=-50.0, le=500.0, strict=True, description="ahead, from the vehicle's front to the object's rear, m"
    )
    y_m: float = Field(ge=-100.0, le=100.0, strict=True, description="to the left, to the object's centre, m")
    relative_speed_mps: float = Field(
        ge=-100.0,
        le=100.0,
        strict=True,
        description="the object's longitudinal speed minus the vehicle's, m/s (v_r, negative while closing)",
    )
    accel_mps2: float | None = Field(
        default=None, ge=-15.0, le=15.0, strict=True, description="the object's own acceleration a_TV, m/s^2"
    )
    relative_accel_mps2: float | None = Field(
        default=None,
        ge=-30.0,
        le=30.0,
        strict=True,
        description="instead of accel_mps2: the object's acceleration minus the vehicle's, m/s^2 (neither: a_TV 0)",
    )
    width_m: float = Field(default=1.8, gt=0.0, le=10.0, strict=True, description="the object's width, m")
    lane: int | None = Field(
        default=None,
        ge=-8,
        le=8,
        strict=True,
        description="the sensor's lane assignment, 0 the vehicle's own, +1 left, -1 right; it then decides "
        "whether the object is in the path instead of the predicted path",
    )


class Query(BaseModel):
    """One vehicle at one instant: what it asks the service."""

    model_config = ConfigDict(
        extra="forbid",
        allow_inf_nan=False,
        json_schema_extra={
            "examples": [
                {
                    "vehicle_id": "truck-17",
                    "category": "N",
                    "speed_kmh": 80.0,
                    "position": {"x": 905.0, "y": 0.3},
                    "heading_deg": 90.0,
                    "timestamp_s": 1700000000.0,
                },
                {
                    "vehicle_id": "bus-3",
                    "category": "M3",
                    "speed_kmh": 60.0,
                    "lane_id": "approach_0",
                    "lane_pos_m": 850.0,
                    "route": ["approach", "curve", "runout"],
                    "forward_target": {"range_m": 30.0, "range_rate_mps": -12.0, "target_accel_mps2": 0.0},
                },
            ]
        },
    )

    vehicle_id: str = Field(
        min_length=1, max_length=128, pattern=VEHICLE_ID_PATTERN, description="the vehicle: no '/', no U+0000"
    )
    category: Category | None = Field(
        default=None,
        description="vehicle category (GB/T 15089); may be left out once set with PUT /v1/vehicles/{id}",
    )
    speed_kmh: float = Field(ge=0.0, le=MAX_SPEED_KMH, strict=True, description="speed V, km/h")
    position: Position | None = Field(default=None, description="the fix; optional when lane_id is given")
    heading_deg: float | None = Field(
        default=None, ge=0.0, lt=360.0, strict=True, description="GNSS heading, degrees clockwise from north"
    )
    accuracy_m: float | None = Field(
        default=None,
        gt=0.0,
        le=1000.0,
        strict=True,
        description="the fix's accuracy: one standard deviation of its position, m (HDOP times the receiver's "
        "error); map matching weighs the fix by it and looks for lanes within 2.5 of it (at least the tolerance)",
    )
    lane_id: str | None = Field(
        default=None, min_length=1, max_length=256, description="SUMO lane id: no map matching when given"
    )
    lane_pos_m: float | None = Field(default=None, ge=0.0, strict=True, description="lane position, m (with lane_id)")
    route: list[str] | None = Field(default=None, max_length=MAX_BATCH, description="route as edge ids")
    network: str | None = Field(
        default=None,
        min_length=1,
        max_length=256,
        description="the served network to answer on (its file name without .net.xml); by default the "
        "vehicle's last network, or for a fix the best match over all networks",
    )
    timestamp_s: float | None = Field(
        default=None, strict=True, description="when the fix was taken, s (any epoch; ordering only)"
    )
    age_s: float | None = Field(default=None, ge=0.0, strict=True, description="how old the fix is now, s")
    forward_target: ForwardTarget | None = Field(
        default=None, description="the forward sensor's target: the answer then carries the forward collision warning"
    )
    objects: list[SensorObject] | None = Field(
        default=None,
        max_length=MAX_OBJECTS,
        description=f"the forward sensor's objects (at most {MAX_OBJECTS}): the service selects the target and "
        "keeps the forward collision warning's state between queries; used instead of forward_target where both "
        "are given",
    )
    accel_mps2: float = Field(
        default=0.0, ge=-15.0, le=15.0, strict=True, description="the vehicle's longitudinal acceleration a_SV, m/s^2"
    )
    yaw_rate_dps: float | None = Field(
        default=None,
        ge=-180.0,
        le=180.0,
        strict=True,
        description="the vehicle's yaw rate, degrees/s, positive turning left: the path predicted from it where "
        "the query is not map-matched",
    )
    braking: bool = Field(default=False, strict=True, description="the driver brakes (4.5.4: T_resp = 0)")
    turn_signal: Literal[-1, 0, 1] = Field(
        default=0, description="-1 right, 0 none, +1 left: with a signal on, the map's path is not used"
    )

    @model_validator(mode="after")
    def _located(self) -> Query:
        check_located(self)
        return self

    @field_validator("objects")
    @classmethod
    def _distinct_objects(cls, objects: list[SensorObject] | None) -> list[SensorObject] | None:
        result: list[SensorObject] | None = check_objects(objects)
        return result


class Batch(BaseModel):
    """One fleet tick: up to 10,000 queries, answered in order."""

    model_config = ConfigDict(
        extra="forbid",
        json_schema_extra={
            "examples": [
                {
                    "queries": [
                        {
                            "vehicle_id": "truck-17",
                            "category": "N",
                            "speed_kmh": 80.0,
                            "position": {"x": 905.0, "y": 0.3},
                        },
                        {
                            "vehicle_id": "car-2",
                            "category": "M1",
                            "speed_kmh": 50.0,
                            "position": {"x": 100.0, "y": 0.0},
                        },
                    ]
                }
            ]
        },
    )

    queries: list[Query] = Field(max_length=MAX_BATCH, description=f"at most {MAX_BATCH} queries")


class VehicleSwitch(BaseModel):
    """The driver's switch (5.2) and the vehicle's category."""

    model_config = ConfigDict(extra="forbid", json_schema_extra={"examples": [{"switched_on": False, "category": "N"}]})

    switched_on: bool = Field(strict=True, description="CSWS on (true) or off (false)")
    category: Category | None = Field(default=None, description="the vehicle's category, used when a query has none")


class Message(BaseModel):
    """An answer that only says why: e.g. a vehicle the service does not know."""

    detail: str


BATCH_ADAPTER = TypeAdapter(Batch)
QUERY_ADAPTER = TypeAdapter(Query)
SWITCH_ADAPTER = TypeAdapter(VehicleSwitch)


#: The field names of every request body, for naming the one an unknown field was probably meant as.
REQUEST_FIELDS = frozenset(
    name
    for model in (Position, ForwardTarget, SensorObject, Query, Batch, VehicleSwitch)
    for name in model.model_fields
)


def unknown_field_message(name: str, known: frozenset[str] = REQUEST_FIELDS) -> str:
    """What a 422 says of a field the contract does not have: its name and the known field it
    most resembles, if one does (a typo such as ``heading`` for ``heading_deg`` would otherwise
    pass as if no heading were given)."""
    shown = name if len(name) <= 64 else name[:64] + "..."
    closest = difflib.get_close_matches(name, sorted(known), n=1, cutoff=0.6)
    return f"unknown field {shown!r}" + (f": did you mean {closest[0]!r}?" if closest else "")
