"""What push keeps across restarts: each sink's cursor in the outbox, the events waiting to be retried,
the dead letters, and the lease that lets one dispatcher deliver at a time.

A SQLite file of its own (``CSWS_PUSH_DB``; by default beside the state store's file), shared by the
workers of a machine. A *sink* is one receiver of events (a fleet's webhook URL, the MQTT broker):
its cursor says up to where the outbox has been delivered to it or queued for it, so an event is
delivered again after a crash, never lost. The queue keeps events in the order queued (``number``):
a vehicle's later events wait behind its first one there.
"""

from __future__ import annotations

import sqlite3
import threading
from pathlib import Path
from typing import NamedTuple, Protocol

__all__ = ["PushStore", "PushState", "Pending", "DeadLetter", "QueuedRow", "push_db_beside", "open_push_state"]

#: An event to queue: its sink, vehicle, body, tries so far, next try (unix s) and last error.
QueuedRow = tuple[str, str, bytes, int, float, str]

_SCHEMA = """
CREATE TABLE IF NOT EXISTS cursors (sink TEXT PRIMARY KEY, cursor TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS pending (
    number INTEGER PRIMARY KEY AUTOINCREMENT, sink TEXT NOT NULL, vehicle TEXT NOT NULL, body BLOB NOT NULL,
    tries INTEGER NOT NULL, next_try_s REAL NOT NULL, queued_s REAL NOT NULL, error TEXT NOT NULL DEFAULT '');
CREATE INDEX IF NOT EXISTS pending_by_vehicle ON pending (sink, vehicle, number);
CREATE TABLE IF NOT EXISTS dead_letters (
    number INTEGER PRIMARY KEY AUTOINCREMENT, sink TEXT NOT NULL, vehicle TEXT NOT NULL, body BLOB NOT NULL,
    tries INTEGER NOT NULL, error TEXT NOT NULL, dead_s REAL NOT NULL);
CREATE TABLE IF NOT EXISTS leases (name TEXT PRIMARY KEY, holder TEXT NOT NULL, expires_s REAL NOT NULL);
"""


class Pending(NamedTuple):
    """An event waiting for its sink: ``tries`` made so far, the next not before ``next_try_s`` (unix s)."""

    number: int
    sink: str
    vehicle: str
    body: bytes
    tries: int
    next_try_s: float
    queued_s: float
    error: str


class DeadLetter(NamedTuple):
    """An event its sink never took: the tries made, the last error, and when it was given up (unix s)."""

    number: int
    sink: str
    vehicle: str
    body: bytes
    tries: int
    error: str
    dead_s: float


class PushStore(Protocol):
    """Push's durable state: :class:`PushState` (a SQLite file), or :class:`service.push.redis_state.RedisPushState`
    (for replicas sharing a Redis). Their methods are documented there."""

    path: str

    def close(self) -> None: ...
    def cursor(self, sink: str) -> str | None: ...
    def advance(self, sink: str, cursor: str, queued: list[QueuedRow], now_s: float) -> None: ...
    def waiting_vehicles(self, sink: str) -> set[str]: ...
    def due(self, sink: str, now_s: float, limit: int) -> list[Pending]: ...
    def queued_count(self, sink: str) -> int: ...
    def delivered(self, number: int) -> None: ...
    def failed(self, number: int, tries: int, next_try_s: float, error: str) -> None: ...
    def dead(self, pending: Pending, tries: int, error: str, now_s: float) -> None: ...
    def dead_letters(self, sink_prefix: str = "", limit: int = 1000) -> list[DeadLetter]: ...
    def hold_lease(self, name: str, holder: str, now_s: float, duration_s: float) -> bool: ...
    def release_lease(self, name: str, holder: str) -> None: ...


#: The schemes of a Redis URL: the push state is kept there rather than in a SQLite file.
REDIS_SCHEMES = ("redis://", "rediss://", "unix://")


def open_push_state(location: str | Path) -> PushStore:
    """Push's state at ``location``: a Redis URL (``redis://``, ``rediss://``, ``unix://``), else a SQLite file."""
    if str(location).startswith(REDIS_SCHEMES):
        from .redis_state import RedisPushState

        return RedisPushState(str(location))
    return PushState(location)


class PushState:
    """The durable state of push in a SQLite file (``:memory:`` for one process only); thread-safe."""

    def __init__(self, path: str | Path) -> None:
        self.path = str(path)
        if self.path != ":memory:":
            Path(self.path).parent.mkdir(parents=True, exist_ok=True)
        self._lock = threading.Lock()
        self._db = sqlite3.connect(self.path, timeout=30.0, isolation_level=None, check_same_thread=False)
        self._db.execute("PRAGMA journal_mode=WAL")
        self._db.execute("PRAGMA synchronous=NORMAL")
        self._db.executescript(_SCHEMA)

    def close(self) -> None:
        """Close the file."""
        with self._lock:
            self._db.close()

    def cursor(self, sink: str) -> str | None:
        """Up to where the outbox went to ``sink`` (delivered or queued), None before its first event."""
        with self._lock:
            row = self._db.execute("SELECT cursor FROM cursors WHERE sink = ?", (sink,)).fetchone()
        return row[0] if row else None

    def advance(self, sink: str, cursor: str, queued: list[QueuedRow], now_s: float) -> None:
        """Queue events (sink, vehicle, body, tries, next try, error) and move the cursor of ``sink``, at once."""
        with self._lock:
            self._db.execute("BEGIN IMMEDIATE")
            try:
                self._db.executemany(
                    "INSERT INTO pending (sink, vehicle, body, tries, next_try_s, queued_s, error) "
                    "VALUES (?, ?, ?, ?, ?, ?, ?)",
                    [(*row[:5], now_s, row[5]) for row in queued],
                )
                self._db.execute(
                    "INSERT INTO cursors (sink, cursor) VALUES (?, ?) ON CONFLICT (sink) DO UPDATE SET cursor = ?",
                    (sink, cursor, cursor),
                )
                self._db.execute("COMMIT")
            except BaseException:
                self._db.execute("ROLLBACK")
                raise

    def waiting_vehicles(self, sink: str) -> set[str]:
        """The vehicles with events queued for ``sink``: their later events go behind them."""
        with self._lock:
            rows = self._db.execute("SELECT DISTINCT vehicle FROM pending WHERE sink = ?", (sink,)).fetchall()
        return {row[0] for row in rows}

    def due(self, sink: str, now_s: float, limit: int) -> list[Pending]:
        """The first queued event of each vehicle of ``sink`` whose next try is due, oldest first."""
        with self._lock:
            rows = self._db.execute(
                "SELECT * FROM pending WHERE number IN (SELECT MIN(number) FROM pending WHERE sink = ? "
                "GROUP BY vehicle) AND next_try_s <= ? ORDER BY number LIMIT ?",
                (sink, now_s, limit),
            ).fetchall()
        return [Pending(*row) for row in rows]

    def queued_count(self, sink: str) -> int:
        """How many events wait for ``sink``."""
        with self._lock:
            return int(self._db.execute("SELECT COUNT(*) FROM pending WHERE sink = ?", (sink,)).fetchone()[0])

    def delivered(self, number: int) -> None:
        """A queued event went out: off the queue."""
        with self._lock:
            self._db.execute("DELETE FROM pending WHERE number = ?", (number,))

    def failed(self, number: int, tries: int, next_try_s: float, error: str) -> None:
        """A queued event failed again: its tries so far and when to try next."""
        with self._lock:
            self._db.execute(
                "UPDATE pending SET tries = ?, next_try_s = ?, error = ? WHERE number = ?",
                (tries, next_try_s, error, number),
            )

    def dead(self, pending: Pending, tries: int, error: str, now_s: float) -> None:
        """Give a queued event up: off the queue, into the dead letters."""
        with self._lock:
            self._db.execute("BEGIN IMMEDIATE")
            self._db.execute(
                "INSERT INTO dead_letters (sink, vehicle, body, tries, error, dead_s) VALUES (?, ?, ?, ?, ?, ?)",
                (pending.sink, pending.vehicle, pending.body, tries, error, now_s),
            )
            self._db.execute("DELETE FROM pending WHERE number = ?", (pending.number,))
            self._db.execute("COMMIT")

    def dead_letters(self, sink_prefix: str = "", limit: int = 1000) -> list[DeadLetter]:
        """The dead letters of the sinks whose names start with ``sink_prefix``, oldest first."""
        with self._lock:
            rows = self._db.execute(
                "SELECT * FROM dead_letters WHERE substr(sink, 1, ?) = ? ORDER BY number LIMIT ?",
                (len(sink_prefix), sink_prefix, limit),
            ).fetchall()
        return [DeadLetter(*row) for row in rows]

    def hold_lease(self, name: str, holder: str, now_s: float, duration_s: float) -> bool:
        """Take or renew the lease ``name`` for ``holder`` until ``now_s + duration_s``; whether it holds it.

        One holder at a time: another takes the lease only once it expired (its holder stopped renewing).
        """
        with self._lock:
            self._db.execute(
                "INSERT INTO leases (name, holder, expires_s) VALUES (?, ?, ?) ON CONFLICT (name) DO UPDATE "
                "SET holder = excluded.holder, expires_s = excluded.expires_s "
                "WHERE leases.holder = excluded.holder OR leases.expires_s < ?",
                (name, holder, now_s + duration_s, now_s),
            )
            row = self._db.execute("SELECT holder FROM leases WHERE name = ?", (name,)).fetchone()
        return row is not None and row[0] == holder

    def release_lease(self, name: str, holder: str) -> None:
        """Give the lease up at once (on stopping), so that another dispatcher need not wait for it to expire."""
        with self._lock:
            self._db.execute("DELETE FROM leases WHERE name = ? AND holder = ?", (name, holder))


def push_db_beside(state_db: str) -> str:
    """The push state's file beside the state store's SQLite file (``push.sqlite3``); ``:memory:`` beside none."""
    state_db = state_db.strip()
    if state_db in ("", ":memory:"):
        return ":memory:"
    return str(Path(state_db).with_name("push.sqlite3"))
