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
from typing import TypeVar

import msgspec

from csws.engine import Engine, VehicleMemory
from csws.road.hmm import Track
from csws.standard import Category
from csws.state import VehicleStatus, switch

from .events import EventTrail, Observed, answer_events, fcw_events, numbered, state_events
from .places import shown_places
from .sessions import SESSION_DECODER, SESSION_ENCODER, LatestAnswer, Session, SessionRecord
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

__all__ = ["TRANSACTION_ATTEMPTS", "LoadedVehicles", "VehicleRegistry"]

#: How many times in all a request reads, answers and writes the vehicles other requests wrote
#: meanwhile before it gives up with a 503. One vehicle's fixes sent at once through two workers,
#: each written, needed a second attempt for about one answer in eight and a fourth for one in four
#: hundred (400 answers counted on a machine with two busy cores); a worker short of CPU loses more
#: in a row (five in a row were seen with the test suite running beside it), so the budget leaves
#: room for twice that.
TRANSACTION_ATTEMPTS = 10

Answered = TypeVar("Answered")


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
        stored, new_settings, encode = self.stored, self.new_settings, SESSION_ENCODER.encode
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
            record = SESSION_DECODER.decode(session)
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
