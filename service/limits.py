"""Bounded requests: a body limit, a JSON content type, and no waiting for clients that stall.

:class:`BodyLimit` bounds the body of every ``POST`` and ``PUT``:

* a declared ``Content-Length`` above the limit is a 413 at once, without reading the body;
  a body without one that grows past the limit is a 413 as soon as it does;
* a body that is not ``application/json`` is a 415 (every body of the API is JSON);
* a client that sends no part of its body for ``timeout_s`` gets a 408 and is closed.

The body is read only when a route reads it, after the caller's key was checked
(:mod:`service.security`): a request without a valid key gets its 401 before any of its body
is read. A batch naming ``"vehicle_id"`` more times
than a batch may hold queries is refused before it is validated (:func:`too_many_queries`).
"""

from __future__ import annotations

import asyncio
import json
from collections.abc import Sequence
from typing import Any

from fastapi.responses import JSONResponse

__all__ = ["BodyLimit", "BodyRefused", "refused", "too_many_queries"]

_BODY_METHODS = frozenset({"POST", "PUT", "PATCH"})


def too_many_queries(body: bytes, limit: int) -> int:
    """How many queries a batch body holds when that is certainly more than ``limit``, else 0.

    Every query has a ``"vehicle_id"`` key, and inside a JSON string the quotes of that word
    are escaped, so the word in quotes counts keys. Counting is a scan of bytes, far cheaper
    than validating the queries.
    """
    count = body.count(b'"vehicle_id"')
    return count if count > limit else 0


async def _respond(send: Any, status: int, detail: str, extra_headers: Sequence[tuple[bytes, bytes]] = ()) -> None:
    """Answer ``{"detail": detail}`` with ``status`` straight from the middleware, closing the connection."""
    body = json.dumps({"detail": detail}).encode()
    headers = [
        (b"content-type", b"application/json"),
        (b"content-length", str(len(body)).encode()),
        (b"connection", b"close"),
        *extra_headers,
    ]
    await send({"type": "http.response.start", "status": status, "headers": headers})
    await send({"type": "http.response.body", "body": body})


def _header(scope: Any, name: bytes) -> str | None:
    """The value of the request header ``name`` (lower case), None without one."""
    for key, value in scope["headers"]:
        if key == name:
            return value.decode("latin-1")
    return None


class BodyRefused(Exception):
    """A body the service will not read to its end: too large (413) or stalled (408). The app answers it
    (:func:`refused`) and the connection is closed."""

    def __init__(self, status_code: int, detail: str) -> None:
        super().__init__(detail)
        self.status_code = status_code
        self.detail = detail


async def refused(_request: Any, exc: Exception) -> JSONResponse:
    """The answer to a :class:`BodyRefused`, closing the connection (the rest of the body is never read)."""
    assert isinstance(exc, BodyRefused)
    return JSONResponse({"detail": exc.detail}, status_code=exc.status_code, headers={"Connection": "close"})


class BodyLimit:
    """ASGI middleware bounding request bodies (see the module).

    Parameters
    ----------
    app
        The application.
    max_bytes
        The largest body accepted, bytes.
    timeout_s
        How long a client may pause while sending its body, s.
    """

    def __init__(self, app: Any, max_bytes: int, timeout_s: float) -> None:
        self.app = app
        self.max_bytes = int(max_bytes)
        self.timeout_s = float(timeout_s)

    async def __call__(self, scope: Any, receive: Any, send: Any) -> None:
        if scope["type"] != "http" or scope["method"] not in _BODY_METHODS:
            await self.app(scope, receive, send)
            return
        declared = _header(scope, b"content-length")
        if declared is not None and declared.isdigit() and int(declared) > self.max_bytes:
            await _respond(send, 413, f"the body is {int(declared)} bytes; at most {self.max_bytes} are accepted")
            return
        media_type = (_header(scope, b"content-type") or "").split(";")[0].strip().lower()
        if media_type != "application/json":
            await _respond(send, 415, "the body must be JSON: Content-Type: application/json")
            return
        await self.app(scope, self._bounded(receive), send)

    def _bounded(self, receive: Any) -> Any:
        """``receive`` for the app: each part of the body within the timeout, the whole within the limit."""
        size, complete = 0, False

        async def bounded() -> Any:
            """The next message of the request, refused when the body stalls or grows too large."""
            nonlocal size, complete
            if complete:  # the body is in: what comes now (a disconnect) may take its time
                return await receive()
            try:
                async with asyncio.timeout(self.timeout_s):  # no task per part, unlike wait_for
                    message = await receive()
            except TimeoutError:
                raise BodyRefused(408, f"the body did not arrive: nothing came for {self.timeout_s:g} s") from None
            if message["type"] == "http.request":
                size += len(message.get("body", b""))
                if size > self.max_bytes:
                    raise BodyRefused(413, f"the body is over {self.max_bytes} bytes, the most accepted")
                complete = not message.get("more_body", False)
            return message

        return bounded
