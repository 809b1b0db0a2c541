"""The state store in Redis: for replicas of the service on several machines.

Keys, in the database the URL names (``redis://HOST:PORT/DB``; give the service a database of
its own):

* ``csws:setting:{vehicle}``: ``1`` or ``0`` (the switch) followed by the category, if set;
  no expiry;
* ``csws:session:{vehicle}``: ``{version}|{session}``, expiring ``session_idle_s`` after its
  last write (Redis's key TTL: nothing to sweep);
* ``csws:places``: a hash of the vehicles' places, ``{network}|{x}|{y}`` by vehicle;
  ``csws:placed``: their vehicles in a sorted set of equal scores, so in key order
  (``ZRANGEBYLEX`` reads a fleet's keys from a cursor on); and ``csws:grid:{network}``, the
  spatial index: the network's vehicles in a sorted set scored by their cell (:func:`place_cell`).
  All are written with the session (a vehicle that moves has its score changed, one that changes
  network leaves the other network's set); a vehicle whose session expired leaves them when a read
  of places meets it, or checks it on its sweep (:data:`PLACES_SWEPT_PER_READ` vehicles per read,
  round and round the placed set from ``csws:places-swept``). The places a store without the index
  wrote are indexed once, at start-up (:meth:`RedisStore.check`), which then sets ``csws:grid-built``;
* the outbox (:mod:`service.events`): ``csws:outbox``, a stream of every fleet's events, and
  ``csws:outbox:{fleet}``, one per fleet, each event added to both under the same id (its cursor),
  trimmed as events are added (``MINID``): a fleet's stream to the fleet's retention time, the
  stream of every fleet to the longest (:class:`service.store.EventRetention`);
  ``csws:history:{vehicle}``, a vehicle's events in a sorted set by their times (``{id}|{event}``
  each, the id's sequence number zero-padded so that events of one time sort in outbox order), whose
  earliest entries written before its fleet's retention time are taken out as events are added, and
  deleted (a few per write) once its last event is past its fleet's retention time, which the sorted
  set ``csws:histories`` tells (scored by when that last event was written, plus its fleet's
  retention time less the longest: a score older than the longest retention time marks a history
  past its own); ``csws:event-seq:{vehicle}``, the number of the vehicle's last event, read with its
  session. All are written by the script that writes the session; none expires by TTL, so that the
  sessions are what ``INFO keyspace`` counts as expiring. The reads leave out what is past its
  fleet's retention time and not yet trimmed, a vehicle's fleet being its key's
  (:meth:`service.store.EventRetention.of_key`).

Reading places (:meth:`RedisStore.placed`) is one server-side script too, over the spatial index
(:mod:`service.store.redis_places`): a small box over a large fleet reads only the places near it.

A request reads its vehicles with one Lua script (one ``MGET``, atomic) and writes them with one
more (atomic, run by the server): per vehicle, it compares the session's version with the one read
and writes session and setting only if it matches. Each takes its vehicles packed in two
arguments (their values' lengths, and their bytes one after the other) and the read returns them
packed the same way, so that the client packs and parses two values, not a few per vehicle: the
scripts and their values are in :mod:`service.store.redis_layout`.

Durability is Redis's: with ``appendonly yes`` and ``appendfsync always`` every write is on disk
before its reply, so no acknowledged ``PUT`` is lost when Redis or its machine fails; with
``appendfsync everysec`` the last second may be lost when the machine fails; without the
append-only file, everything since the last snapshot. Faults (refused or lost connections,
timeouts after :data:`service.store.STORE_TIMEOUT_S`, a Redis still loading or refusing writes)
are :class:`service.store.StoreUnavailable`.
"""

from __future__ import annotations

import math
import re
import time
from collections.abc import Collection, Mapping
from typing import cast
from urllib.parse import urlsplit, urlunsplit

import redis
from redis.backoff import NoBackoff
from redis.retry import Retry

from . import (
    DEFAULT_EVENT_RETENTION_S,
    STORE_TIMEOUT_S,
    Box,
    EventRetention,
    PlacedSession,
    StateStore,
    StoredEvent,
    StoredVehicle,
    StoreUnavailable,
    VehicleWrite,
    checked_idle_s,
    prefix_end,
)
from .redis_layout import (
    EVENT_SEQ_PREFIX,
    HISTORIES_KEY,
    HISTORY_PREFIX,
    OUTBOX_KEY,
    PLACED_KEY,
    PLACES_KEY,
    READ_SCRIPT,
    SESSION_PREFIX,
    SETTING_PREFIX,
    WRITE_SCRIPT,
    decode_place,
    decode_session,
    decode_setting,
    packed,
    unpacked,
    vehicle_fields,
)
from .redis_places import (
    AXIS_BITS,
    BOX_PROBE_FACTOR,
    BOX_SQUARES,
    GRID_BUILT_KEY,
    GRID_PREFIX,
    INDEX_SCRIPT,
    PLACED_SCRATCH_KEY,
    PLACED_SCRIPT,
    PLACES_SWEPT_KEY,
    PLACES_SWEPT_PER_READ,
    axis_ordinal,
    box_ranges,
    place_cell,
)

__all__ = [
    "SESSION_PREFIX",
    "SETTING_PREFIX",
    "PLACES_KEY",
    "PLACED_KEY",
    "GRID_PREFIX",
    "GRID_BUILT_KEY",
    "PLACES_SWEPT_PER_READ",
    "AXIS_BITS",
    "BOX_SQUARES",
    "BOX_PROBE_FACTOR",
    "axis_ordinal",
    "place_cell",
    "box_ranges",
    "OUTBOX_KEY",
    "HISTORY_PREFIX",
    "HISTORIES_KEY",
    "EVENT_SEQ_PREFIX",
    "RedisStore",
]

#: A cursor of the outbox: a stream entry's id.
_CURSOR = re.compile(r"[0-9]{1,20}-[0-9]{1,20}")


def _ms(duration_s: float) -> int:
    """A duration in whole milliseconds, at least one, as the write script takes it."""
    return max(1, round(duration_s * 1000.0))


def shown_url(url: str) -> str:
    """The URL as messages show it: without its password."""
    parts = urlsplit(url)
    if parts.password is None:
        return url
    user = f"{parts.username}:***@" if parts.username else ":***@"
    host = parts.hostname or ""
    return urlunsplit(parts._replace(netloc=f"{user}{host}" + (f":{parts.port}" if parts.port else "")))


class RedisStore(StateStore):
    """Settings and sessions in Redis.

    Parameters
    ----------
    url
        ``redis://[[USER]:PASSWORD@]HOST:PORT/DB`` (``rediss://`` for TLS, ``unix://PATH?db=DB``).
    idle_s
        A session not written for this long expires (its key's TTL), s.
    event_retention_s
        The outbox keeps an event this long, s.
    fleet_retention_s
        Fleets whose events are kept for a time of their own, s by fleet (:class:`service.store.EventRetention`).

    Raises
    ------
    ValueError
        If the URL is malformed.
    """

    def __init__(
        self,
        url: str,
        idle_s: float,
        event_retention_s: float = DEFAULT_EVENT_RETENTION_S,
        fleet_retention_s: Mapping[str, float] | None = None,
    ) -> None:
        idle_s = checked_idle_s(idle_s)
        self.name = shown_url(url)
        self.ttl_ms = max(1, round(idle_s * 1000.0))
        self.event_retention = EventRetention(event_retention_s, fleet_retention_s)
        try:
            # One immediate retry on a broken connection (one the pool kept across a restart of
            # Redis), none on a timeout: a request waits at most about STORE_TIMEOUT_S for its answer.
            self._redis = redis.Redis.from_url(
                url,
                socket_timeout=STORE_TIMEOUT_S,
                socket_connect_timeout=STORE_TIMEOUT_S,
                retry=Retry(NoBackoff(), 1, supported_errors=(redis.ConnectionError,)),
            )
        except ValueError as exc:
            raise ValueError(f"bad Redis URL {self.name}: {exc}") from None
        self._database = int(self._redis.connection_pool.connection_kwargs.get("db", 0))
        self._write_script = self._redis.register_script(WRITE_SCRIPT)
        self._read_script = self._redis.register_script(READ_SCRIPT)
        self._placed_script = self._redis.register_script(PLACED_SCRIPT.replace("__SESSION__", SESSION_PREFIX))
        self._index_script = self._redis.register_script(INDEX_SCRIPT)

    def _unavailable(self, exc: Exception) -> StoreUnavailable:
        return StoreUnavailable(f"the state store {self.name} cannot be reached now: {type(exc).__name__}: {exc}")

    def check(self) -> None:
        """Ping Redis, and index the places written before the spatial index existed (once)."""
        try:
            self._redis.ping()
            if not self._redis.exists(GRID_BUILT_KEY):
                self._index_places()
        except redis.RedisError as exc:
            raise OSError(f"cannot reach the state store {self.name}: {exc}") from None
        except ValueError as exc:
            raise OSError(f"the state store {self.name} holds an unreadable place: {exc}") from None

    def _index_places(self) -> None:
        """Put every place of the hash into the spatial index unless a write indexed it (``HSCAN``: each place
        there all along is read at least once; those written meanwhile were indexed by their write), then
        mark the index built."""
        cursor = 0
        while True:
            cursor, places = self._redis.hscan(PLACES_KEY, cursor, count=1000)
            args: list[bytes | int] = []
            for key, place in cast(dict[bytes, bytes], places).items():
                args += [key, place, place_cell(decode_place(place))]
            if args:
                self._index_script(keys=[PLACES_KEY], args=args)
            if cursor == 0:
                break
        self._redis.set(GRID_BUILT_KEY, 1)

    def read(self, vehicle_ids: Collection[str]) -> dict[str, StoredVehicle]:
        if not vehicle_ids:
            return {}
        vehicle_ids = list(vehicle_ids)
        try:
            values = unpacked(*self._read_script(args=[*packed([v.encode() for v in vehicle_ids])]))
        except redis.RedisError as exc:
            raise self._unavailable(exc) from None
        stored = {}
        columns = values[0::3], values[1::3], values[2::3]
        for vehicle_id, session, setting, seq in zip(vehicle_ids, *columns, strict=True):
            try:
                stored[vehicle_id] = StoredVehicle(
                    None if setting is None else decode_setting(setting), *decode_session(session), int(seq or 0)
                )
            except ValueError as exc:
                raise StoreUnavailable(
                    f"the state store {self.name} holds an unreadable entry of vehicle {vehicle_id!r}: {exc}"
                ) from None
        return stored

    def write(self, writes: Mapping[str, VehicleWrite]) -> set[str]:
        if not writes:
            return set()
        vehicle_ids = list(writes)
        fields = [value for vehicle_id, w in writes.items() for value in vehicle_fields(vehicle_id, w)]
        args: list[int | str | bytes] = [self.ttl_ms, _ms(self.event_retention.longest_s), *packed(fields)]
        for number, vehicle_id in enumerate(vehicle_ids, 1):
            for event in writes[vehicle_id].events:
                retention_ms = _ms(self.event_retention.of(event.fleet))
                args += [number, event.fleet, event.seq, repr(event.time_s), event.body, retention_ms]
        try:
            conflicts = self._write_script(keys=[PLACES_KEY, PLACED_KEY], args=args)
        except redis.RedisError as exc:
            raise self._unavailable(exc) from None
        return {vehicle_ids[number - 1] for number in conflicts}

    def placed(
        self, prefix: str, after: str, limit: int, networks: Collection[str], box: Box | None
    ) -> list[PlacedSession]:
        """Read with one script: from the spatial index for a box whose cells hold fewer than
        :data:`BOX_PROBE_FACTOR` places per vehicle asked for, else along the fleet's keys."""
        end = prefix_end(prefix)
        first = "(" + after if after >= prefix and after else "[" + prefix if prefix else "-"
        networks = list(networks)
        args: list[str | int] = [first, "+" if end is None else "(" + end, limit, "0" if box is None else "1"]
        args += [repr(v) for v in box or (0.0, 0.0, 0.0, 0.0)]
        args += [BOX_PROBE_FACTOR * limit, len(networks), *networks]
        args += [cell for cells in (box_ranges(box) if box is not None else ()) for cell in cells]
        try:
            keys = [PLACES_KEY, PLACED_KEY, PLACED_SCRATCH_KEY, PLACES_SWEPT_KEY]
            found = self._placed_script(keys=keys, args=args)
        except redis.RedisError as exc:
            raise self._unavailable(exc) from None
        placed = []
        for k in range(0, len(found), 3):
            key, stored, place = found[k : k + 3]
            session, _version = decode_session(stored)
            assert session is not None  # only live sessions are found
            placed.append(PlacedSession(key.decode(), session, decode_place(place)))
        return placed

    def events_after(self, fleet: str | None, after: str | None, limit: int) -> list[StoredEvent]:
        """Read from the stream of every fleet or of ``fleet``; the cursor is the entry's id. The read starts at the
        oldest id within the retention time (the fleet's, or the longest), and in the stream of every fleet leaves
        out the entries past their own fleet's, reading on until the page is full or the stream ends."""
        if after is not None and not _CURSOR.fullmatch(after):
            raise ValueError(f"not a cursor of this outbox: {after[:40]!r}")
        now_ms = time.time() * 1000.0
        retention_s = self.event_retention.longest_s if fleet is None else self.event_retention.of(fleet)
        oldest_ms = math.ceil(now_ms - retention_s * 1000.0)
        start = f"{oldest_ms}-0" if after is None or int(after.partition("-")[0]) < oldest_ms else "(" + after
        stream = OUTBOX_KEY if fleet is None else f"{OUTBOX_KEY}:{fleet}"
        events: list[StoredEvent] = []
        while len(events) < limit:
            wanted = limit - len(events)
            entries = self._entries(stream, start, wanted)
            events += [
                StoredEvent(entry_id, key, body)
                for entry_id, key, body in entries
                if fleet is not None or int(entry_id.partition("-")[0]) >= now_ms - self._retention_ms(key)
            ]
            if fleet is not None or len(entries) < wanted:
                break
            start = "(" + entries[-1][0]
        return events

    def _entries(self, stream: str, start: str, count: int) -> list[tuple[str, str, bytes]]:
        """Id, vehicle key and event of at most ``count`` entries of ``stream`` from ``start`` on."""
        try:
            entries = self._redis.xrange(stream, start, "+", count=count)
        except redis.RedisError as exc:
            raise self._unavailable(exc) from None
        return [
            (entry_id.decode(), fields[b"k"].decode(), fields[b"b"])
            for entry_id, fields in cast(list[tuple[bytes, dict[bytes, bytes]]], entries)
        ]

    def _retention_ms(self, vehicle_key: str) -> float:
        """How long the events of the vehicle kept as ``vehicle_key`` are kept, ms."""
        return self.event_retention.of_key(vehicle_key) * 1000.0

    def vehicle_events(self, vehicle_key: str, since_s: float, limit: int) -> list[StoredEvent]:
        """Read from the vehicle's sorted set by time (entries of equal times in the order of their ids), leaving out
        those written before its fleet's retention time that are still there."""
        oldest_ms = time.time() * 1000.0 - self._retention_ms(vehicle_key)
        events: list[StoredEvent] = []
        offset = 0
        while len(events) < limit:
            try:
                members = self._redis.zrangebyscore(HISTORY_PREFIX + vehicle_key, repr(since_s), "+inf", offset, limit)
            except redis.RedisError as exc:
                raise self._unavailable(exc) from None
            for member in cast(list[bytes], members):
                entry_id, _, body = member.partition(b"|")
                ms, _, sequence = entry_id.partition(b"-")
                if int(ms) >= oldest_ms:
                    events.append(StoredEvent(f"{int(ms)}-{int(sequence)}", vehicle_key, body))
            if len(members) < limit:
                break
            offset += limit
        return events[:limit]

    def session_count(self) -> int:
        """The keys with a TTL in the service's database: its sessions (a database of its own).
        Counted by Redis as it goes (``INFO keyspace``), so keys that have just expired may
        still count until Redis reclaims them."""
        try:
            keyspace = self._redis.info("keyspace")
        except redis.RedisError as exc:
            raise self._unavailable(exc) from None
        return int(keyspace.get(f"db{self._database}", {}).get("expires", 0))

    def close(self) -> None:
        self._redis.close()
