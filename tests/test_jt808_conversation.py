"""One connection of the JT/T 808 gateway fed its bytes directly (tests/jt808_connection.py): no sockets, no
road, no work thread. Sub-packaged messages are tests/test_jt808_packages.py's.

The terminal's frames are written from the standard's layout by the test (tests/jt808_terminal.py) and the
platform's read back the same way. Checked here: every frame of a read is answered, in order, in one write; a
frame cut over several reads (an escape cut from the byte it escapes included) is answered once; a report is
queued with its fix; the terminal file is looked at once per turn of the event loop, and a revocation holds
from the next turn; frames beyond a connection's burst are dropped; the driver is told only what changes; a
registration's plate is checked against the list; reports left waiting when a connection ends are counted as shed.
"""

from __future__ import annotations

import asyncio
import struct
from typing import Any, cast

import pytest
from jt808_connection import PHONE, T0_S, Transport, authenticated, frame, open_gateway
from jt808_terminal import (
    Received,
    general_response,
    header_2013,
    header_2019,
    location_body,
    registration_body,
    wire,
)

from csws.gateways.jt808.terminals import add_terminal, revoke_terminal
from csws.gateways.jt808.texts import DriverTexts
from service.jt808 import Conversation
from service.jt808_groups import AnswerSummary
from service.jt808_settings import GatewaySettings


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


def test_reports_left_waiting_when_a_connection_ends_are_counted_as_shed(tmp_path):
    async def run() -> None:
        gateway, queue = open_gateway(tmp_path)
        conversation, _ = authenticated(gateway)
        reports = [frame(0x0200, 2 + k, location_body(50.86, 9.70, 60.0, 90.0, T0_S + k)) for k in range(3)]
        conversation.received(b"".join(reports))
        queue.waiting[0].started = True  # its group began: it is answered, not shed
        conversation.connection_lost(None)
        assert [waiting.shed for waiting in queue.waiting] == [True, True, True]
        assert gateway.counts["shed"] == 2 and "0 report(s) evaluated, 2 shed" in gateway.summary()

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


def test_a_report_whose_time_is_not_bcd_is_answered_as_unreadable_and_the_connection_lives(tmp_path):
    async def run() -> None:
        gateway, queue = open_gateway(tmp_path)
        conversation, transport = authenticated(gateway)
        report = location_body(50.86, 9.70, 70.0, 90.0, T0_S)
        unreadable = report[:-6] + bytes([0x26, 0x11, 0xAA, 0x10, 0x00, 0x00])  # a day of 0xAA: no BCD digits
        assert conversation.received(frame(0x0200, 2, unreadable) + frame(0x0002, 3))
        assert [general_response(f) for f in transport.frames()] == [(2, 0x0200, 2), (3, 0x0002, 0)]
        assert queue.waiting == [] and not transport.closed

    asyncio.run(run())


def test_a_terminal_file_that_cannot_be_read_leaves_the_terminals_read_before_admitted(tmp_path):
    async def run() -> None:
        gateway, _ = open_gateway(tmp_path)
        conversation, transport = authenticated(gateway)
        path = tmp_path / "terminals.json"
        content = path.read_text("utf-8")
        path.write_text(content[: len(content) // 2], "utf-8")  # a hand edit saved half way
        await asyncio.sleep(0)
        assert conversation.received(frame(0x0002, 2))
        path.unlink()
        await asyncio.sleep(0)
        assert conversation.received(frame(0x0002, 3))
        assert [general_response(f) for f in transport.frames()] == [(2, 0x0002, 0), (3, 0x0002, 0)]
        path.write_text(content, "utf-8")
        revoke_terminal(path, PHONE)  # a good file again: read, and its revocation holds
        await asyncio.sleep(0)
        assert conversation.received(frame(0x0002, 4))
        assert [general_response(f) for f in transport.frames()] == [(4, 0x0002, 1)]

    asyncio.run(run())


def test_an_authenticated_connection_speaks_for_its_terminal_alone(tmp_path):
    async def run() -> None:
        gateway, queue = open_gateway(tmp_path)
        other = "13900000000"
        add_terminal(tmp_path / "terminals.json", "acme", other, category="N")
        conversation, transport = authenticated(gateway)
        report = location_body(50.86, 9.70, 70.0, 90.0, T0_S)
        posing = wire(header_2013(0x0200, other, 2, len(report)) + report)
        assert conversation.received(posing + frame(0x0200, 3, report))
        refused, answered = transport.frames()
        assert general_response(refused) == (2, 0x0200, 1)
        assert refused.phone.lstrip("0") == other and answered.phone.lstrip("0") == PHONE  # each to its sender
        assert general_response(answered) == (3, 0x0200, 0)
        assert [waiting.query.vehicle_id for waiting in queue.waiting] == [gateway.terminals.terminal(PHONE).vehicle_id]
        renaming = wire(header_2013(0x0100, other, 4, 0)) + frame(0x0002, 5)  # a registration as the other: refused
        assert conversation.received(renaming)
        refused, beat = transport.frames()
        assert (refused.message_id, general_response(refused)) == (0x8001, (4, 0x0100, 1)) and refused.phone.endswith(
            other
        )
        assert general_response(beat) == (5, 0x0002, 0) and beat.phone.lstrip("0") == PHONE  # still its own

    asyncio.run(run())


def test_a_registration_naming_another_plate_than_the_list_is_refused_as_no_such_vehicle(tmp_path):
    async def run() -> None:
        gateway, _ = open_gateway(tmp_path)
        add_terminal(tmp_path / "terminals.json", "acme", "13900000000", category="N", plate="京A12345")
        conversation, transport = Conversation(gateway), Transport()
        conversation.connection_made(cast(Any, transport))

        def register(serial: int, body: bytes) -> Received:
            assert conversation.received(wire(header_2013(0x0100, "13900000000", serial, len(body)) + body))
            [answer] = transport.frames()
            return answer

        def result(answer: Received) -> tuple[int, int]:
            """The (serial answered, result) of a 0x8100."""
            assert answer.message_id == 0x8100
            return struct.unpack_from(">HB", answer.body)

        assert result(register(1, registration_body("京B99999"))) == (1, 2)  # another vehicle: no such vehicle
        assert result(register(2, registration_body("京a 12345"))) == (2, 0)  # the list's plate, written otherwise
        assert result(register(3, registration_body("LSVAU2180N2183294", plate_colour=0))) == (3, 0)  # a VIN: no plate
        assert result(register(4, registration_body(""))) == (4, 0)  # no plate named
        assert result(register(5, registration_body("京Ａ　１２３４５"))) == (5, 0)  # full-width letters and space
        padded = registration_body("京A12345").replace(b"T".ljust(20, b"\x00"), b"T\x80" + b"\xff" * 18)
        assert result(register(6, padded)) == (6, 0)  # a model field padded with 0xFF, a byte that is not GBK
        unreadable = register(7, registration_body("京A12345")[:20])
        assert (unreadable.message_id, general_response(unreadable)) == (0x8001, (7, 0x0100, 2))

    asyncio.run(run())


def test_a_terminal_listed_again_for_another_vehicle_registers_again_and_its_plate_is_checked(tmp_path):
    async def run() -> None:
        gateway, _ = open_gateway(tmp_path)
        phone, path = "13900000000", tmp_path / "terminals.json"
        add_terminal(path, "acme", phone, category="N", plate="京A12345")

        def answers(conversation: Conversation, transport: Transport, message_id: int, body: bytes) -> Received:
            assert conversation.received(wire(header_2013(message_id, phone, 1, len(body)) + body))
            [answer] = transport.frames()
            return answer

        def connection() -> tuple[Conversation, Transport]:
            conversation, transport = Conversation(gateway), Transport()
            conversation.connection_made(cast(Any, transport))
            return conversation, transport

        registered = answers(*connection(), 0x0100, registration_body("京A12345"))
        assert struct.unpack_from(">HB", registered.body) == (1, 0)
        old_code = registered.body[3:]
        assert general_response(answers(*connection(), 0x0102, old_code)) == (1, 0x0102, 0)  # good on a new connection
        add_terminal(path, "acme", phone, category="N", plate="京B99999")  # the terminal is moved to another truck
        await asyncio.sleep(0)  # the file is looked at again from the next turn
        assert general_response(answers(*connection(), 0x0102, old_code)) == (1, 0x0102, 1)  # the old code fails
        refused = answers(*connection(), 0x0100, registration_body("京A12345"))
        assert struct.unpack_from(">HB", refused.body) == (1, 2)  # still in the old truck: no such vehicle
        again = answers(*connection(), 0x0100, registration_body("京B99999"))
        assert struct.unpack_from(">HB", again.body) == (1, 0) and again.body[3:] != old_code
        assert general_response(answers(*connection(), 0x0102, again.body[3:])) == (1, 0x0102, 0)

    asyncio.run(run())


def test_a_report_that_cannot_be_answered_tells_the_driver_of_a_fault_once_it_lasts(tmp_path):
    async def run() -> None:
        gateway, queue = open_gateway(tmp_path)
        conversation, transport = authenticated(gateway)
        texts = DriverTexts()
        told = []
        answers = [AnswerSummary("active", 0, None), None, None, None, AnswerSummary("active", 0, None)]
        for serial, (offset_s, answer) in enumerate(zip([0.0, 1.0, 6.0, 11.0, 12.0], answers, strict=True), 2):
            conversation.received(frame(0x0200, serial, location_body(50.86, 9.70, 70.0, 90.0, T0_S + offset_s)))
            queue.waiting.pop().deliver(answer)  # None: the state store was unreachable
            told += [f.body[1:].decode("gbk") for f in transport.frames() if f.message_id == 0x8300]
        assert told == [texts.fault, texts.restored]  # after 10 s without an answer, and once answered again

    asyncio.run(run())


def test_a_2019_terminal_is_answered_in_its_own_edition(tmp_path):
    async def run() -> None:
        gateway, queue = open_gateway(tmp_path)
        listed = gateway.terminals.terminal(PHONE)
        assert listed is not None
        conversation, transport = Conversation(gateway), Transport()
        conversation.connection_made(cast(Any, transport))
        code = gateway.terminals.auth_code(listed).encode()
        # 2019 authentication: code length, code, IMEI (15) and software version (20)
        authentication = bytes([len(code)]) + code + b"8".ljust(15, b"0") + b"1.0".ljust(20, b"\x00")
        report = location_body(50.86, 9.70, 70.0, 90.0, T0_S)
        sent = [(0x0102, 1, authentication), (0x0200, 2, report)]
        assert conversation.received(b"".join(wire(header_2019(m, PHONE, n, len(b)) + b) for m, n, b in sent))
        answers = transport.frames()
        assert [general_response(f) for f in answers] == [(1, 0x0102, 0), (2, 0x0200, 0)]
        assert {(f.edition, f.phone) for f in answers} == {(2019, PHONE.rjust(20, "0"))}
        [waiting] = queue.waiting
        waiting.deliver(AnswerSummary("active", 2, 48.2))
        [text] = transport.frames()
        assert text.message_id == 0x8300 and text.edition == 2019
        assert text.body[:2] == bytes([0b1110, 1])  # 2019: display, speech, kind 2 (emergency); text type 1 (notice)
        assert text.body[2:].decode("gbk") == DriverTexts().level2.replace("{speed_kmh}", "48")

    asyncio.run(run())
