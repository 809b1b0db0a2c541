"""Sub-packaged messages through one connection of the JT/T 808 gateway fed its bytes directly
(tests/jt808_connection.py): each package answered, the whole message evaluated once, missing packages
asked for (``0x8003``) in the terminal's edition and forgotten after the last request, packages of
terminals not admitted or of messages not handled refused and not kept.
"""

from __future__ import annotations

import asyncio
import struct
import time
from collections.abc import Callable
from typing import Any, cast

from jt808_connection import PHONE, T0_S, Transport, authenticated, open_gateway
from jt808_terminal import (
    Received,
    general_response,
    location_body,
    package_header_2013,
    package_header_2019,
    wire,
)

from csws.gateways.jt808.reassembly import MAX_OPEN_MESSAGES, MAX_PACKAGES, MAX_REQUESTS
from csws.gateways.jt808.terminals import revoke_terminal
from service.jt808 import Conversation
from service.jt808_settings import GatewaySettings


def batch_packages(
    items: int, count: int, first_serial: int, header: Callable[..., bytes] = package_header_2013
) -> dict[int, bytes]:
    """A batch upload (``0x0704``) of ``items`` reports, 1 s apart from :data:`T0_S`, cut into ``count`` packages
    with serials from ``first_serial``: each package's frame by its number."""
    reports = [location_body(50.86, 9.70 + k * 1e-4, 70.0, 90.0, T0_S + k) for k in range(items)]
    body = struct.pack(">HB", items, 0) + b"".join(struct.pack(">H", len(r)) + r for r in reports)
    cuts = [len(body) * k // count for k in range(count + 1)]
    return {
        number: wire(header(0x0704, PHONE, (first_serial + number - 1) & 0xFFFF, b - a, count, number) + body[a:b])
        for number, (a, b) in enumerate(zip(cuts, cuts[1:], strict=False), 1)
    }


def package_request(received: Received, edition: int = 2013) -> tuple[int, list[int]]:
    """The (first serial, package numbers) of a re-send request ``0x8003`` (its count a byte in 2013, a word in
    2019)."""
    assert received.message_id == 0x8003
    (first_serial,) = struct.unpack_from(">H", received.body)
    count_format = ">B" if edition == 2013 else ">H"
    (count,) = struct.unpack_from(count_format, received.body, 2)
    at = 2 + struct.calcsize(count_format)
    assert len(received.body) == at + 2 * count
    return first_serial, list(struct.unpack_from(f">{count}H", received.body, at))


def test_each_package_of_a_batch_is_answered_once_and_the_whole_batch_when_its_last_package_comes(tmp_path):
    async def run() -> None:
        gateway, queue = open_gateway(tmp_path)
        conversation, transport = authenticated(gateway)
        packages = batch_packages(3, 3, 10)
        for number in (3, 1):
            assert conversation.received(packages[number])
            assert [general_response(f) for f in transport.frames()] == [(9 + number, 0x0704, 0)]  # received
            assert queue.waiting == []  # not whole yet: nothing evaluated
        assert conversation.received(packages[2])
        assert [general_response(f) for f in transport.frames()] == [(11, 0x0704, 0)]  # the batch's answer
        assert [waiting.query.timestamp_s for waiting in queue.waiting] == [T0_S, T0_S + 1, T0_S + 2]

    asyncio.run(run())


async def written(transport: Transport, timeout_s: float = 10.0) -> tuple[list[Received], float]:
    """The frames the gateway writes next, as soon as it writes any, and the monotonic time they came."""
    deadline = time.monotonic() + timeout_s
    while not transport.writes:
        assert time.monotonic() < deadline, "nothing was written"
        await asyncio.sleep(0.002)
    return transport.frames(), time.monotonic()


#: How long the gateway waits for a package before it asks for the missing ones, in these tests, s.
WAIT_S = 0.2


def test_missing_packages_are_asked_for_again_and_a_message_asked_for_in_vain_is_forgotten(tmp_path):
    async def run() -> None:
        gateway, queue = open_gateway(tmp_path, GatewaySettings(package_wait_s=WAIT_S))
        conversation, transport = authenticated(gateway)
        packages = batch_packages(6, 4, 0xFFFE)  # serials 0xFFFE, 0xFFFF, 0, 1
        conversation.received(packages[1] + packages[3])
        sent_at = time.monotonic()
        transport.frames()
        [request], asked_at = await written(transport)
        assert package_request(request) == (0xFFFE, [2, 4]) and asked_at - sent_at >= WAIT_S
        conversation.received(packages[4])  # sent again as it was: the wait starts again
        sent_at = time.monotonic()
        assert [general_response(f) for f in transport.frames()] == [(1, 0x0704, 0)]
        [request], asked_at = await written(transport)
        assert package_request(request) == (0xFFFE, [2]) and asked_at - sent_at >= WAIT_S
        conversation.received(packages[2])
        assert [general_response(f) for f in transport.frames()] == [(0xFFFF, 0x0704, 0)]
        assert len(queue.waiting) == 6

        lost = batch_packages(2, 2, 40)
        conversation.received(lost[2])
        transport.frames()
        deadline = time.monotonic() + 10.0
        while gateway.counts["dropped"] == 0 and time.monotonic() < deadline:
            await asyncio.sleep(0.01)
        assert [package_request(f) for f in transport.frames()] == [(40, [1])] * MAX_REQUESTS
        conversation.received(lost[1])  # forgotten: package 1 no longer completes it
        assert [general_response(f) for f in transport.frames()] == [(40, 0x0704, 0)]
        assert len(queue.waiting) == 6 and conversation.reassembler.next_due_s() is not None

    asyncio.run(run())


def test_a_package_sent_again_after_its_message_completed_is_answered_and_not_kept(tmp_path):
    async def run() -> None:
        gateway, queue = open_gateway(tmp_path, GatewaySettings(package_wait_s=WAIT_S))
        conversation, transport = authenticated(gateway)
        packages = batch_packages(3, 3, 10)
        conversation.received(packages[1] + packages[2] + packages[3])
        transport.frames()
        conversation.received(packages[3])  # its answer was lost: sent again
        assert [general_response(f) for f in transport.frames()] == [(12, 0x0704, 0)]
        assert conversation.reassembler.next_due_s() is None and len(queue.waiting) == 3  # not a new message

    asyncio.run(run())


def test_the_packages_of_a_revoked_terminal_are_refused_and_its_unfinished_messages_forgotten(tmp_path):
    async def run() -> None:
        gateway, queue = open_gateway(tmp_path, GatewaySettings(package_wait_s=WAIT_S))
        conversation, transport = authenticated(gateway)
        packages = batch_packages(4, 4, 20)
        conversation.received(packages[1])
        assert [general_response(f) for f in transport.frames()] == [(20, 0x0704, 0)]
        revoke_terminal(tmp_path / "terminals.json", PHONE)
        await asyncio.sleep(0)  # the file is looked at once a turn of the loop
        conversation.received(packages[2])
        assert [general_response(f) for f in transport.frames()] == [(21, 0x0704, 1)]
        assert conversation.reassembler.next_due_s() is None and queue.waiting == []

    asyncio.run(run())


def test_an_unfinished_message_making_way_for_a_ninth_is_counted_as_dropped(tmp_path):
    async def run() -> None:
        gateway, _ = open_gateway(tmp_path)
        conversation, transport = authenticated(gateway)
        for message in range(MAX_OPEN_MESSAGES + 1):
            conversation.received(batch_packages(2, 2, 100 + 2 * message)[1])
        assert len(transport.frames()) == MAX_OPEN_MESSAGES + 1 and gateway.counts["dropped"] == 1

    asyncio.run(run())


def test_a_2019_terminal_is_asked_for_its_packages_in_its_edition(tmp_path):
    async def run() -> None:
        gateway, _ = open_gateway(tmp_path, GatewaySettings(package_wait_s=WAIT_S))
        conversation, transport = authenticated(gateway)
        packages = batch_packages(4, 3, 7, header=package_header_2019)
        conversation.received(packages[2])
        transport.frames()
        [request], _ = await written(transport)
        assert request.edition == 2019 and package_request(request, 2019) == (7, [1, 3])

    asyncio.run(run())


def test_packages_beyond_the_burst_are_asked_for_again_and_the_message_completes(tmp_path):
    async def run() -> None:
        settings = GatewaySettings(package_wait_s=WAIT_S, frames_burst=10.0, frames_per_s=100.0)
        gateway, queue = open_gateway(tmp_path, settings)
        conversation, transport = authenticated(gateway)  # uses one frame of the burst
        packages = batch_packages(16, 16, 100)
        conversation.received(b"".join(packages.values()))  # 9 fit the burst
        assert len(transport.frames()) == 9 and gateway.counts["dropped"] == 7
        [request], _ = await written(transport)  # by then the allowance is full again
        assert package_request(request) == (100, list(range(10, 17)))
        conversation.received(b"".join(packages[number] for number in range(10, 17)))
        answers = [general_response(f) for f in transport.frames()]
        assert answers == [(99 + number, 0x0704, 0) for number in range(10, 17)]
        assert len(queue.waiting) == 16

    asyncio.run(run())


def test_packages_before_authentication_of_a_message_not_handled_or_too_long_are_refused_and_not_kept(tmp_path):
    async def run() -> None:
        gateway, queue = open_gateway(tmp_path)
        conversation, transport = Conversation(gateway), Transport()
        conversation.connection_made(cast(Any, transport))
        packages = batch_packages(2, 2, 1)
        conversation.received(packages[1] + packages[2])
        assert [general_response(f) for f in transport.frames()] == [(1, 0x0704, 1), (2, 0x0704, 1)]
        assert conversation.reassembler.next_due_s() is None and queue.waiting == []
        conversation, transport = authenticated(gateway)
        photo = b"\xff" * 100  # a multimedia upload (0x0801), which the gateway does not take
        conversation.received(wire(package_header_2013(0x0801, PHONE, 5, len(photo), 300, 1) + photo))
        assert [general_response(f) for f in transport.frames()] == [(5, 0x0801, 3)]
        body = b"\x00" * 10
        too_long = wire(package_header_2013(0x0704, PHONE, 6, len(body), MAX_PACKAGES + 1, 1) + body)
        conversation.received(too_long)  # beyond the packages a message may have: a message error
        assert [general_response(f) for f in transport.frames()] == [(6, 0x0704, 2)]
        assert conversation.reassembler.next_due_s() is None

    asyncio.run(run())
