"""The access log of ``csws serve --access-log text|json``: one line per HTTP request, on standard error.

Each line says when the request ended, its method, path (without the query string), status,
duration in milliseconds, and the fleet of its API key: never the key itself, nor the body. The
``json`` format writes JSON lines (one object per line) for log shippers; ``text`` one plain line.
The line is written by :class:`service.metrics.MetricsMiddleware`, which times every request anyway;
without an access log that costs one comparison per request.
"""

from __future__ import annotations

import logging
import sys
import time
from typing import Any, Literal

import msgspec

__all__ = ["ACCESS_LOGGER", "FLEET_SCOPE_KEY", "AccessFormat", "AccessLog"]

#: The logger the access lines go to (``csws.access``, at INFO).
ACCESS_LOGGER = logging.getLogger("csws.access")
#: Where the request's fleet is kept in its ASGI scope once its key was checked (:mod:`service.security`).
FLEET_SCOPE_KEY = "csws.fleet"
#: The formats of the access log.
AccessFormat = Literal["text", "json"]

_ENCODER = msgspec.json.Encoder()


class _Line(msgspec.Struct):
    """One request of the JSON access log, its fields in this order."""

    time: str
    method: str
    path: str
    status: int
    duration_ms: float
    fleet: str | None


def _now() -> str:
    """The time now, UTC, ISO 8601 to the millisecond."""
    seconds = time.time()
    return time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(seconds)) + f".{int(seconds % 1 * 1000):03d}Z"


class AccessLog:
    """Writes a line per request to :data:`ACCESS_LOGGER`, which it gives a handler on standard error.

    Parameters
    ----------
    format
        ``text`` or ``json`` (JSON lines).
    """

    def __init__(self, format: AccessFormat) -> None:
        if format not in ("text", "json"):
            raise ValueError(f"the access log is text or json, not {format!r}")
        self.format = format
        if not ACCESS_LOGGER.handlers:
            handler = logging.StreamHandler(sys.stderr)
            handler.setFormatter(logging.Formatter("%(message)s"))
            ACCESS_LOGGER.addHandler(handler)
        ACCESS_LOGGER.setLevel(logging.INFO)
        ACCESS_LOGGER.propagate = False

    def record(self, scope: dict[str, Any], status: int, seconds: float) -> None:
        """Write the line of the request of ``scope``, answered with ``status`` in ``seconds``."""
        fleet = scope.get(FLEET_SCOPE_KEY) or None
        line = _Line(_now(), scope["method"], scope["path"], status, round(seconds * 1000.0, 3), fleet)
        if self.format == "json":
            ACCESS_LOGGER.info("%s", _ENCODER.encode(line).decode())
        else:
            ACCESS_LOGGER.info(
                "%s %s %s %d %.3f ms%s",
                line.time,
                line.method,
                line.path,
                line.status,
                line.duration_ms,
                f" fleet={fleet}" if fleet else "",
            )
