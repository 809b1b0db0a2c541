"""Headers every answer carries, and the head a request may have.

:class:`ResponseHeaders` is an ASGI middleware that

* refuses a request with more than :data:`MAX_HEADERS` header lines, or headers of more than
  :data:`service.guard.MAX_HEAD_BYTES` in all, with a 431 (a head that large arriving in parts
  is a 400 from the server before it is complete);
* adds to every answer ``X-Content-Type-Options: nosniff`` (a browser never takes a JSON answer
  or a static file for a script or a page), ``X-Frame-Options: DENY`` and
  ``Referrer-Policy: no-referrer``;
* adds to every HTML page (``/map``, ``/docs``, ``/redoc``, the static pages) a
  ``Content-Security-Policy`` that lets the page run only the service's own script files and
  its own inline scripts, by their SHA-256 (:func:`content_security_policy`), talk only to
  the service, and be framed by nobody (``frame-ancestors 'none'``). Styles may be inline:
  Swagger UI, ReDoc and Leaflet set them from their scripts.
"""

from __future__ import annotations

import base64
import hashlib
import json
import re
from typing import Any

from .guard import MAX_HEAD_BYTES

__all__ = ["MAX_HEADERS", "COMMON_HEADERS", "content_security_policy", "ResponseHeaders"]

#: Most header lines a request may have.
MAX_HEADERS = 100
#: The headers added to every answer.
COMMON_HEADERS = (
    (b"x-content-type-options", b"nosniff"),
    (b"x-frame-options", b"DENY"),
    (b"referrer-policy", b"no-referrer"),
)
_INLINE_SCRIPT = re.compile(rb"<script(?![^>]*\ssrc=)[^>]*>(.*?)</script>", re.DOTALL | re.IGNORECASE)


def content_security_policy(page: bytes) -> bytes:
    """The Content-Security-Policy of an HTML page: the service's own files, and the page's inline scripts by hash."""
    hashes = " ".join(
        f"'sha256-{base64.b64encode(hashlib.sha256(script).digest()).decode()}'"
        for script in _INLINE_SCRIPT.findall(page)
    )
    return (
        "default-src 'none'; "
        f"script-src 'self'{' ' + hashes if hashes else ''}; "
        "style-src 'self' 'unsafe-inline'; img-src 'self' data:; font-src 'self' data:; connect-src 'self'; "
        "worker-src 'self' blob:; base-uri 'none'; form-action 'none'; frame-ancestors 'none'"
    ).encode()


async def _too_many_headers(send: Any) -> None:
    """Answer a 431 for a request with too many or too large headers, closing the connection."""
    body = json.dumps(
        {"detail": f"at most {MAX_HEADERS} header lines of at most {MAX_HEAD_BYTES} bytes in all are accepted"}
    )
    headers = [
        (b"content-type", b"application/json"),
        (b"content-length", str(len(body)).encode()),
        (b"connection", b"close"),
        *COMMON_HEADERS,
    ]
    await send({"type": "http.response.start", "status": 431, "headers": headers})
    await send({"type": "http.response.body", "body": body.encode()})


class ResponseHeaders:
    """ASGI middleware: the header count of requests, the security headers of answers (see the module)."""

    def __init__(self, app: Any) -> None:
        self.app = app

    async def __call__(self, scope: Any, receive: Any, send: Any) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        headers = scope["headers"]
        if len(headers) > MAX_HEADERS or sum(len(name) + len(value) for name, value in headers) > MAX_HEAD_BYTES:
            await _too_many_headers(send)
            return
        page_start: dict[str, Any] | None = None
        page: list[bytes] = []

        async def send_with_headers(message: Any) -> None:
            nonlocal page_start
            if message["type"] == "http.response.start":
                headers = [*message.get("headers", ()), *COMMON_HEADERS]
                message = {**message, "headers": headers}
                if any(k == b"content-type" and v.startswith(b"text/html") for k, v in headers):
                    page_start = message  # held until the whole page is in, to hash its scripts
                    return
            elif page_start is not None and message["type"] == "http.response.body":
                page.append(message.get("body", b""))
                if message.get("more_body", False):
                    return
                body = b"".join(page)
                policy = (b"content-security-policy", content_security_policy(body))
                await send({**page_start, "headers": [*page_start["headers"], policy]})
                message = {"type": "http.response.body", "body": body}
            await send(message)

        await self.app(scope, receive, send_with_headers)
