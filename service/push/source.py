"""Where the events to push come from: the service's durable outbox, read after a cursor.

The state store (:mod:`service.store`) keeps each event the service writes (a curve warning's onset,
change of level and release, a forward collision warning, a change of system state, a matching fault)
in an outbox, in the order written. Push reads it through :class:`EventSource` alone, so any store
that has :meth:`EventSource.events_after` serves, and tests serve events of their own.
"""

from __future__ import annotations

from typing import NamedTuple, Protocol

import msgspec

__all__ = ["EventSource", "StoredEvent", "Event", "parse_event"]


class StoredEvent(NamedTuple):
    """One event of the outbox as the store keeps it.

    Attributes
    ----------
    cursor
        Its place in the outbox: opaque, and later events have later cursors.
    vehicle_key
        The vehicle as the store keeps it (``fleet/vehicle_id``, :func:`service.keys.vehicle_key`).
    body
        The event, one JSON object (``fleet``, ``vehicle_id``, ``seq``, ``kind``, ``time``, ``level``,
        ``state``, ...).
    """

    cursor: str
    vehicle_key: str
    body: bytes


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
