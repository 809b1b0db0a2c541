"""Where the events to push come from: the service's durable outbox, read after a cursor.

The state store (:mod:`service.store`) keeps each event the service writes (a curve warning's onset,
change of level and release, a forward collision warning, a change of system state, a matching fault)
in an outbox, in the order written (:class:`service.store.StoredEvent`). Push reads it through
:class:`EventSource` alone, so every store serves, and tests and benchmarks serve events of their own.
"""

from __future__ import annotations

import threading
from typing import Protocol

import msgspec

from service.store import StoredEvent

__all__ = ["EventSource", "StoredEvent", "Event", "parse_event", "MemoryOutbox"]


class EventSource(Protocol):
    """The outbox of events, read in its order."""

    def events_after(self, fleet: str | None, after: str | None, limit: int) -> list[StoredEvent]:
        """Up to ``limit`` events of ``fleet`` (None: of all fleets) strictly after the cursor ``after``
        (None: from the oldest kept), oldest first."""
        ...


class Event(msgspec.Struct, frozen=True):
    """The fields of an event that push needs: whose it is, its number, and the vehicle's state after it."""

    fleet: str
    vehicle_id: str
    seq: int
    kind: str = ""
    time: float = 0.0
    level: int = 0
    state: str = ""


_DECODER = msgspec.json.Decoder(Event)


def parse_event(body: bytes) -> Event:
    """The fields push needs of an event's JSON body (extra fields are left to the receivers).

    Raises
    ------
    msgspec.ValidationError, msgspec.DecodeError
        For a body that is no event.
    """
    return _DECODER.decode(body)


class MemoryOutbox:
    """An outbox in memory, in one process: an :class:`EventSource` for tests and benchmarks.

    Its cursors are the events' numbers from 1, zero-padded so that they order as strings too.
    """

    def __init__(self) -> None:
        self._events: list[StoredEvent] = []
        self._fleets: list[str] = []
        self._lock = threading.Lock()

    def write(self, fleet: str, vehicle_id: str, body: bytes) -> str:
        """Append an event of ``fleet``'s vehicle ``vehicle_id``; its cursor."""
        with self._lock:
            cursor = f"{len(self._events) + 1:020d}"
            self._events.append(StoredEvent(cursor, f"{fleet}/{vehicle_id}" if fleet else vehicle_id, body))
            self._fleets.append(fleet)
        return cursor

    def events_after(self, fleet: str | None, after: str | None, limit: int) -> list[StoredEvent]:
        """Up to ``limit`` events of ``fleet`` (None: all) after the cursor ``after`` (None: from the first)."""
        with self._lock:
            start = int(after) if after is not None else 0
            if fleet is None:
                return self._events[start : start + limit]
            numbers = (number for number in range(start, len(self._events)) if self._fleets[number] == fleet)
            return [self._events[number] for _, number in zip(range(limit), numbers, strict=False)]
