"""Sub-packaged JT/T 808 messages put back together.

A message longer than one frame's body is sent as packages 1..N of one message id with
consecutive serials (the first package's serial plus the package number minus one), each
with the total and its number in the header. Packages may arrive in any order; a message is
handed on once all its packages are in. Unfinished messages are forgotten after
:data:`PACKAGE_TIMEOUT_S`, and at most :data:`MAX_OPEN_MESSAGES` are kept per connection, so a
terminal cannot fill the gateway's memory with first packages.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from .frames import Frame, FrameError

__all__ = ["MAX_OPEN_MESSAGES", "PACKAGE_TIMEOUT_S", "Reassembler"]

#: An unfinished message is forgotten after this long, s.
PACKAGE_TIMEOUT_S = 60.0
#: Unfinished messages kept per connection; the oldest is forgotten for a new one.
MAX_OPEN_MESSAGES = 8
#: The most packages a message may announce: 64 KiB of body.
MAX_PACKAGES = 64

_Key = tuple[int, int, int]  # message id, package count, first serial


class Reassembler:
    """Collects the packages of sub-packaged messages of one connection."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._clock = clock
        self._open: dict[_Key, tuple[float, dict[int, bytes]]] = {}

    def add(self, frame: Frame) -> Frame | None:
        """The whole message once ``frame`` completes it (``frame`` itself when not sub-packaged), else None.

        Raises
        ------
        FrameError
            For a message announcing more than :data:`MAX_PACKAGES` packages.
        """
        if not frame.subpackaged:
            return frame
        if frame.package_count > MAX_PACKAGES:
            raise FrameError(f"a message of {frame.package_count} packages is longer than {MAX_PACKAGES} allowed")
        now = self._clock()
        self._open = {k: v for k, v in self._open.items() if now - v[0] <= PACKAGE_TIMEOUT_S}
        first_serial = (frame.serial - frame.package_number + 1) & 0xFFFF
        key = (frame.message_id, frame.package_count, first_serial)
        if key not in self._open and len(self._open) >= MAX_OPEN_MESSAGES:
            del self._open[min(self._open, key=lambda k: self._open[k][0])]
        started, packages = self._open.setdefault(key, (now, {}))
        packages[frame.package_number] = frame.body
        if len(packages) < frame.package_count:
            return None
        del self._open[key]
        body = b"".join(packages[number] for number in range(1, frame.package_count + 1))
        return frame._replace(serial=first_serial, body=body, package_count=0, package_number=0)
