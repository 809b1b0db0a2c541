"""JT/T 808 message bodies the gateway reads and writes (2013 and 2019 editions).

Terminal to platform: registration ``0x0100``, authentication ``0x0102``, heartbeat ``0x0002``,
deregistration ``0x0003``, the terminal's general response ``0x0001``, the location report
``0x0200`` and the batch upload ``0x0704``. Platform to terminal: the general response
``0x8001``, the re-send request for sub-packages ``0x8003``, the registration response ``0x8100``,
the text message ``0x8300`` and temporary location tracking ``0x8202``. Text is GBK; times are BCD
``YYMMDDhhmmss`` in UTC+8 (Beijing time), turned into POSIX seconds here.
"""

from __future__ import annotations

import calendar
import functools
import struct
import time
from collections.abc import Sequence
from dataclasses import dataclass
from enum import IntEnum
from typing import NamedTuple

from .frames import FrameError, bcd_decode, bcd_encode

__all__ = [
    "BodyError",
    "LocationReport",
    "MessageId",
    "Registration",
    "ResponseResult",
    "RegistrationResult",
    "TerminalResponse",
    "decode_authentication",
    "decode_location",
    "decode_location_batch",
    "decode_registration",
    "decode_temporary_tracking",
    "decode_terminal_response",
    "encode_general_response",
    "encode_location",
    "encode_package_request",
    "encode_registration_response",
    "encode_temporary_tracking",
    "encode_text_message",
]


class MessageId(IntEnum):
    """The message ids the gateway handles (JT/T 808 Table 3 of 2013, Table 5 of 2019)."""

    TERMINAL_RESPONSE = 0x0001
    HEARTBEAT = 0x0002
    DEREGISTRATION = 0x0003
    REGISTRATION = 0x0100
    AUTHENTICATION = 0x0102
    LOCATION = 0x0200
    LOCATION_BATCH = 0x0704
    PLATFORM_RESPONSE = 0x8001
    PACKAGE_REQUEST = 0x8003
    REGISTRATION_RESPONSE = 0x8100
    TEMPORARY_TRACKING = 0x8202
    TEXT_MESSAGE = 0x8300


class ResponseResult(IntEnum):
    """The result of a general response (``0x8001``, ``0x0001``)."""

    SUCCESS = 0
    FAILURE = 1
    MESSAGE_ERROR = 2
    NOT_SUPPORTED = 3
    ALARM_CONFIRMED = 4


class RegistrationResult(IntEnum):
    """The result of a registration response (``0x8100``)."""

    SUCCESS = 0
    VEHICLE_REGISTERED = 1
    NO_SUCH_VEHICLE = 2
    TERMINAL_REGISTERED = 3
    NO_SUCH_TERMINAL = 4


class BodyError(FrameError):
    """A message body that does not have the layout of its message id."""


#: Beijing time, in which JT/T 808 writes its BCD times: UTC+8.
BEIJING_OFFSET_S = 8 * 3600
#: Status bits of the location report: 1 positioned, 2 south latitude, 3 west longitude.
STATUS_POSITIONED, STATUS_SOUTH, STATUS_WEST = 1 << 1, 1 << 2, 1 << 3
_LOCATION = struct.Struct(">IIIIHHH6s")
#: Registration: the manufacturer, model and terminal id fields' sizes per edition.
_REGISTRATION_FIELDS = {2013: (5, 20, 7), 2019: (11, 30, 30)}
#: 0x8300 flags: bit 0 emergency (2013) / bits 0-1 the kind (2019), bit 2 display, bit 3 text-to-speech.
TEXT_EMERGENCY, TEXT_DISPLAY, TEXT_SPEECH = 1 << 0, 1 << 2, 1 << 3
#: 2019 0x8300 text types: 1 notice, 2 service.
TEXT_TYPE_NOTICE, TEXT_TYPE_SERVICE = 1, 2


class LocationReport(NamedTuple):
    """A location report's basic information (``0x0200``) and its additional items (a named tuple: one is made
    for every report read).

    Attributes
    ----------
    alarm_flags, status_flags
        The alarm and status double words, as sent.
    lat_deg, lon_deg
        WGS-84 degrees, signed by status bits 2 (south) and 3 (west).
    altitude_m
        Metres above sea level.
    speed_kmh
        Speed, from the report's 1/10 km/h.
    heading_deg
        Direction of travel, 0-359 degrees clockwise from north.
    time_s
        The report's time as POSIX seconds (sent in UTC+8).
    additional
        The additional items after the basic information, kept intact.
    """

    alarm_flags: int
    status_flags: int
    lat_deg: float
    lon_deg: float
    altitude_m: int
    speed_kmh: float
    heading_deg: int
    time_s: float
    additional: bytes = b""

    @property
    def positioned(self) -> bool:
        """Status bit 1: the terminal had a satellite fix when it took this report."""
        return bool(self.status_flags & STATUS_POSITIONED)


@dataclass(frozen=True)
class Registration:
    """A terminal's registration (``0x0100``): where it is licensed, what it is, and its plate."""

    province_id: int
    city_id: int
    manufacturer: str
    model: str
    terminal_id: str
    plate_colour: int
    plate: str


@dataclass(frozen=True)
class TerminalResponse:
    """A terminal's general response (``0x0001``) to one of the platform's messages."""

    serial: int
    message_id: int
    result: int


def _text(data: bytes) -> str:
    """GBK text with the padding of a fixed field (NUL bytes and spaces) stripped."""
    try:
        return data.rstrip(b"\x00 ").decode("gbk")
    except UnicodeDecodeError as error:
        raise BodyError(f"text is not GBK: {data[:40]!r}") from error


def _label(data: bytes) -> str:
    """A fixed field's GBK text as far as it is GBK (each byte that is not replaced by U+FFFD): a terminal pads
    its maker or model fields with 0xFF, or writes bytes of another code page, and is a terminal still."""
    return data.rstrip(b"\x00 \xff").decode("gbk", errors="replace")


@functools.lru_cache(maxsize=1024)
def _bcd_time_s(data: bytes) -> float:
    """POSIX seconds of a BCD ``YYMMDDhhmmss`` time in UTC+8 (years 2000-2099).

    Kept for the last 1,024 times: terminals that report every second send the same few times at once.
    """
    try:
        digits = bcd_decode(data)
    except FrameError as error:  # a nibble above 9: the body is unreadable, not the frame
        raise BodyError(f"the time is not BCD: {data.hex()}") from error
    year, month, day, hour, minute, second = (int(digits[i : i + 2]) for i in range(0, 12, 2))
    if not (1 <= month <= 12 and 1 <= day <= calendar.monthrange(2000 + year, month)[1]):
        raise BodyError(f"no such date: {digits}")
    if hour > 23 or minute > 59 or second > 59:
        raise BodyError(f"no such time of day: {digits}")
    return float(calendar.timegm((2000 + year, month, day, hour, minute, second)) - BEIJING_OFFSET_S)


def _bcd_time(time_s: float) -> bytes:
    """The BCD ``YYMMDDhhmmss`` in UTC+8 of POSIX seconds ``time_s``."""
    parts = time.gmtime(int(time_s) + BEIJING_OFFSET_S)
    return bcd_encode(
        f"{parts.tm_year % 100:02d}{parts.tm_mon:02d}{parts.tm_mday:02d}"
        f"{parts.tm_hour:02d}{parts.tm_min:02d}{parts.tm_sec:02d}",
        6,
    )


def decode_location(body: bytes) -> LocationReport:
    """The location report of a ``0x0200`` body (or one item of a ``0x0704`` batch)."""
    if len(body) < _LOCATION.size:
        raise BodyError(f"a location report has at least {_LOCATION.size} bytes, got {len(body)}")
    alarm, status, lat, lon, altitude, speed, heading, when = _LOCATION.unpack_from(body)
    if lat > 90_000_000 or lon > 180_000_000 or heading > 359:
        raise BodyError(f"latitude {lat}, longitude {lon} (1e-6 degrees) or direction {heading} out of range")
    return LocationReport(
        alarm,
        status,
        (-lat if status & STATUS_SOUTH else lat) / 1e6,
        (-lon if status & STATUS_WEST else lon) / 1e6,
        altitude,
        speed / 10.0,
        heading,
        _bcd_time_s(when),
        body[_LOCATION.size :],
    )


def encode_location(report: LocationReport) -> bytes:
    """The ``0x0200`` body of ``report``: the terminal's side, for simulators and tests."""
    status = report.status_flags & ~(STATUS_SOUTH | STATUS_WEST)
    status |= (STATUS_SOUTH if report.lat_deg < 0 else 0) | (STATUS_WEST if report.lon_deg < 0 else 0)
    return (
        _LOCATION.pack(
            report.alarm_flags,
            status,
            round(abs(report.lat_deg) * 1e6),
            round(abs(report.lon_deg) * 1e6),
            report.altitude_m,
            round(report.speed_kmh * 10),
            report.heading_deg % 360,
            _bcd_time(report.time_s),
        )
        + report.additional
    )


def decode_location_batch(body: bytes) -> tuple[int, list[LocationReport]]:
    """The batch kind (0 regular, 1 blind-area back-fill) and the reports of a ``0x0704`` body."""
    if len(body) < 3:
        raise BodyError(f"a batch upload has at least 3 bytes, got {len(body)}")
    count, kind = struct.unpack_from(">HB", body)
    reports: list[LocationReport] = []
    offset = 3
    for _ in range(count):
        if offset + 2 > len(body):
            raise BodyError(f"the batch announces {count} reports and holds {len(reports)}")
        (size,) = struct.unpack_from(">H", body, offset)
        item = body[offset + 2 : offset + 2 + size]
        if len(item) != size:
            raise BodyError(f"report {len(reports) + 1} of the batch is cut short")
        reports.append(decode_location(item))
        offset += 2 + size
    if offset != len(body):
        raise BodyError(f"{len(body) - offset} bytes follow the batch's {count} reports")
    return kind, reports


def decode_registration(body: bytes, edition: int) -> Registration:
    """The registration of a ``0x0100`` body of the given edition."""
    maker_bytes, model_bytes, id_bytes = _REGISTRATION_FIELDS[edition]
    fixed = 4 + maker_bytes + model_bytes + id_bytes + 1
    if len(body) < fixed:
        raise BodyError(f"a {edition} registration has at least {fixed} bytes, got {len(body)}")
    province, city = struct.unpack_from(">HH", body)
    model_at = 4 + maker_bytes
    id_at = model_at + model_bytes
    return Registration(
        province_id=province,
        city_id=city,
        manufacturer=_label(body[4:model_at]),
        model=_label(body[model_at:id_at]),
        terminal_id=_label(body[id_at : id_at + id_bytes]),
        plate_colour=body[fixed - 1],
        plate=_label(body[fixed:]),
    )


def decode_authentication(body: bytes, edition: int) -> str:
    """The authentication code of a ``0x0102`` body (2019: length-prefixed, IMEI and version follow)."""
    if edition == 2013:
        return _text(body)
    if not body or len(body) < 1 + body[0]:
        raise BodyError("a 2019 authentication starts with the code's length and the code")
    return _text(body[1 : 1 + body[0]])


def decode_terminal_response(body: bytes) -> TerminalResponse:
    """The terminal's general response of a ``0x0001`` body."""
    if len(body) != 5:
        raise BodyError(f"a general response has 5 bytes, got {len(body)}")
    return TerminalResponse(*struct.unpack(">HHB", body))


def encode_general_response(serial: int, message_id: int, result: ResponseResult) -> bytes:
    """The platform's general response (``0x8001``) to message ``message_id`` number ``serial``."""
    return struct.pack(">HHB", serial, message_id, result)


def encode_package_request(first_serial: int, package_numbers: Sequence[int], edition: int) -> bytes:
    """The re-send request for sub-packages (``0x8003``): the message's first serial, the count of packages asked
    for (a byte in 2013, a word in 2019) and their numbers (a word each)."""
    count = struct.pack(">B" if edition == 2013 else ">H", len(package_numbers))
    return struct.pack(">H", first_serial) + count + struct.pack(f">{len(package_numbers)}H", *package_numbers)


def encode_registration_response(serial: int, result: RegistrationResult, auth_code: str = "") -> bytes:
    """The registration response (``0x8100``); the authentication code only on success."""
    code = auth_code.encode("gbk") if result == RegistrationResult.SUCCESS else b""
    return struct.pack(">HB", serial, result) + code


def encode_text_message(
    text: str, edition: int, *, display: bool = True, speech: bool = True, emergency: bool = False
) -> bytes:
    """A text message (``0x8300``) for the driver: shown, spoken (TTS), or both.

    2013: a flag byte (bit 0 emergency, bit 2 display, bit 3 TTS) and the text. 2019: the flag
    byte (bits 0-1: 1 service, 2 emergency), the text type (1 notice) and the text.
    """
    flags = (TEXT_DISPLAY if display else 0) | (TEXT_SPEECH if speech else 0)
    encoded = text.encode("gbk")
    if edition == 2013:
        return bytes([flags | (TEXT_EMERGENCY if emergency else 0)]) + encoded
    return bytes([flags | (2 if emergency else 1), TEXT_TYPE_NOTICE]) + encoded


def encode_temporary_tracking(interval_s: int, validity_s: int) -> bytes:
    """Temporary location tracking (``0x8202``): report every ``interval_s`` for ``validity_s``.

    The body is the interval (WORD, s) and the validity (DWORD, s). (An interval of 0 stops
    tracking and has no validity after it; the gateway lets its windows expire instead.)
    """
    return struct.pack(">HI", interval_s, validity_s)


def decode_temporary_tracking(body: bytes) -> tuple[int, int]:
    """The interval and validity (s) of a ``0x8202`` body: the terminal's side, for simulators (0, 0 to stop)."""
    if len(body) == 2 and body == b"\x00\x00":
        return 0, 0
    if len(body) != 6:
        raise BodyError(f"temporary tracking has 6 bytes (2 to stop), got {len(body)}")
    interval_s, validity_s = struct.unpack(">HI", body)
    return interval_s, validity_s
