"""A JT/T 808-2013 terminal written from the standard's byte layout, independent of the gateway's code.

It frames, escapes and checks its messages by the byte, and reads the platform's frames the same
way, so that the tests check the gateway against the standard and not against itself.
"""

from __future__ import annotations

import asyncio
import calendar
import struct
import time
from dataclasses import dataclass

#: Beijing time (UTC+8), in which the reports' BCD times are written.
BEIJING_S = 8 * 3600


def xor(data: bytes) -> int:
    out = 0
    for byte in data:
        out ^= byte
    return out


def wire(content: bytes) -> bytes:
    """Header and body framed: check code, escaping by the byte, flags."""
    escaped = bytearray()
    for byte in content + bytes([xor(content)]):
        escaped += {0x7E: b"\x7d\x02", 0x7D: b"\x7d\x01"}.get(byte, bytes([byte]))
    return b"\x7e" + bytes(escaped) + b"\x7e"


def header_2013(message_id: int, phone: str, serial: int, body_len: int) -> bytes:
    return struct.pack(">HH", message_id, body_len) + bytes.fromhex(phone.rjust(12, "0")) + struct.pack(">H", serial)


def header_2019(message_id: int, phone: str, serial: int, body_len: int) -> bytes:
    """The 2019 header: the version flag (bit 14 of the body properties), protocol version 1, a 20-digit phone."""
    head = struct.pack(">HHB", message_id, body_len | 0x4000, 1)
    return head + bytes.fromhex(phone.rjust(20, "0")) + struct.pack(">H", serial)


def package_header_2013(message_id: int, phone: str, serial: int, body_len: int, count: int, number: int) -> bytes:
    """The 2013 header of package ``number`` of ``count``: the sub-package flag (bit 13) and the package item."""
    return header_2013(message_id, phone, serial, body_len | 0x2000) + struct.pack(">HH", count, number)


def package_header_2019(message_id: int, phone: str, serial: int, body_len: int, count: int, number: int) -> bytes:
    """The 2019 header of package ``number`` of ``count``."""
    return header_2019(message_id, phone, serial, body_len | 0x2000) + struct.pack(">HH", count, number)


def bcd_time(time_s: float) -> bytes:
    t = time.gmtime(int(time_s) + BEIJING_S)
    return bytes.fromhex(
        f"{t.tm_year % 100:02d}{t.tm_mon:02d}{t.tm_mday:02d}{t.tm_hour:02d}{t.tm_min:02d}{t.tm_sec:02d}"
    )


def registration_body(plate: str, plate_colour: int = 1) -> bytes:
    """A 2013 registration: province 11, city 101, maker (5 bytes), model (20), terminal id (7), plate colour,
    plate (GBK)."""
    fixed = struct.pack(">HH", 11, 101) + b"CSWS1" + b"T".ljust(20, b"\x00") + b"0000001"
    return fixed + bytes([plate_colour]) + plate.encode("gbk")


def location_body(lat_deg: float, lon_deg: float, speed_kmh: float, heading_deg: float, time_s: float) -> bytes:
    """A 0x0200 body: alarm 0, status positioned (bit 1), north and east."""
    return struct.pack(
        ">IIIIHHH",
        0,
        0b10,
        round(lat_deg * 1e6),
        round(lon_deg * 1e6),
        0,
        round(speed_kmh * 10),
        round(heading_deg) % 360,
    ) + bcd_time(time_s)


@dataclass(frozen=True)
class Received:
    """A platform frame as the terminal reads it."""

    message_id: int
    serial: int
    body: bytes
    #: The phone number of the header, its BCD digits (2013: 12 digits, 2019: 20).
    phone: str = ""
    edition: int = 2013


def read_frames(data: bytes) -> list[Received]:
    """The frames in ``data`` (whole frames only), unescaped and checked."""
    frames = []
    for part in data.split(b"\x7e"):
        if not part:
            continue
        raw = part.replace(b"\x7d\x02", b"\x7e").replace(b"\x7d\x01", b"\x7d")
        assert xor(raw[:-1]) == raw[-1], "the platform's check code is wrong"
        message_id, properties = struct.unpack_from(">HH", raw)
        if properties & 0x4000:  # 2019: a version byte, then a 10-byte phone
            assert raw[4] == 1, "the platform's protocol version is wrong"
            phone, (serial,), body, edition = raw[5:15].hex(), struct.unpack_from(">H", raw, 15), raw[17:-1], 2019
        else:
            phone, (serial,), body, edition = raw[4:10].hex(), struct.unpack_from(">H", raw, 10), raw[12:-1], 2013
        assert len(body) == properties & 0x3FF, "the platform's body length is wrong"
        frames.append(Received(message_id, serial, body, phone, edition))
    return frames


class Terminal:
    """One terminal's TCP connection to the gateway."""

    def __init__(self, phone: str, plate: str = "") -> None:
        self.phone, self.serial, self.plate = phone, 0, plate
        self.auth_code = b""
        self.inbox: list[Received] = []
        self._buffer = b""

    async def connect(self, port: int) -> None:
        self.reader, self.writer = await asyncio.open_connection("127.0.0.1", port)

    async def send(self, message_id: int, body: bytes = b"") -> int:
        """Send a message; its serial."""
        self.serial += 1
        self.writer.write(wire(header_2013(message_id, self.phone, self.serial, len(body)) + body))
        await self.writer.drain()
        return self.serial

    async def receive(self, count: int, timeout_s: float = 10.0) -> list[Received]:
        """Wait until ``count`` more frames have come; them."""
        deadline = time.monotonic() + timeout_s
        while len(self.inbox) < count:
            remaining = deadline - time.monotonic()
            assert remaining > 0, f"only {len(self.inbox)} of {count} frames came"
            data = await asyncio.wait_for(self.reader.read(65536), remaining)
            assert data, "the gateway closed the connection"
            self._buffer += data
            end = self._buffer.rfind(b"\x7e")
            complete, self._buffer = self._buffer[: end + 1], self._buffer[end + 1 :]
            if complete.count(b"\x7e") % 2 == 1:  # an opening flag whose frame is still coming
                start = complete.rfind(b"\x7e")
                complete, self._buffer = complete[:start], complete[start:] + self._buffer
            self.inbox += read_frames(complete)
        taken, self.inbox = self.inbox[:count], self.inbox[count:]
        return taken

    async def register_and_authenticate(self) -> Received:
        """0x0100 then 0x0102 with the code the 0x8100 gave; the platform's 0x8001."""
        await self.send(0x0100, registration_body(self.plate))
        [answer] = await self.receive(1)
        assert answer.message_id == 0x8100
        serial, result = struct.unpack_from(">HB", answer.body)
        assert (serial, result) == (self.serial, 0), f"registration refused with result {result}"
        self.auth_code = answer.body[3:]
        await self.send(0x0102, self.auth_code)
        [response] = await self.receive(1)
        return response

    async def close(self) -> None:
        self.writer.close()


def general_response(received: Received) -> tuple[int, int, int]:
    """The (serial, message id, result) of a 0x8001."""
    assert received.message_id == 0x8001
    return struct.unpack(">HHB", received.body)


def posix_s(year: int, month: int, day: int, hour: int, minute: int, second: int) -> float:
    return float(calendar.timegm((year, month, day, hour, minute, second)))
