"""What the service keeps of each vehicle between requests, kept in the state store (:mod:`service.store`).

* Its **setting**: what its fleet set, the driver switch (5.2) and the category; kept until changed.
* Its **session**: the network and lane of its last match, what map matching keeps of its
  fixes (:class:`csws.road.hmm.MatchState`: the sequence its next fix continues), what the
  engine keeps of it (:class:`csws.engine.VehicleMemory`: system state and activation, last
  timestamp, the release rule's memory), and what its forward collision warning keeps
  (:class:`FcwMemory`: state, level hold, objects in the path, last target), and what its
  events are told by (:class:`service.events.EventTrail`: the last level, state and FCW level).
  A vehicle that moves to another network takes its system state along. A session not written for the idle time expires;
  the stored setting remains.

A request does not rely on anything its worker remembers: it reads the vehicles it names from
the store (one round trip), puts their memories into the engines, is answered, and writes the
sessions back (one round trip); the engines hold a vehicle only during a request. The write
of a vehicle happens only if no other request wrote its session since it was read; a vehicle
another request got to first is read and answered again (:meth:`VehicleRegistry.transact`).
So the requests of one vehicle are answered one after the other, each from the session the
previous one left, whichever worker or replica serves each.

Each answer that changes what the trail kept becomes events (:mod:`service.events`), numbered on
from the last number the store kept of the vehicle and written with its session: a vehicle answered
again after a conflict is numbered again from what it reads then, so its numbers have no gaps.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass, field
from typing import TypeVar

import msgspec

from csws.engine import Engine, VehicleMemory
from csws.road.hmm import MatchState, Track
from csws.standard import Category
from csws.state import Fault, SystemState, VehicleStatus, switch
from csws.warning.release import HeldWarning

from .events import Event, EventTrail, Observed, answer_events, fcw_events, numbered, state_events
from .places import shown_places
from .store import (
    NOTHING_STORED,
    Place,
    StateStore,
    StoredVehicle,
    StoreUnavailable,
    VehicleSetting,
    VehicleWrite,
)
from .timing import UNTIMED, Stages

__all__ = [
    "TRANSACTION_ATTEMPTS",
    "Session",
    "LatestAnswer",
    "FcwMemory",
    "SessionRecord",
    "LoadedVehicles",
    "VehicleRegistry",
]

#: How often a request reads and answers again the vehicles other requests wrote meanwhile
#: before it gives up with a 503.
TRANSACTION_ATTEMPTS = 5

Answered = TypeVar("Answered")


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
        The system state's code (:data:`csws.fcw.physics.FCW_STATES`): Figure 2's hysteresis starts from it.
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


_ENCODER = msgspec.msgpack.Encoder()
_DECODER = msgspec.msgpack.Decoder(SessionRecord)


class LoadedVehicles:
    """The vehicles of one request as the store had them, their memories in the engines until :meth:`close`.

    Parameters
    ----------
    registry
        The engines and the networks' names.
    stored
        What the store holds of each vehicle of the request.
    """

    def __init__(self, registry: VehicleRegistry, stored: dict[str, StoredVehicle]) -> None:
        self.engines = registry.engines
        self.network_names = registry.network_names
        self.stored = stored
        self.sessions: dict[str, Session] = {}
        self.new_settings: dict[str, VehicleSetting] = {}
        self.written: set[str] = set()
        #: What map matching kept of the vehicles' fixes of this request, until each is :meth:`seen`.
        self.tracks: dict[str, Track | None] = {}
        #: Where each vehicle with a session was as read (network, lane, lane position): its place is
        #: written again only when that changed.
        self.read_lanes: dict[str, tuple[int, str | None, float]] = {}
        for vehicle_id, vehicle in stored.items():
            record = registry.decode(vehicle.session)
            if record is not None:
                network_index = registry.network_index[record.network]
                self.sessions[vehicle_id] = Session(
                    network_index,
                    record.lane_id,
                    record.lane_pos_m,
                    record.latest,
                    record.fcw,
                    record.matching,
                    record.event_trail(),
                )
                self.read_lanes[vehicle_id] = (network_index, record.lane_id, record.lane_pos_m)
                self.engines[network_index].restore(vehicle_id, record.memory())

    def __enter__(self) -> LoadedVehicles:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Take the vehicles out of the engines."""
        for vehicle_id, session in self.sessions.items():
            self.engines[session.network_index].forget(vehicle_id)

    def setting(self, vehicle_id: str) -> VehicleSetting | None:
        """What the fleet set for the vehicle, if anything."""
        return self.new_settings.get(vehicle_id) or self.stored.get(vehicle_id, NOTHING_STORED).setting

    def category(self, vehicle_id: str) -> Category | None:
        """The category the fleet set for the vehicle, if any."""
        setting = self.setting(vehicle_id)
        return setting.category if setting is not None else None

    def session(self, vehicle_id: str) -> Session | None:
        """The vehicle's session, if it has one."""
        return self.sessions.get(vehicle_id)

    def track(self, vehicle_id: str) -> Track | None:
        """What map matching keeps of the vehicle's fixes, if anything: as this request's last fix of it left it,
        else as its session has it."""
        if vehicle_id in self.tracks:
            return self.tracks[vehicle_id]
        session = self.sessions.get(vehicle_id)
        if session is None or session.matching is None:
            return None
        return Track(session.network_index, session.matching)

    def keep_track(self, vehicle_id: str, track: Track | None) -> None:
        """What map matching keeps of the vehicle's latest fix: its session takes it when it is :meth:`seen`."""
        self.tracks[vehicle_id] = track

    def network_of(self, vehicle_id: str) -> int:
        """The network whose engine holds the vehicle's memory (the first for a new vehicle)."""
        session = self.sessions.get(vehicle_id)
        return session.network_index if session is not None else 0

    def place(self, vehicle_id: str, network_index: int) -> None:
        """Make sure the vehicle has a session on ``network_index`` before its engine evaluates it.

        A new session starts from the stored switch; a vehicle that moved to another
        network takes its system state and its fix intervals along (not the warning memory of the
        other map's curves).
        """
        session = self.sessions.get(vehicle_id)
        if session is None:
            self.sessions[vehicle_id] = Session(network_index, None)
            setting = self.setting(vehicle_id)
            if setting is not None and not setting.switched_on:
                self.engines[network_index].switch(vehicle_id, False)
        elif session.network_index != network_index:
            memory = self.engines[session.network_index].memory(vehicle_id)
            self.engines[session.network_index].forget(vehicle_id)
            self.engines[network_index].restore(
                vehicle_id, VehicleMemory(memory.status, intervals_s=memory.intervals_s)
            )
            session.network_index = network_index

    def seen(
        self, vehicle_id: str, lane_id: str | None, lane_pos_m: float = 0.0, latest: LatestAnswer | None = None
    ) -> Session:
        """Record that a vehicle (placed by :meth:`place`) was just answered, its lane and lane position if
        it matched one, and what its answer said; its session.

        A fix that matched nothing keeps the last matched lane, so one bad fix does not
        break the continuity of the next. Its session is written back at the end of the request.
        """
        session = self.sessions[vehicle_id]
        if vehicle_id in self.tracks:
            track = self.tracks[vehicle_id]
            session.matching = track.state if track is not None and track.map_index == session.network_index else None
        if lane_id is not None:
            session.lane_id, session.lane_pos_m = lane_id, lane_pos_m
        if latest is not None:
            session.latest = latest
        self.written.add(vehicle_id)
        return session

    def trail(self, vehicle_id: str) -> EventTrail:
        """What the vehicle's events are told by now (a vehicle :meth:`place` placed)."""
        return self.sessions[vehicle_id].trail

    def observe(self, vehicle_id: str, observed: Observed) -> None:
        """Note the events of an answer of the vehicle (placed by :meth:`place`), written with its session."""
        session = self.sessions[vehicle_id]
        session.trail, events = answer_events(vehicle_id, session.trail, observed)
        session.events += events

    def observe_fcw(self, vehicle_id: str, level: int, object_id: int | None, observed: Observed) -> None:
        """Note the event of a forward collision warning's answer of the vehicle at ``level`` (target ``object_id``)
        whose curve warning's answer was ``observed``."""
        session = self.sessions[vehicle_id]
        session.trail, events = fcw_events(vehicle_id, session.trail, level, object_id, observed)
        session.events += events

    def configure(self, vehicle_id: str, switched_on: bool, category: Category | None) -> None:
        """Set a vehicle's switch (5.2) and category; both are stored with its session."""
        previous = self.setting(vehicle_id) or VehicleSetting()
        self.new_settings[vehicle_id] = VehicleSetting(switched_on, category or previous.category)
        network_index = self.network_of(vehicle_id)
        self.place(vehicle_id, network_index)
        self.seen(vehicle_id, None)
        self.engines[network_index].switch(vehicle_id, switched_on)

    def known(self, vehicle_id: str) -> bool:
        """Whether the vehicle has a session or a stored setting."""
        return vehicle_id in self.sessions or self.setting(vehicle_id) is not None

    def status(self, vehicle_id: str) -> VehicleStatus:
        """The vehicle's status: from its engine, or the stored switch when it has no session."""
        session = self.sessions.get(vehicle_id)
        if session is not None:
            return self.engines[session.network_index].status(vehicle_id)
        return switch(VehicleStatus(), (self.setting(vehicle_id) or VehicleSetting()).switched_on)

    def writes(self) -> dict[str, VehicleWrite]:
        """What to store of the vehicles this request answered or set."""
        writes = {}
        stored, new_settings, encode = self.stored, self.new_settings, _ENCODER.encode
        places = self._places()
        for vehicle_id in self.written:
            session = self.sessions[vehicle_id]
            memory = self.engines[session.network_index].memory(vehicle_id)
            if memory.status.state != session.trail.state:  # switched without an answer (5.2): a StrEnum
                session.trail, events = state_events(vehicle_id, session.trail, memory.status.state.value, time.time())
                session.events += events
            record = SessionRecord.of(self.network_names[session.network_index], session, memory)
            vehicle = stored.get(vehicle_id, NOTHING_STORED)
            writes[vehicle_id] = VehicleWrite(
                vehicle.version,
                encode(record),
                new_settings.get(vehicle_id),
                places.get(vehicle_id),
                numbered(session.events, vehicle.event_seq) if session.events else (),
            )
        return writes

    def _places(self) -> dict[str, Place]:
        """Where the live map shows the vehicles to write that it shows (``GET /v1/fleet``): those matched
        to a lane of their network and answered at least once, whose lane position changed since they were
        read (a vehicle standing still keeps the place stored; one whose session was written before places
        were kept gets its place when it next moves)."""
        road_maps = [engine.road_map for engine in self.engines]
        lanes = {}
        for vehicle_id in self.written:
            session = self.sessions[vehicle_id]
            road_map = road_maps[session.network_index]
            if session.lane_id is None or session.latest is None or road_map is None:
                continue
            lane = (session.network_index, session.lane_id, session.lane_pos_m)
            if self.read_lanes.get(vehicle_id) != lane and road_map.has_lane(session.lane_id):
                lanes[vehicle_id] = lane
        return shown_places(road_maps, self.network_names, lanes)


class VehicleRegistry:
    """The vehicles of the served networks' engines, kept in a state store.

    Parameters
    ----------
    network_names
        The served networks' names, in the served order (sessions name their network).
    engines
        One engine per served network, in the same order.
    store
        Where settings and sessions are kept.
    """

    def __init__(self, network_names: Sequence[str], engines: Sequence[Engine], store: StateStore) -> None:
        self.network_names = tuple(network_names)
        self.network_index = {name: index for index, name in enumerate(self.network_names)}
        self.engines = tuple(engines)
        self.store = store

    def decode(self, session: bytes | None) -> SessionRecord | None:
        """A stored session; None for none, and for one this service cannot take up (written by
        another version of it, or naming a network it does not serve): the vehicle starts afresh."""
        if session is None:
            return None
        try:
            record = _DECODER.decode(session)
        except msgspec.MsgspecError:
            return None
        return record if record.network in self.network_index else None

    def read(self, vehicle_ids: Collection[str]) -> LoadedVehicles:
        """The vehicles as the store has them, for a request that writes nothing (use as a context manager).

        Raises
        ------
        StoreUnavailable
            When the store cannot be read now.
        """
        return LoadedVehicles(self, self.store.read(vehicle_ids))

    def transact(
        self,
        vehicle_ids: Collection[str],
        work: Callable[[LoadedVehicles, Collection[str]], Answered],
        stages: Stages = UNTIMED,
    ) -> Answered:
        """Read the vehicles, do ``work`` on them, write back what it changed; for vehicles whose
        session another request wrote in the meantime, read them again and redo ``work`` on them
        alone, until none is left.

        Parameters
        ----------
        vehicle_ids
            The vehicles of the request.
        work
            Called with the loaded vehicles and the ids it is to work on (all at first).
        stages
            Where the time of reading (``read``) and writing (``write``) the vehicles is counted.

        Returns
        -------
        What the last call of ``work`` returned.

        Raises
        ------
        StoreUnavailable
            When the store cannot be read or written now, or other requests still wrote some
            of the vehicles after :data:`TRANSACTION_ATTEMPTS` attempts.
        """
        pending = set(vehicle_ids)
        for _attempt in range(TRANSACTION_ATTEMPTS):
            with stages("read"):
                vehicles = self.read(pending)
            try:
                answered = work(vehicles, pending)
                with stages("write"):
                    pending = self.store.write(vehicles.writes())
            finally:
                vehicles.close()
            if not pending:
                return answered
        raise StoreUnavailable(
            f"{len(pending)} vehicle(s) were changed by other requests during each of {TRANSACTION_ATTEMPTS} attempts"
        )
