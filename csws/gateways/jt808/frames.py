"""JT/T 808 frames: delimiting, escaping, the check code and the message header (2013 and 2019).

A frame on the wire is ``0x7e | header | body | check code | 0x7e``. Between the flags,
``0x7e`` is sent as ``0x7d 0x02`` and ``0x7d`` as ``0x7d 0x01``; the check code is the XOR of
every header and body byte before escaping. Words and double words are big-endian.

The header (JT/T 808-2013 4.4.3 / 2019 4.5.3):

* message id (WORD) and body properties (WORD): bits 0-9 the body length, 10-12 the
  encryption, 13 sub-packaged, and in the 2019 edition bit 14 the version flag;
* 2019 only: the protocol version (BYTE);
* the terminal's phone number in BCD: 6 bytes (12 digits) in 2013, 10 bytes (20 digits) in 2019;
* the message serial (WORD);
* when sub-packaged: the total number of packages and this package's number (WORD each, from 1).

Everything here is pure: bytes in, frames out, and :class:`FrameError` naming what is wrong.
"""

from __future__ import annotations

import functools
import struct
from typing import NamedTuple

from csws.errors import CswsError

__all__ = [
    "FLAG",
    "MAX_BODY_BYTES",
    "MAX_FRAME_BYTES",
    "Frame",
    "FrameError",
    "FrameSplitter",
    "FrameWriter",
    "bcd_decode",
    "bcd_encode",
    "check_code",
    "decode_frame",
    "encode_frame",
    "escape",
    "unescape",
]

#: The flag byte that opens and closes every frame.
FLAG = 0x7E
#: The escape byte: 0x7d 0x02 stands for 0x7e, 0x7d 0x01 for 0x7d.
ESCAPE = 0x7D
#: Bits 0-9 of the body properties give the body's length, so a body has at most 1,023 bytes.
MAX_BODY_BYTES = 0x3FF
#: The longest frame between the flags once unescaped: a 2019 header with sub-packages (21 bytes),
#: the longest body and the check code.
MAX_FRAME_BYTES = 21 + MAX_BODY_BYTES + 1

#: Phone numbers whose BCD form is kept, so that a connection's every frame does not convert its phone again.
PHONES_KEPT = 32_768

_SUBPACKAGED = 1 << 13
_VERSION_FLAG = 1 << 14
_ENCRYPTION_MASK = 0b111 << 10
_PHONE_BYTES = {2013: 6, 2019: 10}
_FLAG_BYTE = bytes([FLAG])
#: The header up to the serial, whole: message id, body properties, (2019: protocol version,) phone, serial.
_HEAD_2013, _HEAD_2019 = struct.Struct(">HH6sH"), struct.Struct(">HHB10sH")
_WORDS = struct.Struct(">HH")


class FrameError(CswsError, ValueError):
    """A frame that cannot be read: a bad escape, check code, length or header."""


class Frame(NamedTuple):
    """One JT/T 808 message: its header's fields and its body (a named tuple: made for every frame read).

    Attributes
    ----------
    message_id
        The message id, e.g. ``0x0200`` for a location report.
    phone
        The terminal's phone number as the decimal digits of its BCD field (leading zeros kept:
        12 digits in 2013, 20 in 2019).
    serial
        The message serial, 0-65535, counted by the sender.
    body
        The message body, unescaped.
    edition
        2013 or 2019 (the 2019 edition sets the version flag, bit 14 of the body properties).
    protocol_version
        The 2019 header's protocol version byte (1 for the 2019 edition); 0 in 2013.
    encryption
        Bits 10-12 of the body properties: 0 plain, bit 10 RSA.
    package_count, package_number
        Sub-packaging: the total number of packages and this one's number from 1; 0 and 0 for a
        message in one frame.
    """

    message_id: int
    phone: str
    serial: int
    body: bytes = b""
    edition: int = 2013
    protocol_version: int = 0
    encryption: int = 0
    package_count: int = 0
    package_number: int = 0

    @property
    def subpackaged(self) -> bool:
        """Whether this frame is one package of a longer message."""
        return self.package_count > 0


def escape(data: bytes) -> bytes:
    """Escape ``0x7d`` and ``0x7e`` for the wire (0x7d -> 0x7d 0x01, 0x7e -> 0x7d 0x02)."""
    return data.replace(b"\x7d", b"\x7d\x01").replace(b"\x7e", b"\x7d\x02")


def unescape(data: bytes) -> bytes:
    """Undo :func:`escape`; :class:`FrameError` for a ``0x7d`` not followed by 0x01 or 0x02."""
    if b"\x7d" not in data:
        return data
    parts = data.split(b"\x7d")
    out = bytearray(parts[0])
    for part in parts[1:]:
        if not part or part[0] not in (0x01, 0x02):
            raise FrameError("bad escape: 0x7d must be followed by 0x01 or 0x02")
        out.append(ESCAPE if part[0] == 0x01 else FLAG)
        out += part[1:]
    return bytes(out)


def check_code(data: bytes) -> int:
    """The XOR of every byte of ``data`` (the header and body, before escaping)."""
    code = 0
    for byte in data:
        code ^= byte
    return code


@functools.lru_cache(maxsize=PHONES_KEPT)
def bcd_encode(digits: str, size: int) -> bytes:
    """``digits`` as ``size`` bytes of packed BCD, zero-padded on the left (kept for the phones in use)."""
    if not digits.isdigit() or len(digits) > 2 * size:
        raise FrameError(f"a BCD[{size}] field holds up to {2 * size} decimal digits, got {digits[:40]!r}")
    return bytes.fromhex(digits.rjust(2 * size, "0"))


@functools.lru_cache(maxsize=PHONES_KEPT)
def bcd_decode(data: bytes) -> str:
    """The decimal digits of packed BCD ``data``; :class:`FrameError` for a nibble above 9 (kept for the phones in
    use)."""
    digits = data.hex()
    if not digits.isdigit():
        raise FrameError(f"not BCD: {digits}")
    return digits


def _header(frame: Frame) -> bytes:
    """The header of ``frame`` with the body length filled in."""
    if len(frame.body) > MAX_BODY_BYTES:
        raise FrameError(f"a body holds at most {MAX_BODY_BYTES} bytes, got {len(frame.body)}")
    if frame.edition not in _PHONE_BYTES:
        raise FrameError(f"the edition is 2013 or 2019, got {frame.edition}")
    properties = len(frame.body) | ((frame.encryption << 10) & _ENCRYPTION_MASK)
    if frame.subpackaged:
        properties |= _SUBPACKAGED
    head = struct.pack(">HH", frame.message_id, properties | (_VERSION_FLAG if frame.edition == 2019 else 0))
    if frame.edition == 2019:
        head += bytes([frame.protocol_version])
    head += bcd_encode(frame.phone, _PHONE_BYTES[frame.edition]) + struct.pack(">H", frame.serial)
    if frame.subpackaged:
        head += struct.pack(">HH", frame.package_count, frame.package_number)
    return head


def encode_frame(frame: Frame) -> bytes:
    """``frame`` as it goes on the wire: flag, escaped header, body and check code, flag."""
    content = _header(frame) + frame.body
    return bytes([FLAG]) + escape(content + bytes([check_code(content)])) + bytes([FLAG])


def decode_frame(escaped: bytes) -> Frame:
    """The frame whose bytes between the two flags are ``escaped``.

    The check code is right when the XOR of every byte, itself included, is 0; the header up to the
    serial is read in one unpack.

    Raises
    ------
    FrameError
        For a bad escape, a check code that does not match, a header cut short, a body whose
        length differs from the header's, or a phone number that is not BCD.
    """
    content = unescape(escaped)
    size = len(content)
    if size < 13:
        raise FrameError(f"a frame has at least 13 bytes (a 2013 header and the check code), got {size}")
    if check_code(content):
        raise FrameError(f"check code {content[-1]:#04x} does not match {check_code(content[:-1]):#04x}")
    properties = content[2] << 8 | content[3]
    if properties & _VERSION_FLAG:
        edition, head = 2019, _HEAD_2019
    else:
        edition, head = 2013, _HEAD_2013
    head_bytes = head.size + (4 if properties & _SUBPACKAGED else 0)
    if size < head_bytes + 1:
        raise FrameError(f"the header is cut short: {size - 1} bytes for a {head_bytes}-byte header")
    if edition == 2019:
        message_id, _, protocol_version, phone_bcd, serial = head.unpack_from(content)
    else:
        (message_id, _, phone_bcd, serial), protocol_version = head.unpack_from(content), 0
    package_count = package_number = 0
    if properties & _SUBPACKAGED:
        package_count, package_number = _WORDS.unpack_from(content, head.size)
        if not 1 <= package_number <= package_count:
            raise FrameError(f"package {package_number} of {package_count} does not exist")
    if size - head_bytes - 1 != properties & MAX_BODY_BYTES:
        raise FrameError(
            f"the header gives a {properties & MAX_BODY_BYTES}-byte body, the frame has {size - head_bytes - 1}"
        )
    return Frame(
        message_id,
        bcd_decode(phone_bcd),
        serial,
        content[head_bytes:-1],
        edition,
        protocol_version,
        (properties & _ENCRYPTION_MASK) >> 10,
        package_count,
        package_number,
    )


class FrameWriter:
    """Writes the platform's frames to one terminal, with the part of the header they all share packed once.

    Every frame to a terminal has the same phone number (BCD), edition and, in 2019, protocol
    version (1); only the message id, the body's length, the serial and the body change, so the
    check code of the shared part is kept too. The bytes are :func:`encode_frame`'s for the same
    fields (a frame in one package, unencrypted).

    Raises
    ------
    FrameError
        For an edition other than 2013 and 2019 or a phone number that is not decimal digits.
    """

    def __init__(self, phone: str, edition: int) -> None:
        if edition not in _PHONE_BYTES:
            raise FrameError(f"the edition is 2013 or 2019, got {edition}")
        self.phone, self.edition = phone, edition
        shared = (b"\x01" if edition == 2019 else b"") + bcd_encode(phone, _PHONE_BYTES[edition])
        self._shared, self._shared_code = shared, check_code(shared)
        self._version_flag = _VERSION_FLAG if edition == 2019 else 0
        self._head = struct.Struct(f">HH{len(shared)}sH")

    def frame(self, message_id: int, serial: int, body: bytes) -> bytes:
        """The frame of message ``message_id`` number ``serial`` with ``body``, as it goes on the wire."""
        if len(body) > MAX_BODY_BYTES:
            raise FrameError(f"a body holds at most {MAX_BODY_BYTES} bytes, got {len(body)}")
        properties = len(body) | self._version_flag
        words = message_id ^ properties ^ serial  # the XOR of the header's words, byte by byte below
        code = self._shared_code ^ (words >> 8) ^ (words & 0xFF) ^ check_code(body)
        content = self._head.pack(message_id, properties, self._shared, serial) + body + bytes((code,))
        return _FLAG_BYTE + escape(content) + _FLAG_BYTE


class FrameSplitter:
    """Cuts a TCP byte stream into the escaped contents of frames.

    Bytes before the first flag are dropped; two flags in a row (one frame's end and the next
    one's start, or an empty frame) give nothing. A run between flags longer than an escaped
    :data:`MAX_FRAME_BYTES` frame can be is dropped whole, so a peer that never sends a flag
    cannot make the buffer grow: :attr:`dropped_bytes` counts what was thrown away.
    """

    #: The longest escaped run a frame can have: every byte escaped into two.
    MAX_ESCAPED_BYTES = 2 * MAX_FRAME_BYTES

    def __init__(self) -> None:
        #: The escaped bytes of the frame begun and not yet ended; None outside a frame (before the first flag,
        #: or after a run too long for a frame).
        self._pending: bytes | None = None
        self.dropped_bytes = 0

    def feed(self, data: bytes) -> list[bytes]:
        """The complete frames (their escaped bytes between the flags) that ``data`` ends."""
        pieces = bytes(data).split(_FLAG_BYTE)
        frames: list[bytes] = []
        pending = self._pending
        if pending is None:
            self.dropped_bytes += len(pieces[0])
        else:
            pending = self._within_bounds(pending + pieces[0])
        for piece in pieces[1:]:  # each piece after a flag
            if pending:
                frames.append(pending)
            pending = piece if len(piece) <= self.MAX_ESCAPED_BYTES else self._within_bounds(piece)
        self._pending = pending
        return frames

    def _within_bounds(self, run: bytes) -> bytes | None:
        """``run`` if a frame can be that long; else None, its bytes counted as dropped."""
        if len(run) <= self.MAX_ESCAPED_BYTES:
            return run
        self.dropped_bytes += len(run)
        return None
