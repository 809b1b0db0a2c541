"""JT/T 808 frames and bodies against byte layouts the tests write out themselves.

Every expected frame here is put together byte by byte from the standard's layout (header
fields, BCD, XOR check code, escaping by the byte), not by the code under test.
"""

from __future__ import annotations

import calendar
import re
import struct
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st
from jt808_terminal import header_2013, header_2019, wire, xor

from csws.gateways.jt808.frames import Frame, FrameError, FrameSplitter, FrameWriter, decode_frame, encode_frame
from csws.gateways.jt808.messages import (
    BodyError,
    LocationReport,
    RegistrationResult,
    ResponseResult,
    decode_authentication,
    decode_location,
    decode_location_batch,
    decode_registration,
    encode_general_response,
    encode_location,
    encode_registration_response,
    encode_text_message,
)


def test_a_heartbeat_frame_is_the_standards_bytes():
    content = header_2013(0x0002, "13800138000", 7, 0)
    frame = Frame(message_id=0x0002, phone="013800138000", serial=7)
    assert encode_frame(frame) == wire(content)
    assert decode_frame(wire(content)[1:-1]) == frame


def test_the_2019_header_carries_the_version_flag_and_a_20_digit_phone():
    body = b"\x01\x02"
    content = header_2019(0x0200, "13800138000", 65535, len(body)) + body
    decoded = decode_frame(wire(content)[1:-1])
    assert (decoded.edition, decoded.protocol_version, decoded.phone, decoded.serial) == (
        2019,
        1,
        "13800138000".rjust(20, "0"),
        65535,
    )
    assert encode_frame(decoded) == wire(content)


def test_a_subpackaged_header_has_count_and_number():
    body = b"abc"
    content = struct.pack(">HH", 0x0704, len(body) | 0x2000) + bytes(6) + struct.pack(">HHH", 1, 3, 2) + body
    decoded = decode_frame(wire(content)[1:-1])
    assert (decoded.package_count, decoded.package_number, decoded.body) == (3, 2, body)
    assert encode_frame(decoded) == wire(content)


#: Any frame's fields: escapes (0x7d, 0x7e) may fall in the id, the serial, the body and the check code.
FRAME_FIELDS = {
    "message_id": st.integers(0, 0xFFFF),
    "serial": st.integers(0, 0xFFFF),
    "body": st.binary(max_size=300),
    "phone": st.text("0123456789", min_size=1, max_size=12),
    "edition": st.sampled_from([2013, 2019]),
}


@given(**FRAME_FIELDS)
def test_frames_round_trip_with_escapes_anywhere(message_id, serial, body, phone, edition):
    """Bytes 0x7d and 0x7e in the id, the serial, the body and the check code all survive."""
    header = (header_2013 if edition == 2013 else header_2019)(message_id, phone, serial, len(body))
    encoded = wire(header + body)
    assert 0x7E not in encoded[1:-1]
    frame = decode_frame(encoded[1:-1])
    assert (frame.message_id, frame.serial, frame.body, frame.edition) == (message_id, serial, body, edition)
    assert encode_frame(frame) == encoded


def test_a_wrong_check_code_is_an_error():
    content = header_2013(0x0002, "1", 1, 0)
    bad = content + bytes([xor(content) ^ 0xFF])
    with pytest.raises(FrameError, match="check code"):
        decode_frame(bad)


@pytest.mark.parametrize(
    ("escaped", "problem"),
    [
        (b"\x00\x02\x00\x00\x7d\x03" + bytes(8), "bad escape"),
        (b"\x00\x02\x00\x00\x7d", "bad escape"),
        (bytes(5), "at least 13 bytes"),
    ],
)
def test_bad_escapes_and_short_frames_are_errors(escaped, problem):
    with pytest.raises(FrameError, match=problem):
        decode_frame(escaped)


def test_a_body_length_that_disagrees_with_the_header_is_an_error():
    content = header_2013(0x0200, "1", 1, 10) + bytes(4)
    with pytest.raises(FrameError, match="10-byte body"):
        decode_frame(wire(content)[1:-1])


def test_the_splitter_finds_frames_across_reads_and_drops_noise():
    one = wire(header_2013(0x0002, "1", 1, 0))
    two = wire(header_2013(0x0002, "1", 2, 0))
    stream = b"noise" + one + two + one[:5]
    splitter = FrameSplitter()
    found = []
    for i in range(0, len(stream), 3):  # three bytes per read
        found += splitter.feed(stream[i : i + 3])
    assert [decode_frame(f).serial for f in found] == [1, 2]
    assert splitter.dropped_bytes == len(b"noise")
    assert [decode_frame(f).serial for f in splitter.feed(one[5:])] == [1]


def test_the_splitter_drops_a_run_without_flags_and_recovers():
    splitter = FrameSplitter()
    assert splitter.feed(b"\x7e" + bytes(10_000)) == []
    assert splitter.dropped_bytes >= 10_000
    good = wire(header_2013(0x0002, "1", 9, 0))
    assert [decode_frame(f).serial for f in splitter.feed(good)] == [9]


@given(**FRAME_FIELDS)
def test_a_terminals_frame_writer_writes_the_standards_bytes(message_id, serial, body, phone, edition):
    """The platform's frames to one terminal, its header's shared part packed once, are the standard's bytes:
    the 2019 ones with the version flag and protocol version 1, the check code over every byte."""
    header = (header_2013 if edition == 2013 else header_2019)(message_id, phone, serial, len(body))
    writer = FrameWriter(phone.rjust(12 if edition == 2013 else 20, "0"), edition)
    assert writer.frame(message_id, serial, body) == wire(header + body)
    assert writer.frame(message_id, serial, body) == encode_frame(
        Frame(message_id, writer.phone, serial, body, edition, 1 if edition == 2019 else 0)
    )


def test_a_frame_writer_refuses_a_body_too_long_and_an_unknown_edition():
    with pytest.raises(FrameError, match="at most 1023"):
        FrameWriter("1", 2013).frame(0x8300, 1, bytes(1024))
    with pytest.raises(FrameError, match="2013 or 2019"):
        FrameWriter("1", 2011)


@st.composite
def chopped_stream(draw: st.DrawFn) -> tuple[list[bytes], list[int], list[bytes]]:
    """Frames whose contents are rich in 0x7d and 0x7e (escaped on the wire), and their stream cut into reads at
    random places: inside a frame, between its two flags, and between an escape byte and the one it escapes."""
    serials = draw(st.lists(st.integers(0, 0xFFFF), min_size=1, max_size=6))
    rich = st.binary(max_size=40).map(lambda b: b.replace(b"\x00", b"\x7d").replace(b"\x01", b"\x7e"))
    bodies = draw(st.lists(rich, min_size=len(serials), max_size=len(serials)))
    frames = [wire(header_2013(0x0200, "13800138000", s, len(b)) + b) for s, b in zip(serials, bodies, strict=True)]
    stream = b"".join(frames)
    cuts = sorted(draw(st.sets(st.integers(1, len(stream) - 1), max_size=12)))
    reads = [stream[a:b] for a, b in zip([0, *cuts], [*cuts, len(stream)], strict=True)]
    return reads, serials, bodies


@given(chopped_stream())
def test_the_splitter_finds_every_frame_however_the_reads_cut_the_stream(case):
    """Several frames in one read, a frame over several reads, an escape cut from the byte it escapes: each frame
    comes out once, whole, in order, and nothing is dropped."""
    reads, serials, bodies = case
    splitter = FrameSplitter()
    found = [decode_frame(escaped) for read in reads for escaped in splitter.feed(read)]
    assert [(f.serial, f.body) for f in found] == list(zip(serials, bodies, strict=True))
    assert splitter.dropped_bytes == 0


def test_an_escape_cut_at_a_read_boundary_is_read_as_one_byte():
    body = b"\x7e\x7d"
    frame = wire(header_2013(0x0200, "1", 3, len(body)) + body)
    cut = frame.index(b"\x7d\x02") + 1  # the read ends between 0x7d and 0x02
    splitter = FrameSplitter()
    assert splitter.feed(frame[:cut]) == []
    [escaped] = splitter.feed(frame[cut:])
    assert decode_frame(escaped).body == body


def location_body(lat_e6, lon_e6, speed_01kmh, heading, bcd_time, status=0b10, extra=b""):
    return (
        struct.pack(">IIIIHHH", 0, status, lat_e6, lon_e6, 123, speed_01kmh, heading) + bytes.fromhex(bcd_time) + extra
    )


def test_a_location_report_reads_position_speed_heading_and_beijing_time():
    extra = bytes([0x01, 4, 0, 0, 0x30, 0x39])  # additional item 0x01 (mileage), kept intact
    body = location_body(31_230_416, 121_473_701, 725, 270, "261126081530", extra=extra)
    report = decode_location(body)
    assert report.lat_deg == pytest.approx(31.230416) and report.lon_deg == pytest.approx(121.473701)
    assert report.speed_kmh == pytest.approx(72.5) and report.heading_deg == 270 and report.altitude_m == 123
    assert report.time_s == calendar.timegm((2026, 11, 26, 0, 15, 30))  # 08:15:30 in UTC+8
    assert report.positioned and report.additional == extra
    assert encode_location(report) == body


def test_south_and_west_status_bits_sign_the_coordinates():
    report = decode_location(location_body(33_868_800, 151_209_300, 0, 0, "260101000000", status=0b1110))
    assert (report.lat_deg, report.lon_deg) == (pytest.approx(-33.8688), pytest.approx(-151.2093))


@pytest.mark.parametrize(
    ("body", "problem"),
    [
        (bytes(20), "at least 28 bytes"),
        (location_body(0, 0, 0, 0, "261332000000"), "no such date"),
        (location_body(0, 0, 0, 0, "260230000000"), "no such date"),
        (location_body(0, 0, 0, 0, "26010124000a"), "not BCD"),
        (location_body(0, 0, 0, 400, "260101000000"), "out of range"),
    ],
)
def test_bad_location_reports_are_errors(body, problem):
    with pytest.raises(FrameError, match=problem):
        decode_location(body)


def test_a_batch_upload_gives_each_report():
    bodies = [location_body(1_000_000 * i, 2_000_000, 100 * i, 10 * i, "260101000000") for i in range(1, 4)]
    batch = struct.pack(">HB", 3, 1) + b"".join(struct.pack(">H", len(b)) + b for b in bodies)
    kind, reports = decode_location_batch(batch)
    assert kind == 1 and [r.lat_deg for r in reports] == [1.0, 2.0, 3.0]
    with pytest.raises(BodyError, match="cut short|announces"):
        decode_location_batch(batch[:-3])


def test_registration_2013_and_2019():
    plate = "京A12345".encode("gbk")
    body13 = struct.pack(">HH", 11, 101) + b"MAKER" + b"M1".ljust(20, b"\x00") + b"T000001" + b"\x01" + plate
    reg = decode_registration(body13, 2013)
    assert (reg.province_id, reg.city_id, reg.manufacturer, reg.model, reg.terminal_id, reg.plate_colour) == (
        11,
        101,
        "MAKER",
        "M1",
        "T000001",
        1,
    )
    assert reg.plate == "京A12345"
    body19 = struct.pack(">HH", 11, 101) + b"MAKER".ljust(11, b"\x00") + b"M".ljust(30, b"\x00")
    body19 += b"T1".ljust(30, b"\x00") + b"\x02" + plate
    assert decode_registration(body19, 2019).terminal_id == "T1"
    with pytest.raises(BodyError):
        decode_registration(body13[:20], 2013)


def test_authentication_codes_of_both_editions():
    assert decode_authentication(b"abc123", 2013) == "abc123"
    body19 = bytes([6]) + b"abc123" + b"8" * 15 + b"1.0".ljust(20, b"\x00")
    assert decode_authentication(body19, 2019) == "abc123"


def test_platform_answers_have_the_standards_layout():
    assert encode_general_response(0x1234, 0x0200, ResponseResult.SUCCESS) == b"\x12\x34\x02\x00\x00"
    assert encode_registration_response(5, RegistrationResult.SUCCESS, "code") == b"\x00\x05\x00code"
    assert encode_registration_response(5, RegistrationResult.NO_SUCH_TERMINAL, "code") == b"\x00\x05\x04"


def test_text_messages_are_gbk_with_display_and_speech_flags():
    text = "前方弯道，请减速"
    assert encode_text_message(text, 2013) == bytes([0b1100]) + text.encode("gbk")
    assert encode_text_message(text, 2013, emergency=True)[0] == 0b1101
    assert encode_text_message(text, 2019, emergency=True)[:2] == bytes([0b1110, 1])
    assert encode_text_message(text, 2019, speech=False)[0] == 0b0101


def test_a_location_report_round_trips_through_a_frame():
    report = LocationReport(0, 0b10, 50.86, 9.7, 210, 63.4, 359, 1_700_000_000.0)
    frame = Frame(message_id=0x0200, phone="13912345678", serial=1, body=encode_location(report))
    back = decode_location(decode_frame(encode_frame(frame)[1:-1]).body)
    assert back == report


def test_the_documented_conversation_is_well_formed():
    """docs/jt808.md's frames, read by the byte: check codes, lengths, and the message ids it names."""
    text = (Path(__file__).resolve().parents[1] / "docs" / "jt808.md").read_text("utf-8")
    frames = re.findall(r"^(T>P|P>T) (0x[0-9a-f]{4}) .*\n    ((?:[0-9a-f]{2} ?)+)$", text, re.M)
    assert [message_id for _, message_id, _ in frames] == [
        "0x0100", "0x8100", "0x0102", "0x8001", "0x0200", "0x8001", "0x8300", "0x0002", "0x8001", "0x8202", "0x0001"
    ]  # fmt: skip
    for _, message_id, hex_bytes in frames:
        raw = bytes.fromhex(hex_bytes)
        assert raw[0] == raw[-1] == 0x7E
        content = raw[1:-1].replace(b"\x7d\x02", b"\x7e").replace(b"\x7d\x01", b"\x7d")
        assert xor(content[:-1]) == content[-1]
        body_length = struct.unpack_from(">H", content, 2)[0] & 0x3FF
        assert struct.unpack_from(">H", content)[0] == int(message_id, 16) and len(content) == 12 + body_length + 1
    report = decode_location(bytes.fromhex(frames[4][2])[13:-2])
    assert (report.lat_deg, report.lon_deg, report.speed_kmh, report.heading_deg) == (50.868, 9.707, 80.0, 90)
    tracking, answer = (bytes.fromhex(hex_bytes)[13:-2] for _, _, hex_bytes in frames[-2:])
    assert struct.unpack(">HI", tracking) == (1, 34)  # every 1 s, valid 34 s
    assert struct.unpack(">HHB", answer) == (6, 0x8202, 0)  # to the platform's serial 6: success
