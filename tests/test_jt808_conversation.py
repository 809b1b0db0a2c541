"""One connection of the JT/T 808 gateway fed its bytes directly: no sockets, no road, no work thread.

The terminal's frames are written from the standard's layout by the test (tests/jt808_terminal.py) and the
platform's read back the same way. Checked here: every frame of a read is answered, in order, in one write; a
frame cut over several reads (an escape cut from the byte it escapes included) is answered once; a report is
queued with its fix; the terminal file is looked at once per turn of the event loop, and a revocation holds
from the next turn; frames beyond a connection's burst are dropped; the driver is told only what changes.
"""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any, cast

import pytest
from jt808_terminal import Received, general_response, header_2013, location_body, read_frames, wire

from csws.gateways.jt808.terminals import TerminalList, add_terminal, revoke_terminal
from csws.gateways.jt808.texts import DriverTexts
from service.jt808 import Conversation, Gateway
from service.jt808_groups import AnswerSummary, Waiting
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


def test_the_frames_of_one_read_are_answered_in_one_write_and_the_report_queued_with_its_fix(tmp_path):
    async def run() -> None:
        gateway, queue = open_gateway(tmp_path)
        conversation, transport = authenticated(gateway)
        report = location_body(50.861234, 9.707654, 63.4, 271.0, T0_S)
        conversation.received(frame(0x0002, 2) + frame(0x0200, 3, report) + frame(0x0002, 4))
        assert len(transport.writes) == 1
        answers = transport.frames()
        assert [general_response(a) for a in answers] == [(2, 0x0002, 0), (3, 0x0200, 0), (4, 0x0002, 0)]
        assert [a.serial for a in answers] == [2, 3, 4]  # the platform's own serials, one up per frame
        [waiting] = queue.waiting
        query = waiting.query
        assert (query.position.lat, query.position.lon) == pytest.approx((50.861234, 9.707654), abs=1e-9)
        assert (query.speed_kmh, query.heading_deg, query.timestamp_s) == (63.4, 271.0, T0_S)
        assert query.age_s == pytest.approx(1.0)

    asyncio.run(run())


def test_a_frame_cut_over_reads_inside_an_escape_is_answered_once(tmp_path):
    async def run() -> None:
        gateway, _ = open_gateway(tmp_path)
        conversation, transport = authenticated(gateway)
        serial = 0x7E7D  # both bytes escaped on the wire
        whole = frame(0x0002, serial)
        cut = whole.index(b"\x7d\x02") + 1
        for piece in (whole[:3], whole[3:cut], whole[cut:]):
            assert transport.writes == []
            conversation.received(piece)
        assert [general_response(f) for f in transport.frames()] == [(serial, 0x0002, 0)]

    asyncio.run(run())


def test_the_terminal_file_is_looked_at_once_a_turn_and_a_revocation_holds_from_the_next(tmp_path, monkeypatch):
    async def run() -> None:
        gateway, _ = open_gateway(tmp_path)
        conversation, transport = authenticated(gateway)
        await asyncio.sleep(0)
        looked: list[int] = []
        refresh = gateway.terminals.refresh
        monkeypatch.setattr(gateway.terminals, "refresh", lambda: looked.append(1) or refresh())
        conversation.received(frame(0x0002, 2))
        conversation.received(frame(0x0002, 3) + frame(0x0002, 4))
        assert len(looked) == 1  # three frames, two reads, one turn of the loop
        revoke_terminal(tmp_path / "terminals.json", PHONE)
        await asyncio.sleep(0)  # the next turn
        conversation.received(frame(0x0002, 5))
        assert len(looked) == 2
        results = [general_response(f)[2] for f in transport.frames()]
        assert results == [0, 0, 0, 1]  # refused once revoked

    asyncio.run(run())


def test_frames_beyond_a_connections_burst_are_dropped(tmp_path):
    async def run() -> None:
        gateway, _ = open_gateway(tmp_path, GatewaySettings(frames_per_s=1.0, frames_burst=4.0))
        conversation, transport = authenticated(gateway)  # one of the four
        conversation.received(b"".join(frame(0x0002, serial) for serial in range(2, 8)))
        assert [general_response(f)[0] for f in transport.frames()] == [2, 3, 4]

    asyncio.run(run())


def test_the_driver_is_told_a_level_when_it_comes_on_or_rises_and_not_again(tmp_path):
    async def run() -> None:
        gateway, queue = open_gateway(tmp_path)
        conversation, transport = authenticated(gateway)
        texts = DriverTexts()
        told: list[tuple[int, str]] = []
        for serial, (level, speed_kmh) in enumerate([(0, None), (1, 61.7), (1, 61.7), (2, 48.2), (2, 48.2)], 2):
            conversation.received(frame(0x0200, serial, location_body(50.86, 9.70, 70.0, 90.0, T0_S + serial)))
            waiting = queue.waiting.pop()
            waiting.deliver(AnswerSummary("active", level, speed_kmh))
            for sent in transport.frames():
                if sent.message_id == 0x8300:
                    flags, text = sent.body[0], sent.body[1:].decode("gbk")
                    told.append((flags, text))
        display_and_speech = 0b1100
        assert told == [
            (display_and_speech, texts.level1.replace("{speed_kmh}", "61")),
            (display_and_speech | 1, texts.level2.replace("{speed_kmh}", "48")),  # level 2 is urgent
        ]

    asyncio.run(run())
