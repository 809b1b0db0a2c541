"""Sub-packaged JT/T 808 messages put back together, and the packages that did not come asked for again.

A message longer than one frame's body is sent as packages 1..N of one message id with
consecutive serials (the first package's serial plus the package number minus one), each
with the total and its number in the header. Packages may arrive in any order; a message is
handed on once all its packages are in, under the serial of the package that completed it.

JT/T 808-2013, 7.12 (sub-packaged messages): a receiver that misses packages may ask for them
with the re-send request ``0x8003``, and the sender sends each again as it was. So a message
that has heard nothing for the wait (:class:`Reassembler`'s ``wait_s``) has its missing packages
asked for (:meth:`Reassembler.missing_due`), up to :data:`MAX_REQUESTS` times, and is forgotten
after the last request goes unanswered as long. At most :data:`MAX_OPEN_MESSAGES` are kept per
connection, so a terminal cannot fill the gateway's memory with first packages. A package of a
message completed shortly before (sent again because its answer was lost) is not kept: it would
start the message anew, and asking for the rest would have the whole message evaluated twice.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple

from .frames import Frame, FrameError

__all__ = ["MAX_OPEN_MESSAGES", "MAX_PACKAGES", "MAX_REQUESTS", "PACKAGE_WAIT_S", "Missing", "Reassembler"]

#: A message whose packages have not all come is asked for the missing ones after this long without a
#: package, s (as the gateways in use do: the standard names no time).
PACKAGE_WAIT_S = 10.0
#: The missing packages of a message are asked for at most this many times, a wait apart; a message
#: still missing some a wait after the last request is forgotten.
MAX_REQUESTS = 3
#: Unfinished messages kept per connection; the one heard from least recently is forgotten for a new one.
MAX_OPEN_MESSAGES = 8
#: The most packages a message may announce: 64 KiB of body.
MAX_PACKAGES = 64

_Key = tuple[int, int, int]  # message id, package count, first serial


class Missing(NamedTuple):
    """The packages of one message to ask for again (the body of a re-send request ``0x8003``)."""

    message_id: int
    first_serial: int
    package_numbers: list[int]


@dataclass
class _Unfinished:
    """The packages of one message that have come, and when the message was last heard from or asked for."""

    heard_s: float
    packages: dict[int, bytes] = field(default_factory=dict)
    requests: int = 0


class Reassembler:
    """Collects the packages of sub-packaged messages of one connection.

    Parameters
    ----------
    clock
        Monotonic seconds.
    wait_s
        How long a message waits for a package before the missing ones are asked for, s.
    forgot
        Called with the message id of each unfinished message forgotten: asked for in vain, or
        making way for a new one beyond :data:`MAX_OPEN_MESSAGES`.
    """

    def __init__(
        self,
        clock: Callable[[], float] = time.monotonic,
        wait_s: float = PACKAGE_WAIT_S,
        forgot: Callable[[int], None] = lambda message_id: None,
    ) -> None:
        self._clock = clock
        self.wait_s = wait_s
        self._forgot = forgot
        self._open: dict[_Key, _Unfinished] = {}
        #: Messages completed lately, and when: the time a terminal may still send one of their packages again.
        self._completed: dict[_Key, float] = {}

    def add(self, frame: Frame) -> Frame | None:
        """The whole message once the package ``frame`` completes it (its serial the completing package's),
        else None.

        Raises
        ------
        FrameError
            For a message announcing more than :data:`MAX_PACKAGES` packages.
        """
        if frame.package_count > MAX_PACKAGES:
            raise FrameError(f"a message of {frame.package_count} packages is longer than {MAX_PACKAGES} allowed")
        now = self._clock()
        first_serial = (frame.serial - frame.package_number + 1) & 0xFFFF
        key = (frame.message_id, frame.package_count, first_serial)
        unfinished = self._open.get(key)
        if unfinished is None:
            if self._completed_lately(key, now):
                return None
            if len(self._open) >= MAX_OPEN_MESSAGES:
                oldest = min(self._open, key=lambda k: self._open[k].heard_s)
                del self._open[oldest]
                self._forgot(oldest[0])
            unfinished = self._open[key] = _Unfinished(now)
        unfinished.heard_s = now
        unfinished.packages[frame.package_number] = frame.body
        if len(unfinished.packages) < frame.package_count:
            return None
        del self._open[key]
        self._completed[key] = now
        body = b"".join(unfinished.packages[number] for number in range(1, frame.package_count + 1))
        return frame._replace(body=body, package_count=0, package_number=0)

    def _completed_lately(self, key: _Key, now: float) -> bool:
        """Whether the message ``key`` was completed within the time its terminal may send a package again (as long
        as an unfinished message is kept: a wait, and a wait after each request); the record of older ones, and
        of all but the latest :data:`MAX_OPEN_MESSAGES`, is dropped."""
        kept_s = self.wait_s * (MAX_REQUESTS + 1)
        recent = [(k, at) for k, at in self._completed.items() if now - at <= kept_s][-MAX_OPEN_MESSAGES:]
        self._completed = dict(recent)
        return key in self._completed

    def clear(self) -> None:
        """Forget every unfinished message (its terminal is no longer admitted)."""
        self._open.clear()

    def next_due_s(self) -> float | None:
        """When the earliest unfinished message will have waited :attr:`wait_s` (the clock's seconds); None
        without one."""
        if not self._open:
            return None
        return min(unfinished.heard_s for unfinished in self._open.values()) + self.wait_s

    def missing_due(self) -> list[Missing]:
        """The packages to ask for again now: those of each message that has waited :attr:`wait_s` since it was
        last heard from or asked for, at most :data:`MAX_REQUESTS` times (a message asked for that often without
        an answer is forgotten)."""
        now = self._clock()
        asked: list[Missing] = []
        for key, unfinished in list(self._open.items()):
            if now - unfinished.heard_s < self.wait_s:
                continue
            if unfinished.requests >= MAX_REQUESTS:
                del self._open[key]
                self._forgot(key[0])
                continue
            message_id, count, first_serial = key
            numbers = [number for number in range(1, count + 1) if number not in unfinished.packages]
            asked.append(Missing(message_id, first_serial, numbers))
            unfinished.requests += 1
            unfinished.heard_s = now
        return asked
