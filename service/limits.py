"""Bounded requests: a body limit, a JSON content type, and no waiting for clients that stall.

:class:`BodyLimit` reads the body of every ``POST`` and ``PUT`` itself before the app sees it:

* a declared ``Content-Length`` above the limit is a 413 at once, without reading the body;
  a body without one that grows past the limit is a 413 as soon as it does;
* a body that is not ``application/json`` is a 415 (every body of the API is JSON);
* a client that sends no part of its body for ``timeout_s`` gets a 408 and is closed.

The endpoints then read the body from memory. A batch naming ``"vehicle_id"`` more times
than a batch may hold queries is refused before it is validated (:func:`too_many_queries`).
"""

from __future__ import annotations

import asyncio
import json
from collections.abc import Sequence

__all__ = ["BodyLimit", "too_many_queries"]

_BODY_METHODS = frozenset({"POST", "PUT", "PATCH"})


def too_many_queries(body: bytes, limit: int) -> int:
    """How many queries a batch body holds when that is certainly more than ``limit``, else 0.

    Every query has a ``"vehicle_id"`` key, and inside a JSON string the quotes of that word
    are escaped, so the word in quotes counts keys. Counting is a scan of bytes, far cheaper
    than validating the queries.
    """
    count = body.count(b'"vehicle_id"')
    return count if count > limit else 0


async def _respond(send, status: int, detail: str, extra_headers: Sequence[tuple[bytes, bytes]] = ()) -> None:
    body = json.dumps({"detail": detail}).encode()
    headers = [
        (b"content-type", b"application/json"),
        (b"content-length", str(len(body)).encode()),
        (b"connection", b"close"),
        *extra_headers,
    ]
    await send({"type": "http.response.start", "status": status, "headers": headers})
    await send({"type": "http.response.body", "body": body})


def _header(scope, name: bytes) -> str | None:
    for key, value in scope["headers"]:
        if key == name:
            return value.decode("latin-1")
    return None


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

    def __init__(self, app, max_bytes: int, timeout_s: float) -> None:
        self.app = app
        self.max_bytes = int(max_bytes)
        self.timeout_s = float(timeout_s)

    async def __call__(self, scope, receive, send) -> None:
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
        chunks, size = [], 0
        while True:
            try:
                async with asyncio.timeout(self.timeout_s):  # no task per chunk, unlike wait_for
                    message = await receive()
            except TimeoutError:
                await _respond(send, 408, f"the body did not arrive: nothing came for {self.timeout_s:g} s")
                return
            if message["type"] == "http.disconnect":
                return
            chunk = message.get("body", b"")
            size += len(chunk)
            if size > self.max_bytes:
                await _respond(send, 413, f"the body is over {self.max_bytes} bytes, the most accepted")
                return
            chunks.append(chunk)
            if not message.get("more_body", False):
                break
        body = b"".join(chunks)
        delivered = False

        async def replay():
            nonlocal delivered
            if delivered:
                return await receive()
            delivered = True
            return {"type": "http.request", "body": body, "more_body": False}

        await self.app(scope, replay, send)
