"""What the service keeps of a vehicle between its requests, and how: the session during a request
(:class:`Session`), the record the state store keeps of it (:class:`SessionRecord`, MessagePack), and
the parts of it the live map and the forward collision warning read (:class:`LatestAnswer`,
:class:`FcwMemory`). :mod:`service.vehicles` reads and writes them in the store."""

from __future__ import annotations

from dataclasses import dataclass, field

import msgspec

from csws.engine import VehicleMemory
from csws.road.hmm import MatchState
from csws.standard import Category
from csws.state import Fault, SystemState, VehicleStatus
from csws.warning.release import HeldWarning

from .events import Event, EventTrail

__all__ = ["LatestAnswer", "FcwMemory", "Session", "SessionRecord", "SESSION_ENCODER", "SESSION_DECODER"]


class LatestAnswer(msgspec.Struct, array_like=True, frozen=True, gc=False):
    """What the latest answer of a vehicle said, kept with its session for the live map (``GET /v1/fleet``)."""

    category: Category | None
    speed_kmh: float
    level: int
    timestamp_s: float | None
    #: The heading the vehicle sent, degrees from north (None when it sent none).
    heading_deg: float | None = None
    #: The target curve (3.12) and its V_w at the target's level, km/h; None without a warning.
    curve_id: str | None = None
    warning_speed_kmh: float | None = None
    #: When the service answered it, Unix time, s: the live map's age of the vehicle's last fix.
    answered_at_s: float | None = None


class FcwMemory(msgspec.Struct, array_like=True, frozen=True, gc=False):
    """What a vehicle's forward collision warning keeps between queries (one vehicle's
    :class:`csws.fcw.fleet.FleetMemory`), stored with its session.

    Attributes
    ----------
    state
        The system state's code (:data:`csws.fcw.state.FCW_STATES`): Figure 2's hysteresis starts from it.
    held_level, hold_until_s
        The level held and until when (the level's hold, :func:`csws.fcw.objects.hold_level`).
    last_time_s
        The time of its last frame, s: a query not after it changes nothing of this memory.
    in_path_ids, cut_in_ids
        The objects that were in the path, and those of them cutting in (4.5.5 c).
    target_id
        The last frame's target, None without one.
    """

    state: int
    held_level: int
    hold_until_s: float
    last_time_s: float
    in_path_ids: tuple[int, ...] = ()
    cut_in_ids: tuple[int, ...] = ()
    target_id: int | None = None


@dataclass(slots=True)
class Session:
    """A vehicle seen recently, during a request.

    Attributes
    ----------
    network_index
        The served network whose engine holds its memory.
    lane_id
        Its last matched lane, None when no fix of it matched yet.
    lane_pos_m
        Its position on that lane, m.
    latest
        What its latest answer said (the live map's view of it, ``GET /v1/fleet``).
    fcw
        What its forward collision warning keeps, None before its first query with objects.
    matching
        What map matching keeps of its fixes on the network ``network_index`` (:class:`csws.road.hmm.MatchState`),
        None before its first matched fix.
    trail
        What its last answer's events were told by (:mod:`service.events`).
    events
        The events of this request's answers of it, not yet numbered.
    """

    network_index: int
    lane_id: str | None
    lane_pos_m: float = 0.0
    latest: LatestAnswer | None = None
    fcw: FcwMemory | None = None
    matching: MatchState | None = None
    trail: EventTrail = EventTrail()
    events: list[Event] = field(default_factory=list)


class SessionRecord(msgspec.Struct, array_like=True, frozen=True, gc=False):
    """A session as the store keeps it: a MessagePack array of about 45 to 140 bytes."""

    network: str
    lane_id: str | None
    state: SystemState
    switched_on: bool
    activated: bool
    last_timestamp_s: float | None
    fault: Fault | None
    #: The release rule's CPOIs (curve id, part index) of level 1 and level 2.
    held_points: tuple[frozenset[tuple[str, int]], frozenset[tuple[str, int]]]
    held_kept_at_s: tuple[float | None, float | None]
    #: Where on ``lane_id`` it was last matched, m, and what its latest answer said (sessions written
    #: before these were kept have neither).
    lane_pos_m: float = 0.0
    latest: LatestAnswer | None = None
    #: The forward collision warning's memory (sessions of vehicles never queried with objects have none).
    fcw: FcwMemory | None = None
    #: The last intervals between its fixes, s, its update period is learnt from (:mod:`csws.warning.latency`).
    intervals_s: tuple[float, ...] = ()
    #: What map matching keeps of its fixes (sessions of vehicles never matched from a fix have none).
    matching: MatchState | None = None
    #: Where the release rule's CPOIs were at the last update, and that update's timestamp and speed
    #: (:class:`csws.warning.release.HeldWarning`; sessions written before these were kept have neither).
    held_places: tuple[tuple[str, int, float, float], ...] = ()
    held_seen: tuple[float, float] | None = None
    #: What its last answer's events were told by (sessions written before events were kept have none).
    trail: EventTrail | None = None

    def event_trail(self) -> EventTrail:
        """What the last answer's events were told by: as kept, else as the session's state and latest answer say."""
        if self.trail is not None:
            return self.trail
        return EventTrail(self.latest.level if self.latest is not None else 0, self.state.value)

    def memory(self) -> VehicleMemory:
        """What the engine keeps of the vehicle."""
        status = VehicleStatus(self.state, self.switched_on, self.activated, self.last_timestamp_s, self.fault)
        if not (self.held_points[0] or self.held_points[1]):
            return VehicleMemory(status, intervals_s=self.intervals_s)  # no level held: no release rule to take up
        held = HeldWarning(self.held_points, self.held_kept_at_s, self.held_places, self.held_seen)
        return VehicleMemory(status, held, self.intervals_s)

    @classmethod
    def of(cls, network: str, session: Session, memory: VehicleMemory) -> SessionRecord:
        status, held = memory.status, memory.held
        return cls(
            network,
            session.lane_id,
            status.state,
            status.switched_on,
            status.activated,
            status.last_timestamp_s,
            status.fault,
            held.points,
            held.kept_at_s,
            session.lane_pos_m,
            session.latest,
            session.fcw,
            memory.intervals_s,
            session.matching,
            held.places,
            held.seen,
            session.trail,
        )


#: Sessions to the bytes the store keeps, and back.
SESSION_ENCODER = msgspec.msgpack.Encoder()
SESSION_DECODER = msgspec.msgpack.Decoder(SessionRecord)
