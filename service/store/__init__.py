"""The state store: the one place where every worker and replica of the service keeps its vehicles.

It holds, per vehicle (by its key, :func:`service.keys.vehicle_key`):

* its **setting**, what its fleet set with ``PUT /v1/vehicles/{id}``: the driver switch (5.2)
  and the category. Settings are kept until changed;
* its **session**, what answering its next fix needs (:mod:`service.vehicles` encodes it):
  the last matched lane, the system state, the release rule's memory. A session carries a
  **version**, raised by each write of it, and expires when it has not been written for the
  idle time;
* its **place**, where the live map shows it (:class:`Place`), written with its session and
  indexed, so that ``GET /v1/fleet`` reads a page of a fleet, or the vehicles in a box, without
  reading the others (:meth:`StateStore.placed`);
* its **events** (:mod:`service.events`), in the **outbox**: written in the transaction (SQLite) or
  script (Redis) of the session they came from, so that an acknowledged answer's events are kept
  and a write refused for a version conflict leaves none; numbered per vehicle (``seq``, from 1
  without gaps: the last number is kept per vehicle, beyond its session), read in outbox order per
  fleet (:meth:`StateStore.events_after`) or per vehicle by time (:meth:`StateStore.vehicle_events`),
  and kept for their fleet's retention time (:class:`EventRetention`; :data:`DEFAULT_EVENT_RETENTION_S`
  unless set), trimmed as the store writes.

Two backends implement :class:`StateStore`: SQLite in WAL mode (:mod:`service.store.sqlite`),
the embedded default for the workers of one machine, and Redis (:mod:`service.store.redis`),
for replicas on several machines. Each reads the vehicles of a request in one round trip
and writes them back in one (one transaction on SQLite, one server-side script on Redis).

A write is conditional per vehicle: a vehicle's session, setting and place are written together,
and only if its session still has the version read before; else nothing of that vehicle is
written and it is reported, so that the caller reads it again and redoes its work
(:meth:`service.vehicles.VehicleRegistry.transact`). Requests for one vehicle therefore
never overwrite one another's session.
"""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple

from csws.standard import Category

if TYPE_CHECKING:
    from service.settings import ServiceSettings

__all__ = [
    "STORE_TIMEOUT_S",
    "MAX_SESSION_IDLE_S",
    "DEFAULT_EVENT_RETENTION_S",
    "NewEvent",
    "StoredEvent",
    "checked_idle_s",
    "EventRetention",
    "StoreUnavailable",
    "VehicleSetting",
    "StoredVehicle",
    "NOTHING_STORED",
    "VehicleWrite",
    "Place",
    "PlacedSession",
    "Box",
    "prefix_end",
    "StateStore",
    "open_store",
]

#: How long one store operation may wait (for a lock, a connection, an answer), s: longer would
#: hold up every other request of the worker; the client is told to retry instead.
STORE_TIMEOUT_S = 0.5
#: The longest session idle time a store takes, s (366 days): Redis keeps a key's time to live as
#: whole milliseconds in a signed 64-bit integer, counted from now, and a setting that a store
#: cannot hold is refused at start rather than failing every write.
MAX_SESSION_IDLE_S = 366 * 86400.0
#: How long the outbox keeps an event by default, s (7 days): ``CSWS_EVENT_RETENTION_S``.
DEFAULT_EVENT_RETENTION_S = 7 * 86400.0


def checked_idle_s(idle_s: float) -> float:
    """``idle_s`` as a float if a store can hold it as a session idle time; ValueError otherwise."""
    if not 0.0 < idle_s <= MAX_SESSION_IDLE_S:
        raise ValueError(
            f"the session idle time must be positive and at most {MAX_SESSION_IDLE_S:.0f} s (366 days), "
            f"got {idle_s!r} s"
        )
    return float(idle_s)


class EventRetention:
    """How long the outbox keeps an event after it was written: a fleet's own time, else the service's.

    Parameters
    ----------
    default_s
        The service's retention time (``CSWS_EVENT_RETENTION_S``), s.
    fleets_s
        Fleets with a retention time of their own (``CSWS_EVENT_RETENTION_BY_FLEET``), s by fleet name.

    Raises
    ------
    ValueError
        If a time is not positive or longer than a store can hold (:data:`MAX_SESSION_IDLE_S`).
    """

    def __init__(
        self, default_s: float = DEFAULT_EVENT_RETENTION_S, fleets_s: Mapping[str, float] | None = None
    ) -> None:
        self.default_s = checked_idle_s(default_s)
        self.fleets_s = {fleet: checked_idle_s(s) for fleet, s in (fleets_s or {}).items()}

    def of(self, fleet: str) -> float:
        """The retention time of ``fleet``'s events, s."""
        return self.fleets_s.get(fleet, self.default_s)

    def of_key(self, vehicle_key: str) -> float:
        """The retention time of the events of the vehicle kept as ``vehicle_key``, s: its fleet's, the fleet being
        what comes before the key's first ``/`` (:func:`service.keys.vehicle_key`)."""
        fleet, slash, _ = vehicle_key.partition("/")
        return self.of(fleet if slash else "")

    @property
    def longest_s(self) -> float:
        """The longest retention time of any fleet, s: what an outbox of every fleet keeps."""
        return max([self.default_s, *self.fleets_s.values()])

    def __repr__(self) -> str:
        return f"EventRetention({self.default_s!r}, {self.fleets_s!r})"


class StoreUnavailable(OSError):
    """The state store cannot be read or written now (locked, unreachable, timed out, gone): retry later."""


@dataclass(frozen=True)
class VehicleSetting:
    """What a fleet set for a vehicle.

    Attributes
    ----------
    switched_on
        The CSWS switch (5.2).
    category
        The vehicle's category, used when a query gives none.
    """

    switched_on: bool = True
    category: Category | None = None


class StoredVehicle(NamedTuple):
    """What the store holds of one vehicle (a named tuple: a request reads thousands).

    Attributes
    ----------
    setting
        What its fleet set, None when nothing was ever set.
    session
        Its session as :mod:`service.vehicles` encoded it; None when it has none (or it expired).
    version
        The version of its session: 0 without one.
    event_seq
        The number of its last event (0 before its first): kept beyond its session, so that its events stay
        numbered without gaps when a new session starts.
    """

    setting: VehicleSetting | None = None
    session: bytes | None = None
    version: int = 0
    event_seq: int = 0


#: A vehicle the store holds nothing of.
NOTHING_STORED = StoredVehicle()


class Place(NamedTuple):
    """Where the live map shows a vehicle: its network and its point there, in the coordinates of the
    network's curves (lon/lat on geo-referenced networks, else network metres).

    Attributes
    ----------
    network
        The served network's name.
    x, y
        The point (longitude and latitude, degrees, or network metres).
    """

    network: str
    x: float
    y: float


#: min x, min y, max x, max y of a box, in the coordinates of :class:`Place`.
Box = tuple[float, float, float, float]


class PlacedSession(NamedTuple):
    """A live session found by its place (:meth:`StateStore.placed`).

    Attributes
    ----------
    key
        The vehicle's key.
    session
        Its session as :mod:`service.vehicles` encoded it.
    place
        Its place, as written with the session.
    """

    key: str
    session: bytes
    place: Place


class NewEvent(NamedTuple):
    """An event to put in the outbox with its vehicle's session.

    Attributes
    ----------
    fleet
        The vehicle's fleet: the stream it goes to.
    seq
        Its number among the vehicle's events.
    time_s
        Its time, s since the epoch: the history's order (:meth:`StateStore.vehicle_events`).
    body
        Its JSON (:func:`service.events.encode_event`).
    """

    fleet: str
    seq: int
    time_s: float
    body: bytes


class StoredEvent(NamedTuple):
    """An event as the outbox holds it.

    Attributes
    ----------
    cursor
        Its place in the outbox, opaque: the events after it are read with :meth:`StateStore.events_after`.
    vehicle_key
        Its vehicle's key (:func:`service.keys.vehicle_key`).
    body
        Its JSON.
    """

    cursor: str
    vehicle_key: str
    body: bytes


class VehicleWrite(NamedTuple):
    """What to write of one vehicle: its session, and with it a new setting if one was made, and its new
    place if it has one (a named tuple: a request writes thousands).

    Attributes
    ----------
    expected_version
        The version of the session the writer read: the write happens only if it is still that.
    session
        The new session, encoded; it is stored with the next version.
    setting
        A new setting to store together with the session, or None to keep the stored one.
    place
        Where the live map shows the vehicle now, or None to keep the stored place (a vehicle that
        never matched has none): the store indexes it for :meth:`StateStore.placed`.
    events
        The vehicle's new events, numbered on from its stored ``event_seq``, for the outbox.
    """

    expected_version: int
    session: bytes
    setting: VehicleSetting | None = None
    place: Place | None = None
    events: tuple[NewEvent, ...] = ()


def prefix_end(prefix: str) -> str | None:
    """The first string after every string that starts with ``prefix`` (in code point order, which is
    also the order of their UTF-8 bytes): keys of a prefix are those from ``prefix`` to it; None for
    the empty prefix, which every string starts with."""
    return prefix[:-1] + chr(ord(prefix[-1]) + 1) if prefix else None


class StateStore(ABC):
    """Settings and sessions of the vehicles, shared by every worker and replica.

    Attributes
    ----------
    name
        The store in messages: its file, or its URL without a password.
    """

    name: str

    @abstractmethod
    def check(self) -> None:
        """Make sure the store can serve, at start-up.

        Raises
        ------
        OSError
            One line naming the store, when it cannot be reached or read, or holds what it should not.
        """

    @abstractmethod
    def read(self, vehicle_ids: Collection[str]) -> dict[str, StoredVehicle]:
        """What the store holds of each vehicle (:data:`NOTHING_STORED` for one it holds nothing of),
        in one round trip, as of one instant.

        Raises
        ------
        StoreUnavailable
            When the store cannot be read now.
        """

    @abstractmethod
    def write(self, writes: Mapping[str, VehicleWrite]) -> set[str]:
        """Write each vehicle's session (and setting) whose session still has the expected version,
        all in one round trip; return the vehicles whose session another writer changed meanwhile
        (nothing of them was written).

        Raises
        ------
        StoreUnavailable
            When the store cannot be written now; then nothing was written.
        """

    @abstractmethod
    def placed(
        self, prefix: str, after: str, limit: int, networks: Collection[str], box: Box | None
    ) -> list[PlacedSession]:
        """The live sessions with a place, in the order of their keys: those whose key starts with
        ``prefix`` (a fleet's, see :func:`service.keys.vehicle_key`) and comes after ``after``, placed
        on one of ``networks`` within ``box`` (edges included; None for everywhere), at most ``limit``,
        as of one instant. The places are indexed, so that a box reads only what is in it.

        Raises
        ------
        StoreUnavailable
            When the store cannot be read now.
        """

    @abstractmethod
    def events_after(self, fleet: str | None, after: str | None, limit: int) -> list[StoredEvent]:
        """The events of ``fleet`` (None: of every fleet) in outbox order, strictly after the cursor ``after``
        (None: from the oldest retained), at most ``limit``.

        Raises
        ------
        ValueError
            When ``after`` is no cursor of this store.
        StoreUnavailable
            When the store cannot be read now.
        """

    @abstractmethod
    def vehicle_events(self, vehicle_key: str, since_s: float, limit: int) -> list[StoredEvent]:
        """The retained events of one vehicle whose time is at least ``since_s``, in the order of their times
        (then outbox order), at most ``limit``.

        Raises
        ------
        StoreUnavailable
            When the store cannot be read now.
        """

    @abstractmethod
    def session_count(self) -> int:
        """How many sessions the store holds (those not expired).

        Raises
        ------
        StoreUnavailable
            When the store cannot be read now.
        """

    @abstractmethod
    def close(self) -> None:
        """Let go of the store's connections."""


def open_store(settings: ServiceSettings, clock: Callable[[], float] = time.time) -> StateStore:
    """The store the settings name: Redis at ``settings.state`` if given, else the SQLite file ``settings.state_db``.

    Parameters
    ----------
    settings
        The service's settings (``state``, ``state_db``, ``session_idle_s``, ``event_retention_s``,
        ``event_retention_by_fleet``).
    clock
        Seconds of the clock that dates SQLite sessions (Redis expires its own).

    Raises
    ------
    OSError
        If the SQLite file cannot be opened.
    ValueError
        If the Redis URL is malformed.
    """
    if settings.state:
        from .redis import RedisStore

        return RedisStore(
            settings.state, settings.session_idle_s, settings.event_retention_s, settings.event_retention_by_fleet
        )
    from .sqlite import SQLiteStore

    return SQLiteStore(
        settings.state_db, settings.session_idle_s, clock, settings.event_retention_s, settings.event_retention_by_fleet
    )
