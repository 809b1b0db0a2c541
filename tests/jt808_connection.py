"""One connection of the JT/T 808 gateway without sockets, road or work thread: a transport that keeps what
is written, a batcher that keeps what is queued, and a gateway admitting one terminal."""

from __future__ import annotations

from pathlib import Path
from typing import Any, cast

from jt808_terminal import (
    Received,
    general_response,
    header_2013,
    read_frames,
    wire,
)

from csws.gateways.jt808.terminals import TerminalList, add_terminal
from service.jt808 import Conversation, Gateway
from service.jt808_groups import Waiting
from service.jt808_settings import GatewaySettings

PHONE = "13800138000"
#: The reports' time, and the gateway's clock a second later, POSIX s.
T0_S = 1_790_000_000.0


class Transport:
    """A connection's transport that keeps what is written, write by write."""

    def __init__(self) -> None:
        self.writes: list[bytes] = []
        self.closed = False

    def write(self, data: bytes) -> None:
        self.writes.append(data)

    def is_closing(self) -> bool:
        return self.closed

    def close(self) -> None:
        self.closed = True

    def pause_reading(self) -> None:
        pass

    def resume_reading(self) -> None:
        pass

    def frames(self) -> list[Received]:
        """The frames written since last asked, read as a terminal reads them."""
        written, self.writes = b"".join(self.writes), []
        return read_frames(written)


class Queue:
    """The gateway's batcher, keeping the reports queued for their warnings."""

    def __init__(self) -> None:
        self.waiting: list[Waiting] = []

    def queue(self, waiting: Waiting) -> None:
        self.waiting.append(waiting)


def frame(message_id: int, serial: int, body: bytes = b"") -> bytes:
    return wire(header_2013(message_id, PHONE, serial, len(body)) + body)


def open_gateway(tmp_path: Path, settings: GatewaySettings | None = None) -> tuple[Gateway, Queue]:
    """A gateway admitting the terminal ``PHONE``, its batcher a :class:`Queue`."""
    add_terminal(tmp_path / "terminals.json", "acme", PHONE, category="N")
    terminals = TerminalList(tmp_path / "terminals.json")
    gateway = Gateway(
        cast(Any, None), cast(Any, None), terminals, settings or GatewaySettings(), clock=lambda: T0_S + 1.0
    )
    queue = Queue()
    gateway.batcher = cast(Any, queue)
    return gateway, queue


def authenticated(gateway: Gateway) -> tuple[Conversation, Transport]:
    """A connection of ``PHONE``, authenticated with its code (serial 1)."""
    conversation, transport = Conversation(gateway), Transport()
    conversation.connection_made(cast(Any, transport))
    listed = gateway.terminals.terminal(PHONE)
    assert listed is not None
    code = gateway.terminals.auth_code(listed).encode()
    assert conversation.received(frame(0x0102, 1, code))
    assert [general_response(f) for f in transport.frames()] == [(1, 0x0102, 0)]
    return conversation, transport
