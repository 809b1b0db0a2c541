"""Which addresses a webhook may reach: no open relay into the service's own network.

A webhook URL is the fleet admin's, but the service makes the connection, from inside its own
network. So a URL must be ``http`` or ``https``, and every address its host resolves to must be
one the service may reach:

* never a link-local address (169.254.0.0/16, fe80::/10), a cloud's metadata address
  (:data:`METADATA_ADDRESSES`), the unspecified address, a multicast or the broadcast address;
* a loopback, private or otherwise non-global address only where the service's admin allows it
  (``CSWS_WEBHOOK_ALLOW_PRIVATE=1``, ``csws serve --webhook-allow-private``).

The check runs when a URL is added and again at each connection, whose socket then goes to the very
address checked (:func:`pinned_connection`): a name that resolves elsewhere later (DNS rebinding)
is checked again and cannot slip past.
"""

from __future__ import annotations

import http.client
import ipaddress
import socket
import ssl
from urllib.parse import SplitResult, urlsplit

__all__ = [
    "METADATA_ADDRESSES",
    "UnsafeTarget",
    "address_refusal",
    "checked_url",
    "resolved_addresses",
    "pinned_connection",
]

IPAddress = ipaddress.IPv4Address | ipaddress.IPv6Address

#: The instance metadata services of the clouds (AWS, GCP, Azure, Oracle: 169.254.169.254, link-local
#: anyway; AWS over IPv6; Alibaba Cloud), refused whatever is allowed.
METADATA_ADDRESSES = frozenset(
    ipaddress.ip_address(address) for address in ("169.254.169.254", "fd00:ec2::254", "100.100.100.200")
)
_BROADCAST = ipaddress.IPv4Address("255.255.255.255")
#: The schemes a webhook may use, and their default ports.
SCHEMES = {"http": 80, "https": 443}


class UnsafeTarget(ValueError):
    """A webhook URL or address the service will not connect to; the message says why, in one line."""


def address_refusal(address: IPAddress, allow_private: bool) -> str | None:
    """Why the service may not connect to ``address`` (None: it may), refusing link-local, metadata,
    unspecified, multicast and broadcast addresses always, and non-global ones unless ``allow_private``."""
    if isinstance(address, ipaddress.IPv6Address) and address.ipv4_mapped is not None:
        return address_refusal(address.ipv4_mapped, allow_private)
    if address in METADATA_ADDRESSES:
        return "a cloud metadata address"
    for refused, reason in (
        (address.is_link_local, "a link-local address"),
        (address.is_unspecified, "the unspecified address"),
        (address.is_multicast, "a multicast address"),
        (address == _BROADCAST, "the broadcast address"),
    ):
        if refused:
            return reason
    if not allow_private and not address.is_global:
        return "a loopback or private address (allowed only with CSWS_WEBHOOK_ALLOW_PRIVATE=1)"
    return None


def checked_url(url: str) -> SplitResult:
    """``url`` split, when it is an ``http`` or ``https`` URL with a host; else :class:`UnsafeTarget`."""
    try:
        parts = urlsplit(url)
        parts.port  # noqa: B018 - a port that is no number raises here
    except ValueError as error:
        raise UnsafeTarget(f"{url!r} is no URL: {error}") from None
    if parts.scheme not in SCHEMES:
        raise UnsafeTarget(f"{url!r}: a webhook is an http:// or https:// URL")
    if not parts.hostname:
        raise UnsafeTarget(f"{url!r}: a webhook URL needs a host")
    return parts


def resolved_addresses(url: str, allow_private: bool) -> list[IPAddress]:
    """The addresses the host of ``url`` resolves to, each one the service may reach.

    Raises
    ------
    UnsafeTarget
        For a URL that is not http(s), a host that does not resolve, or any address refused
        (:func:`address_refusal`): a name must not resolve to a refused address at all.
    """
    parts = checked_url(url)
    host = parts.hostname or ""
    port = parts.port or SCHEMES[parts.scheme]
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except (OSError, UnicodeError) as error:
        raise UnsafeTarget(f"{url!r}: the host {host!r} does not resolve ({error})") from None
    addresses = list(dict.fromkeys(ipaddress.ip_address(str(info[4][0]).split("%")[0]) for info in infos))
    for address in addresses:
        reason = address_refusal(address, allow_private)
        if reason is not None:
            raise UnsafeTarget(f"{url!r}: the host {host!r} is {address}, {reason}")
    return addresses


class _OneSend(http.client.HTTPConnection):
    """Sends a request's head and its body in one ``send``: two make the receiver wake twice, which on loopback
    costs more than the request itself."""

    def _send_output(self, message_body: object = None, encode_chunked: bool = False) -> None:
        if not isinstance(message_body, bytes) or encode_chunked:
            super()._send_output(message_body, encode_chunked)  # type: ignore[misc]
            return
        self._buffer.extend((b"", b""))  # type: ignore[attr-defined]
        head = b"\r\n".join(self._buffer)  # type: ignore[attr-defined]
        del self._buffer[:]  # type: ignore[attr-defined]
        self.send(head + message_body)


class _PinnedHTTP(_OneSend):
    """An HTTP connection whose socket goes to one address checked beforehand, whatever its host resolves to."""

    def __init__(self, host: str, port: int, timeout_s: float, address: IPAddress) -> None:
        super().__init__(host, port, timeout=timeout_s)
        self.address = address

    def connect(self) -> None:
        self.sock = socket.create_connection((str(self.address), self.port), self.timeout)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)


class _PinnedHTTPS(_OneSend, http.client.HTTPSConnection):
    """An HTTPS connection to one address checked beforehand, its certificate checked against the URL's host."""

    def __init__(self, host: str, port: int, timeout_s: float, address: IPAddress) -> None:
        super().__init__(host, port, timeout=timeout_s, context=ssl.create_default_context())
        self.address = address

    def connect(self) -> None:
        sock = socket.create_connection((str(self.address), self.port), self.timeout)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.sock = self._context.wrap_socket(sock, server_hostname=self.host)  # type: ignore[attr-defined]


def pinned_connection(url: str, allow_private: bool, timeout_s: float) -> http.client.HTTPConnection:
    """A new connection to the host of ``url``, to an address checked now (:func:`resolved_addresses`).

    Raises
    ------
    UnsafeTarget
        When the URL or any address its host resolves to is refused.
    """
    parts = checked_url(url)
    address = resolved_addresses(url, allow_private)[0]
    connection_type = _PinnedHTTPS if parts.scheme == "https" else _PinnedHTTP
    return connection_type(parts.hostname or "", parts.port or SCHEMES[parts.scheme], timeout_s, address)
