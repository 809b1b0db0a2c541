"""The state store in one SQLite file (WAL): the embedded default, shared by the workers of one machine.

Two tables: ``vehicle_settings`` (kept until changed) and ``vehicle_sessions`` (with their
version and when they were last written). A session not written for the idle time counts as
absent at once; the rows are swept out at most every :data:`SWEEP_PERIOD_S`. The places of the
vehicles (:class:`~service.store.Place`) are in ``vehicle_places``, written in the transaction of
their sessions, and indexed twice: by key (its primary key: a fleet's page in key order) and by
point in the R*Tree ``vehicle_place_boxes`` (kept by triggers: a small box reads only the places
in it; the R*Tree holds single-precision bounds rounded outwards, so its hits are checked again
against the exact point). A box holding many places compared with the page asked for is read in
key order instead, checking each place against it: sorting every hit of a large box for each
page would cost what the box holds, not what the page does.

The outbox of events (:mod:`service.store.sqlite_outbox`): a vehicle's events are inserted in the
transaction of its session, and the number of its last one (``vehicle_event_seqs``) is read with the
session, in the same statement. Events older than their fleet's retention time (by when they were
written; :class:`service.store.EventRetention`) are deleted with the expired sessions, and left out of
the reads until then.

A request reads its vehicles with one statement (one snapshot) and writes them in one
``BEGIN IMMEDIATE`` transaction: each session is written only over the version read, by an
``executemany`` whose count of changed rows tells whether every one was; only when some were
not (another request wrote them meanwhile) are the stored versions read to find which, and
the others written. Writers of the workers take turns for the length of a write,
never for the engine's work in between; one that finds the lock taken tries again every
:data:`LOCK_RETRY_S` (SQLite's own busy handler would sleep from 1 ms up to 100 ms, far longer
than a write holds the lock). Settings and events are written with ``synchronous=FULL``
(on disk when the 200 goes out); a transaction of sessions alone with ``NORMAL``, which
in WAL mode survives a crash of the service and may lose the last sessions only when the
machine itself fails, costing those vehicles a fresh session.

The file is watched: after each write its inode and permissions are compared with those of the
file opened (:meth:`SQLiteStore._check_file`, one ``stat``). A file that was deleted, replaced
or made read-only makes that write and every later operation a
:class:`~service.store.StoreUnavailable` (a 503 with ``Retry-After``, and ``/readyz`` 503),
logged once: the write went to a file that nobody will read again, so it is not acknowledged,
and the service does not start over on a new, empty file, since the acknowledged settings
are in the old one. Restart the service once the file is back. A worker forked after the
file was opened opens it again only if it is still the same file. The file (and with it
SQLite's ``-wal`` and ``-shm`` files, which take its permissions) is created readable and
writable by its owner only (0600): it holds every fleet's vehicle ids and positions.
"""

from __future__ import annotations

import json
import logging
import os
import sqlite3
import stat
import time
from collections.abc import Callable, Collection, Iterable, Mapping
from pathlib import Path

from csws.standard import Category

from . import (
    DEFAULT_EVENT_RETENTION_S,
    STORE_TIMEOUT_S,
    Box,
    EventRetention,
    Place,
    PlacedSession,
    StateStore,
    StoredEvent,
    StoredVehicle,
    StoreUnavailable,
    VehicleSetting,
    VehicleWrite,
    checked_idle_s,
    prefix_end,
)
from .sqlite_outbox import EVENT_COLUMNS, OUTBOX_SCHEMA, SQLiteOutbox

__all__ = ["SWEEP_PERIOD_S", "LOCK_RETRY_S", "FILE_MODE", "BOX_PROBE_FACTOR", "SQLiteStore"]

logger = logging.getLogger("csws.service")

#: The permissions of a database file the store creates: its owner's only.
FILE_MODE = 0o600
#: Names SQLite takes for a private database of one connection, not a file.
_NOT_FILES = ("", ":memory:")

#: Expired sessions are deleted at most this often (by whichever write comes first), s.
SWEEP_PERIOD_S = 60.0
#: How long to wait before trying again for a lock another worker holds, s.
LOCK_RETRY_S = 0.0001

_SCHEMA = (
    "CREATE TABLE IF NOT EXISTS vehicle_settings ("
    "vehicle_id TEXT PRIMARY KEY, switched_on INTEGER NOT NULL, category TEXT)",
    "CREATE TABLE IF NOT EXISTS vehicle_sessions ("
    "vehicle_id TEXT PRIMARY KEY, version INTEGER NOT NULL, written_s REAL NOT NULL, session BLOB NOT NULL)",
    "CREATE TABLE IF NOT EXISTS vehicle_places ("
    "vehicle_id TEXT PRIMARY KEY, network TEXT NOT NULL, x REAL NOT NULL, y REAL NOT NULL)",
    "CREATE VIRTUAL TABLE IF NOT EXISTS vehicle_place_boxes USING rtree(id, min_x, max_x, min_y, max_y)",
    "CREATE TRIGGER IF NOT EXISTS vehicle_place_added AFTER INSERT ON vehicle_places BEGIN "
    "INSERT INTO vehicle_place_boxes VALUES (new.rowid, new.x, new.x, new.y, new.y); END",
    "CREATE TRIGGER IF NOT EXISTS vehicle_place_moved AFTER UPDATE ON vehicle_places BEGIN "
    "UPDATE vehicle_place_boxes SET min_x = new.x, max_x = new.x, min_y = new.y, max_y = new.y "
    "WHERE id = new.rowid; END",
    "CREATE TRIGGER IF NOT EXISTS vehicle_place_gone AFTER DELETE ON vehicle_places BEGIN "
    "DELETE FROM vehicle_place_boxes WHERE id = old.rowid; END",
    *OUTBOX_SCHEMA,
)
#: Settings and live sessions of the vehicles of a JSON list, in one statement.
_READ = (
    "SELECT wanted.value, settings.switched_on, settings.category, sessions.session, sessions.version, seqs.seq "
    "FROM json_each(?) AS wanted "
    "LEFT JOIN vehicle_settings AS settings ON settings.vehicle_id = wanted.value "
    "LEFT JOIN vehicle_sessions AS sessions ON sessions.vehicle_id = wanted.value AND sessions.written_s >= ? "
    "LEFT JOIN vehicle_event_seqs AS seqs ON seqs.vehicle_id = wanted.value"
)
_LIVE_VERSIONS = (
    "SELECT vehicle_id, version FROM vehicle_sessions "
    "WHERE vehicle_id IN (SELECT value FROM json_each(?)) AND written_s >= ?"
)
#: A session over the live one of the version read: no row changes when the version moved or the session expired.
_UPDATE_SESSION = (
    "UPDATE vehicle_sessions SET version = version + 1, written_s = ?, session = ? "
    "WHERE vehicle_id = ? AND version = ? AND written_s >= ?"
)
#: A first session (version 1): no row changes when another request wrote a live one meanwhile.
_INSERT_SESSION = (
    "INSERT INTO vehicle_sessions (vehicle_id, version, written_s, session) VALUES (?, 1, ?, ?) "
    "ON CONFLICT (vehicle_id) DO UPDATE SET version = 1, written_s = excluded.written_s, session = excluded.session "
    "WHERE vehicle_sessions.written_s < ?"
)
_WRITE_SETTING = "INSERT OR REPLACE INTO vehicle_settings (vehicle_id, switched_on, category) VALUES (?, ?, ?)"
#: A place, updated in its row (its rowid, the R*Tree's id, stays).
_WRITE_PLACE = (
    "INSERT INTO vehicle_places (vehicle_id, network, x, y) VALUES (?, ?, ?, ?) "
    "ON CONFLICT (vehicle_id) DO UPDATE SET network = excluded.network, x = excluded.x, y = excluded.y"
)
_SWEEP = (
    "DELETE FROM vehicle_places WHERE vehicle_id IN (SELECT vehicle_id FROM vehicle_sessions WHERE written_s < ?)",
    "DELETE FROM vehicle_sessions WHERE written_s < ?",
)
_PLACED_COLUMNS = "SELECT places.vehicle_id, sessions.session, places.network, places.x, places.y "
#: A box holding at least this many places per vehicle asked for is read in key order (below). Measured
#: on 100,000 places, pieces of 501: the R*Tree plan costs about 6 µs per place in the box (21 ms for
#: 3,300, 0.4 ms for 19), the key-order plan about 0.5 µs per place it passes (4 ms for a box of 3 %
#: of the places, 50 ms for a box of 19): they meet near 2,000 places in the box.
BOX_PROBE_FACTOR = 4
#: How many places of any fleet the R*Tree holds in a box, counted up to :limit.
_BOX_PROBE = (
    "SELECT count(*) FROM (SELECT 1 FROM vehicle_place_boxes "
    "WHERE max_x >= :min_x AND min_x <= :max_x AND max_y >= :min_y AND min_y <= :max_y LIMIT :probe)"
)
_INSIDE = "AND places.x BETWEEN :min_x AND :max_x AND places.y BETWEEN :min_y AND :max_y "
#: The places of a key range in key order (the primary key's), each joined to its live session.
_PLACED_IN_ORDER = (
    "FROM vehicle_places AS places CROSS JOIN vehicle_sessions AS sessions "
    "WHERE places.vehicle_id > :after AND places.vehicle_id >= :prefix {below} {inside}"
    "AND places.network IN (SELECT value FROM json_each(:networks)) "
    "AND sessions.vehicle_id = places.vehicle_id AND sessions.written_s >= :oldest "
    "ORDER BY places.vehicle_id LIMIT :limit"
)
#: The places in a box (the R*Tree's hits, checked against the exact points), then as above.
_PLACED_IN_BOX = (
    "FROM vehicle_place_boxes AS boxes CROSS JOIN vehicle_places AS places CROSS JOIN vehicle_sessions AS sessions "
    "WHERE boxes.max_x >= :min_x AND boxes.min_x <= :max_x AND boxes.max_y >= :min_y AND boxes.min_y <= :max_y "
    "AND places.rowid = boxes.id "
    "AND places.x BETWEEN :min_x AND :max_x AND places.y BETWEEN :min_y AND :max_y "
    "AND places.vehicle_id > :after AND places.vehicle_id >= :prefix {below} "
    "AND places.network IN (SELECT value FROM json_each(:networks)) "
    "AND sessions.vehicle_id = places.vehicle_id AND sessions.written_s >= :oldest "
    "ORDER BY places.vehicle_id LIMIT :limit"
)


def _setting(switched_on: int, category: str | None) -> VehicleSetting:
    """A stored setting from its columns; ValueError for an unknown category."""
    return VehicleSetting(bool(switched_on), Category(category) if category else None)


class SQLiteStore(StateStore):
    """Settings and sessions in a SQLite file.

    Parameters
    ----------
    path
        The database file (created with its folder if missing), or ``":memory:"`` (one process only).
    idle_s
        A session not written for this long expires, s.
    clock
        Seconds of the clock that dates the sessions: wall-clock time, which every worker
        shares and which goes on across restarts (injectable, so that expiry is testable
        without waiting).
    event_retention_s
        The outbox keeps an event this long after it was written, s.
    fleet_retention_s
        Fleets whose events are kept for a time of their own, s by fleet (:class:`service.store.EventRetention`).

    Raises
    ------
    OSError
        One line naming the file, when it cannot be opened as a database.
    """

    def __init__(
        self,
        path: str | Path,
        idle_s: float,
        clock: Callable[[], float] = time.time,
        event_retention_s: float = DEFAULT_EVENT_RETENTION_S,
        fleet_retention_s: Mapping[str, float] | None = None,
    ) -> None:
        idle_s = checked_idle_s(idle_s)
        self.name = str(path)
        self.idle_s = float(idle_s)
        self.event_retention = EventRetention(event_retention_s, fleet_retention_s)
        self.clock = clock
        self._swept_s = -float("inf")
        self._pid = os.getpid()
        self._file: tuple[int, int] | None = None  # device and inode of the file opened
        self._lost: str | None = None  # why the file can no longer be used, once it cannot
        if self.name not in _NOT_FILES:
            self._create_private(Path(self.name))
        self._connection = self._connect()
        self._file = self._identity()
        self._outbox = SQLiteOutbox(self.name, self.name in _NOT_FILES, lambda: self._db, self.event_retention, clock)

    @staticmethod
    def _create_private(path: Path) -> None:
        """Create the database file (and its folder) if missing, readable and writable by its owner only.

        Raises
        ------
        OSError
            One line naming the file, when it cannot be created.
        """
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            os.close(os.open(path, os.O_CREAT | os.O_RDWR, FILE_MODE))
        except OSError as exc:
            raise OSError(f"cannot open the vehicle state database {path}: {exc.strerror}") from None

    def _identity(self) -> tuple[int, int] | None:
        """The device and inode of the database file now; None for a private database.

        Raises
        ------
        OSError
            If the file is gone.
        """
        if self.name in _NOT_FILES:
            return None
        status = os.stat(self.name)
        return status.st_dev, status.st_ino

    def _check_file(self) -> None:
        """Raise :class:`StoreUnavailable` if the file opened was deleted, replaced or made read-only
        (logged the first time)."""
        if self._file is None:
            return
        if self._lost is None:
            try:
                status = os.stat(self.name)
                if (status.st_dev, status.st_ino) != self._file:
                    self._lost = "was replaced by another file"
                elif not status.st_mode & stat.S_IWUSR:
                    self._lost = "was made read-only"
            except FileNotFoundError:
                self._lost = "was deleted"
            except OSError as exc:
                self._lost = f"cannot be looked at ({exc.strerror})"
            if self._lost is not None:
                logger.error(
                    "the vehicle state database %s %s: writes are refused (503) until the service is restarted "
                    "with the file back",
                    self.name,
                    self._lost,
                )
        self._refuse_if_lost()

    def _connect(self) -> sqlite3.Connection:
        """A connection to the database, its tables made if missing.

        Raises
        ------
        OSError
            One line naming the file, when it cannot be opened as a database.
        """
        self._durable = True
        try:
            connection = sqlite3.connect(
                self.name, check_same_thread=False, isolation_level=None, timeout=STORE_TIMEOUT_S
            )
            if self.name != ":memory:":
                # Readers never wait for the writer: the workers of one service share the file.
                connection.execute("PRAGMA journal_mode=WAL")
            connection.execute("PRAGMA synchronous=FULL")
            for statement in _SCHEMA:
                connection.execute(statement)
            connection.execute("PRAGMA busy_timeout=0")  # from now on waits are _execute's
        except sqlite3.Error as exc:
            raise OSError(f"cannot open the vehicle state database {self.name}: {exc}") from None
        return connection

    @property
    def _db(self) -> sqlite3.Connection:
        """This process's connection: a worker forked after the store was opened makes its own, since a
        SQLite connection must not be used on both sides of a fork."""
        if self._pid != os.getpid():
            self._check_file()  # never a new, empty file in place of the one the master opened
            try:
                self._connection = self._connect()
            except OSError as exc:
                raise StoreUnavailable(str(exc)) from None
            self._pid = os.getpid()
        return self._connection

    def check(self) -> None:
        """Read every setting once: a database of another program, or one holding an unknown
        category, stops start-up here rather than failing requests later."""
        try:
            for switched_on, category in self._execute("SELECT switched_on, category FROM vehicle_settings"):
                _setting(switched_on, category)
            self._execute("SELECT vehicle_id, version, written_s, session FROM vehicle_sessions LIMIT 1").fetchall()
            self._execute("SELECT vehicle_id, network, x, y FROM vehicle_places LIMIT 1").fetchall()
            self._execute(EVENT_COLUMNS + "LIMIT 1").fetchall()
        except (sqlite3.Error, ValueError) as exc:
            raise OSError(f"the vehicle state database {self.name} cannot be read: {exc}") from None

    def read(self, vehicle_ids: Collection[str]) -> dict[str, StoredVehicle]:
        if not vehicle_ids:
            return {}
        self._refuse_if_lost()
        try:
            rows = self._execute(_READ, (json.dumps(list(vehicle_ids)), self._oldest_live_s())).fetchall()
            return {
                vehicle_id: StoredVehicle(
                    None if switched_on is None else _setting(switched_on, category), session, version or 0, seq or 0
                )
                for vehicle_id, switched_on, category, session, version, seq in rows
            }
        except (sqlite3.Error, ValueError) as exc:
            raise StoreUnavailable(f"the vehicle state database {self.name} cannot be read now: {exc}") from None

    def write(self, writes: Mapping[str, VehicleWrite]) -> set[str]:
        if not writes:
            return set()
        try:
            self._set_durable(any(w.setting is not None or w.events for w in writes.values()))
            self._refuse_if_lost()
            self._execute("BEGIN IMMEDIATE")
            try:
                conflicts = self._write(writes)
                self._db.execute("COMMIT")
            finally:
                if self._db.in_transaction:
                    self._db.execute("ROLLBACK")
        except sqlite3.Error as exc:
            raise StoreUnavailable(f"the vehicle state database {self.name} cannot be written now: {exc}") from None
        self._check_file()  # committed to the file everyone reads, or not acknowledged
        return conflicts

    def _refuse_if_lost(self) -> None:
        """Raise :class:`StoreUnavailable` once the file was found deleted, replaced or read-only."""
        if self._lost is not None:
            raise StoreUnavailable(f"the vehicle state database {self.name} {self._lost}")

    def _write(self, writes: Mapping[str, VehicleWrite]) -> set[str]:
        """Inside the write transaction: write the sessions still at the version read (and their
        settings), sweep when due; return the others."""
        now_s = self.clock()
        oldest_live_s = now_s - self.idle_s
        self._db.execute("SAVEPOINT sessions")
        conflicts: set[str] = set()
        if self._write_sessions(writes.items(), now_s, oldest_live_s) != len(writes):
            self._db.execute("ROLLBACK TO sessions")
            live = dict(self._db.execute(_LIVE_VERSIONS, (json.dumps(list(writes)), oldest_live_s)).fetchall())
            conflicts = {
                vehicle_id for vehicle_id, w in writes.items() if live.get(vehicle_id, 0) != w.expected_version
            }
            self._write_sessions([(v, w) for v, w in writes.items() if v not in conflicts], now_s, oldest_live_s)
        self._db.execute("RELEASE sessions")
        settings = [
            (vehicle_id, int(w.setting.switched_on), w.setting.category.value if w.setting.category else None)
            for vehicle_id, w in writes.items()
            if w.setting is not None and vehicle_id not in conflicts
        ]
        if settings:
            self._db.executemany(_WRITE_SETTING, settings)
        places = [(v, *w.place) for v, w in writes.items() if w.place is not None and v not in conflicts]
        if places:
            self._db.executemany(_WRITE_PLACE, places)
        self._outbox.write(self._db, [(v, w) for v, w in writes.items() if w.events and v not in conflicts], now_s)
        if now_s - self._swept_s >= SWEEP_PERIOD_S:
            for statement in _SWEEP:
                self._db.execute(statement, (oldest_live_s,))
            self._outbox.trim(self._db, now_s)
            self._swept_s = now_s
        return conflicts

    def _write_sessions(self, writes: Iterable[tuple[str, VehicleWrite]], now_s: float, oldest_live_s: float) -> int:
        """Write each session over the live one of its expected version (or as the first one);
        how many were written."""
        updates, inserts = [], []
        for vehicle_id, w in writes:
            if w.expected_version:
                updates.append((now_s, w.session, vehicle_id, w.expected_version, oldest_live_s))
            else:
                inserts.append((vehicle_id, now_s, w.session, oldest_live_s))
        return (self._db.executemany(_UPDATE_SESSION, updates).rowcount if updates else 0) + (
            self._db.executemany(_INSERT_SESSION, inserts).rowcount if inserts else 0
        )

    def _execute(self, statement: str, parameters: tuple | dict = ()) -> sqlite3.Cursor:
        """Execute a statement that may need a lock another worker holds: tried again every
        :data:`LOCK_RETRY_S` while the lock is taken, for at most :data:`STORE_TIMEOUT_S`."""
        deadline_s = time.monotonic() + STORE_TIMEOUT_S
        while True:
            try:
                return self._db.execute(statement, parameters)
            except sqlite3.OperationalError as exc:
                if exc.sqlite_errorcode & 0xFF != sqlite3.SQLITE_BUSY or time.monotonic() >= deadline_s:
                    raise
            time.sleep(LOCK_RETRY_S)

    def _set_durable(self, durable: bool) -> None:
        """``synchronous=FULL`` for a transaction with settings or events, ``NORMAL`` for one of sessions alone."""
        if durable != self._durable:
            self._db.execute(f"PRAGMA synchronous={'FULL' if durable else 'NORMAL'}")
            self._durable = durable

    def _oldest_live_s(self) -> float:
        """When the oldest session that has not expired was written, on the store's clock."""
        return self.clock() - self.idle_s

    def placed(
        self, prefix: str, after: str, limit: int, networks: Collection[str], box: Box | None
    ) -> list[PlacedSession]:
        """Read with one statement, whose cost the page bounds: in key order along the primary key (the
        exact points checked against the box if any), except for a box holding fewer than
        :data:`BOX_PROBE_FACTOR` places per vehicle asked for (a bounded count in the R*Tree tells), read
        from the R*Tree's hits, sorted."""
        self._refuse_if_lost()
        end = prefix_end(prefix)
        parameters = {
            "after": after,
            "prefix": prefix,
            "end": end,
            "networks": json.dumps(list(networks)),
            "oldest": self._oldest_live_s(),
            "limit": limit,
        }
        if box is not None:
            parameters |= dict(zip(("min_x", "min_y", "max_x", "max_y"), box, strict=True))
        below = "" if end is None else "AND places.vehicle_id < :end"
        try:
            if box is not None and self._few_in(parameters, BOX_PROBE_FACTOR * limit):
                statement = _PLACED_IN_BOX.format(below=below)
            else:
                statement = _PLACED_IN_ORDER.format(below=below, inside="" if box is None else _INSIDE)
            rows = self._execute(_PLACED_COLUMNS + statement, parameters).fetchall()
        except sqlite3.Error as exc:
            raise StoreUnavailable(f"the vehicle state database {self.name} cannot be read now: {exc}") from None
        return [PlacedSession(key, session, Place(network, x, y)) for key, session, network, x, y in rows]

    def _few_in(self, box: dict, count: int) -> bool:
        """Whether the R*Tree holds fewer than ``count`` places in the box (``min_x`` ... ``max_y`` of ``box``)."""
        return int(self._execute(_BOX_PROBE, {**box, "probe": count}).fetchone()[0]) < count

    def events_after(self, fleet: str | None, after: str | None, limit: int) -> list[StoredEvent]:
        """Read from the outbox (:mod:`service.store.sqlite_outbox`) on a connection of its own."""
        self._refuse_if_lost()
        return self._outbox.events_after(fleet, after, limit)

    def vehicle_events(self, vehicle_key: str, since_s: float, limit: int) -> list[StoredEvent]:
        """Read from the outbox (:mod:`service.store.sqlite_outbox`) on a connection of its own."""
        self._refuse_if_lost()
        return self._outbox.vehicle_events(vehicle_key, since_s, limit)

    def session_count(self) -> int:
        """Counted in the file, which is looked at first (``/readyz``: not ready once it is gone)."""
        self._check_file()
        try:
            return int(
                self._execute(
                    "SELECT COUNT(*) FROM vehicle_sessions WHERE written_s >= ?", (self._oldest_live_s(),)
                ).fetchone()[0]
            )
        except sqlite3.Error as exc:
            raise StoreUnavailable(f"the vehicle state database {self.name} cannot be read now: {exc}") from None

    def close(self) -> None:
        if self._pid == os.getpid():
            self._connection.close()
        self._outbox.close()
