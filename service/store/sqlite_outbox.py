"""The outbox of the SQLite state store (:mod:`service.store.sqlite`): the vehicles' events (:mod:`service.events`).

The table ``vehicle_events``: its integer key, never reused (``AUTOINCREMENT``), is the events' order
and cursor; it is indexed by fleet and key (a fleet's stream) and by vehicle and time (a vehicle's
history). The number of each vehicle's last event is kept in ``vehicle_event_seqs``, which the store
reads with the vehicle's session. Events are written by :meth:`SQLiteOutbox.write` inside the store's
write transaction, and read on a connection of their own (:meth:`SQLiteOutbox.reader`). An event is kept for
its fleet's retention time (:class:`service.store.EventRetention`) after it was written: deleted by
:meth:`SQLiteOutbox.trim`, and left out of the reads from then on until it is.
"""

from __future__ import annotations

import os
import sqlite3
import threading
from collections.abc import Callable, Sequence

from . import STORE_TIMEOUT_S, EventRetention, StoredEvent, StoreUnavailable, VehicleWrite

__all__ = ["OUTBOX_SCHEMA", "SQLiteOutbox"]

OUTBOX_SCHEMA = (
    "CREATE TABLE IF NOT EXISTS vehicle_events ("
    "cursor INTEGER PRIMARY KEY AUTOINCREMENT, fleet TEXT NOT NULL, vehicle_id TEXT NOT NULL, seq INTEGER NOT NULL, "
    "time_s REAL NOT NULL, written_s REAL NOT NULL, body BLOB NOT NULL)",
    "CREATE INDEX IF NOT EXISTS vehicle_events_by_fleet ON vehicle_events (fleet, cursor)",
    "CREATE INDEX IF NOT EXISTS vehicle_events_by_vehicle ON vehicle_events (vehicle_id, time_s)",
    "CREATE TABLE IF NOT EXISTS vehicle_event_seqs (vehicle_id TEXT PRIMARY KEY, seq INTEGER NOT NULL)",
)
_INSERT_EVENT = "INSERT INTO vehicle_events (fleet, vehicle_id, seq, time_s, written_s, body) VALUES (?, ?, ?, ?, ?, ?)"
_WRITE_SEQ = "INSERT OR REPLACE INTO vehicle_event_seqs (vehicle_id, seq) VALUES (?, ?)"
EVENT_COLUMNS = "SELECT cursor, vehicle_id, body FROM vehicle_events "


def _cursor_key(cursor: str) -> int:
    """The outbox key a cursor names (its decimal digits); ValueError for anything else."""
    if not (cursor.isascii() and cursor.isdigit() and len(cursor) <= 19):
        raise ValueError(f"not a cursor of this outbox: {cursor[:40]!r}")
    return int(cursor)


class SQLiteOutbox:
    """The events in the store's database file.

    Parameters
    ----------
    name
        The database file, or a private database's name (``":memory:"``, ``""``).
    private
        Whether the database is private to one connection, so read on the store's own.
    connection
        The store's connection of this process (the writes').
    retention
        How long each fleet's events are kept after they were written.
    clock
        The store's clock, s.
    """

    def __init__(
        self,
        name: str,
        private: bool,
        connection: Callable[[], sqlite3.Connection],
        retention: EventRetention,
        clock: Callable[[], float],
    ) -> None:
        self.name = name
        self.retention = retention
        self.clock = clock
        self.private = private
        self.connection = connection
        self._reader: sqlite3.Connection | None = None
        self._reader_pid = os.getpid()
        self._lock = threading.Lock()

    @staticmethod
    def write(db: sqlite3.Connection, writes: Sequence[tuple[str, VehicleWrite]], now_s: float) -> None:
        """Inside the write transaction on ``db``: the events of the vehicles written, and the number of each
        one's last event."""
        if not writes:
            return
        db.executemany(
            _INSERT_EVENT,
            [(e.fleet, vehicle_id, e.seq, e.time_s, now_s, e.body) for vehicle_id, w in writes for e in w.events],
        )
        db.executemany(_WRITE_SEQ, [(vehicle_id, w.events[-1].seq) for vehicle_id, w in writes])

    def kept(self, now_s: float) -> tuple[str, tuple]:
        """The condition (SQL and its parameters) of an event still within its fleet's retention time at ``now_s``:
        written at most that long before."""
        fleets = list(self.retention.fleets_s.items())
        retention_s = f"CASE fleet {' '.join(['WHEN ? THEN ?'] * len(fleets))} ELSE ? END" if fleets else "?"
        return f"written_s >= ? - {retention_s}", (
            now_s,
            *(v for pair in fleets for v in pair),
            self.retention.default_s,
        )

    def trim(self, db: sqlite3.Connection, now_s: float) -> None:
        """Inside the write transaction on ``db``: delete the events past their fleet's retention time at ``now_s``."""
        condition, parameters = self.kept(now_s)
        db.execute(f"DELETE FROM vehicle_events WHERE NOT ({condition})", parameters)

    def events_after(self, fleet: str | None, after: str | None, limit: int) -> list[StoredEvent]:
        """:meth:`service.store.StateStore.events_after`: along the key (every fleet) or the fleet's index; the
        cursor is the key in decimal."""
        first = -1 if after is None else _cursor_key(after)
        kept, kept_parameters = self.kept(self.clock())
        if fleet is None:
            return self._events(
                f"WHERE cursor > ? AND {kept} ORDER BY cursor LIMIT ?", (first, *kept_parameters, limit)
            )
        where = f"WHERE fleet = ? AND cursor > ? AND {kept} ORDER BY cursor LIMIT ?"
        return self._events(where, (fleet, first, *kept_parameters, limit))

    def vehicle_events(self, vehicle_key: str, since_s: float, limit: int) -> list[StoredEvent]:
        """:meth:`service.store.StateStore.vehicle_events`, along the vehicle's index."""
        kept, kept_parameters = self.kept(self.clock())
        where = f"WHERE vehicle_id = ? AND time_s >= ? AND {kept} ORDER BY time_s, cursor LIMIT ?"
        return self._events(where, (vehicle_key, since_s, *kept_parameters, limit))

    def _events(self, where: str, parameters: tuple) -> list[StoredEvent]:
        """The events that ``where`` selects (with its ``parameters``), read on :meth:`reader`."""
        try:
            with self._lock:
                rows = self.reader().execute(EVENT_COLUMNS + where, parameters).fetchall()
        except sqlite3.Error as exc:
            raise StoreUnavailable(f"the vehicle state database {self.name} cannot be read now: {exc}") from None
        return [StoredEvent(str(cursor), vehicle_id, body) for cursor, vehicle_id, body in rows]

    def reader(self) -> sqlite3.Connection:
        """This process's connection for reading the outbox: others than the work thread read it (push), and a
        read on the connection of the writes, between the statements of a write, would see events not yet
        committed. A private database has one connection only, the writes'."""
        if self.private:
            return self.connection()
        if self._reader is None or self._reader_pid != os.getpid():
            self._reader = sqlite3.connect(
                self.name, check_same_thread=False, isolation_level=None, timeout=STORE_TIMEOUT_S
            )
            self._reader_pid = os.getpid()
        return self._reader

    def close(self) -> None:
        """Let go of this process's reading connection."""
        if self._reader is not None and self._reader_pid == os.getpid():
            self._reader.close()
            self._reader = None
