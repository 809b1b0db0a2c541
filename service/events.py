"""Warning events: what changed for a vehicle between two answers, as the outbox keeps it (docs/events.md).

An answer is compared with what the vehicle's session kept of the previous one (:class:`EventTrail`:
the curve warning's level, the system state, the forward collision warning's level, whether map
matching had failed); each change is an :class:`Event`:

* ``curve_onset``: the curve warning's level rose from 0 (6.1: a warning starts);
* ``curve_level``: it moved between 1 and 2 (6.1: the two levels told apart);
* ``curve_release``: it fell to 0 (the release rule let the warning go);
* ``fcw``: the forward collision warning's level changed;
* ``state``: the system state changed (off, standby, active, fault: 5.3-5.5);
* ``matching_fault``: the vehicle's position matched no lane of the map (the fault 5.4 indicates).

The functions here are pure: :mod:`service.vehicles` numbers the events (``seq``, per vehicle, from 1
without gaps) and hands them to the state store with the session they came from, in one write.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import msgspec

from .store import NewEvent

__all__ = [
    "CURVE_ONSET",
    "CURVE_LEVEL",
    "CURVE_RELEASE",
    "FCW",
    "STATE",
    "MATCHING_FAULT",
    "EVENT_KINDS",
    "Position",
    "Event",
    "EventTrail",
    "Observed",
    "changes",
    "answer_events",
    "observed_of",
    "fcw_events",
    "state_events",
    "encode_event",
    "numbered",
    "split_key",
]

CURVE_ONSET = "curve_onset"
CURVE_LEVEL = "curve_level"
CURVE_RELEASE = "curve_release"
FCW = "fcw"
STATE = "state"
MATCHING_FAULT = "matching_fault"
#: Every kind of event, in the order the events of one answer come.
EVENT_KINDS = (STATE, MATCHING_FAULT, CURVE_ONSET, CURVE_LEVEL, CURVE_RELEASE, FCW)
#: The fault code (:attr:`csws.state.Fault.code`) of a position that matches no lane.
NO_MAP_MATCH_CODE = "no_map_match"


class Position(msgspec.Struct, frozen=True, gc=False):
    """Where the vehicle was placed: network metres, and longitude/latitude on a geo-referenced network."""

    x: float
    y: float
    lon: float | None = None
    lat: float | None = None


class Event(msgspec.Struct, frozen=True, gc=False):
    """One event of a vehicle, as the outbox keeps it (JSON) and ``GET /v1/events`` sends it.

    ``level`` is the curve warning's level after the event, or for ``fcw`` the forward collision
    warning's; ``state`` the system state after it; ``time`` the fix's timestamp (the service's clock
    for a query without one), s since the epoch.
    """

    fleet: str
    vehicle_id: str
    seq: int
    kind: str
    time: float
    level: int
    state: str
    network: str | None = None
    curve_id: str | None = None
    object_id: int | None = None
    v_w_kmh: float | None = None
    s_w_m: float | None = None
    position: Position | None = None
    street: str | None = None
    fault_code: str | None = None


class EventTrail(msgspec.Struct, array_like=True, frozen=True, gc=False):
    """What a vehicle's session keeps of its last answer to tell the next one's events by.

    Attributes
    ----------
    level
        The curve warning's level (0, 1, 2).
    state
        The system state's value (``"off"``, ``"standby"``, ``"active"``, ``"fault"``).
    fcw_level
        The forward collision warning's level (0 without one).
    matching_fault
        Whether its position matched no lane.
    """

    level: int = 0
    state: str = "standby"
    fcw_level: int = 0
    matching_fault: bool = False


class Observed(NamedTuple):
    """What one answer said of a vehicle, as far as its events need.

    Attributes
    ----------
    time_s
        The fix's timestamp, else the service's clock, s since the epoch.
    level, state, fault_code
        The curve warning's level, the system state's value and its fault's code (None without a fault).
    curve_id, v_w_kmh, s_w_m
        The target curve (3.12), its warning speed V_w, km/h, and warning distance S_w, m (None without one).
    network, position, street
        Where it was placed (None where nothing matched).
    """

    time_s: float
    level: int
    state: str
    fault_code: str | None = None
    curve_id: str | None = None
    v_w_kmh: float | None = None
    s_w_m: float | None = None
    network: str | None = None
    position: Position | None = None
    street: str | None = None


def split_key(key: str) -> tuple[str, str]:
    """The fleet and the id of a vehicle kept as ``key`` (:func:`service.keys.vehicle_key`: neither has a ``/``)."""
    fleet, _, vehicle_id = key.rpartition("/")
    return fleet, vehicle_id


def _event(key: str, kind: str, observed: Observed, level: int, object_id: int | None = None) -> Event:
    """An event of ``kind`` told from ``observed`` (numbered 0 until :mod:`service.vehicles` gives it its ``seq``)."""
    fleet, vehicle_id = split_key(key)
    return Event(
        fleet,
        vehicle_id,
        0,
        kind,
        observed.time_s,
        level,
        observed.state,
        observed.network,
        observed.curve_id,
        object_id,
        observed.v_w_kmh,
        observed.s_w_m,
        observed.position,
        observed.street,
        observed.fault_code,
    )


def _curve_kind(before: int, after: int) -> str | None:
    """The kind of a change of the curve warning's level from ``before`` to ``after`` (None for none)."""
    if before == after:
        return None
    if before == 0:
        return CURVE_ONSET
    return CURVE_RELEASE if after == 0 else CURVE_LEVEL


def changes(trail: EventTrail, level: int, state: str, matching_fault: bool) -> bool:
    """Whether an answer at ``level`` in ``state`` (a :class:`csws.state.SystemState` is its value), its position
    matching no lane or not, changes the ``trail``: most do not, and need no :class:`Observed` told from them."""
    return level != trail.level or state != trail.state or matching_fault != trail.matching_fault


def answer_events(key: str, trail: EventTrail, observed: Observed) -> tuple[EventTrail, list[Event]]:
    """The events of an answer of the vehicle kept as ``key`` and the trail it leaves: a state change (5.3-5.5),
    a new map-matching fault (5.4), then a change of the curve warning's level (6.1), each at most once."""
    matching_fault = observed.fault_code == NO_MAP_MATCH_CODE
    if not changes(trail, observed.level, observed.state, matching_fault):
        return trail, []
    events = []
    if observed.state != trail.state:
        events.append(_event(key, STATE, observed, observed.level))
    if matching_fault and not trail.matching_fault:
        events.append(_event(key, MATCHING_FAULT, observed, observed.level))
    kind = _curve_kind(trail.level, observed.level)
    if kind is not None:
        events.append(_event(key, kind, observed, observed.level))
    return EventTrail(observed.level, observed.state, trail.fcw_level, matching_fault), events


def fcw_events(
    key: str, trail: EventTrail, level: int, object_id: int | None, observed: Observed
) -> tuple[EventTrail, list[Event]]:
    """The ``fcw`` event of a forward collision warning's answer at ``level`` (its target ``object_id``) when the
    level changed (4.5.5: the warning starts, rises or ends), and the trail it leaves; ``observed`` is the
    curve warning's answer to the same query."""
    if level == trail.fcw_level:
        return trail, []
    return msgspec.structs.replace(trail, fcw_level=level), [_event(key, FCW, observed, level, object_id)]


def state_events(key: str, trail: EventTrail, state: str, time_s: float) -> tuple[EventTrail, list[Event]]:
    """The ``state`` event of a vehicle whose system state became ``state`` without an answer (its driver
    switched it, 5.2), and the trail it leaves."""
    if state == trail.state:
        return trail, []
    observed = Observed(time_s, trail.level, state)
    return msgspec.structs.replace(trail, state=state), [_event(key, STATE, observed, trail.level)]


def observed_of(answer: Any, time_s: float) -> Observed:
    """What an answer said (the contract's WarningAnswer as :func:`service.encoding.encode_answer` builds it) at
    ``time_s``, as its events need."""
    target, matched = answer.target, answer.matched
    observed = Observed(time_s, int(answer.level), str(answer.state.value), answer.fault_code)
    if target is not None:
        observed = observed._replace(
            curve_id=target["curve_id"], v_w_kmh=target["warning_speed_kmh"], s_w_m=target["warning_distance_m"]
        )
    if matched is not None:
        point = matched.position
        position = Position(point["x"], point["y"], point.get("lon"), point.get("lat"))
        observed = observed._replace(network=matched.network, position=position, street=matched.street_name)
    return observed


_ENCODER = msgspec.json.Encoder()


def encode_event(event: Event, seq: int) -> bytes:
    """The JSON of ``event`` numbered ``seq``, as the outbox keeps it."""
    return _ENCODER.encode(msgspec.structs.replace(event, seq=seq))


def numbered(events: Sequence[Event], last_seq: int) -> tuple[NewEvent, ...]:
    """A vehicle's ``events`` numbered on from the number of its last one, ``last_seq``, for the outbox."""
    return tuple(
        NewEvent(event.fleet, seq, event.time, encode_event(event, seq))
        for seq, event in enumerate(events, last_seq + 1)
    )
