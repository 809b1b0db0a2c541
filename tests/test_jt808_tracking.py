"""Temporary location tracking (0x8202): its bytes, the regular interval, when to ask, and a terminal that honours it.

The 0x8202 body is written here from JT/T 808's layout (WORD interval in s, 0 to stop, then DWORD
validity in s); when to ask is checked against formula (1) (6.1) and the latency allowance computed
here, with V_w from the standard's tables; a tracking window's end is checked against a terminal
whose timeline (clock skew, transit, queue, downlink, the validity from receipt) the test lays out;
the simulated terminal is driven by a platform written here byte by byte (tests/jt808_terminal.py),
which asks it for tracking after its first report, on a clock the test moves itself.
"""

from __future__ import annotations

import asyncio
import calendar
import math
import struct
from collections.abc import Callable

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st
from jt808_terminal import BEIJING_S, header_2013, read_frames, wire

from csws.gateways.jt808.frames import decode_frame
from csws.gateways.jt808.messages import BodyError, decode_temporary_tracking, encode_temporary_tracking
from csws.gateways.jt808.simulator import SimulatedTerminal, Track, simulate
from csws.gateways.jt808.tracking import CurveAhead, ReportPace, TrackingSettings, tracking_window_s
from csws.standard import warning_speed
from csws.warning.rules import WarningSettings

REACTION_S, G_MPS2 = 0.8, 9.8  # formula (1), 6.1
#: The engine's defaults the allowance is computed with here: system delay, and the longest period it learns, s.
DELAY_S, CAP_S = 0.1, 5.0
#: A guard against a hang only: how long the test waits for what it drives to happen, s (never a measured time).
HANG_S = 60.0


def test_a_tracking_request_is_the_standards_bytes():
    body = struct.pack(">HI", 1, 45)  # interval 1 s, valid 45 s
    frame = wire(header_2013(0x8202, "13800138000", 7, len(body)) + body)
    decoded = decode_frame(frame[1:-1])
    assert (decoded.message_id, decoded.serial, decoded.body) == (0x8202, 7, body)
    assert encode_temporary_tracking(1, 45) == body
    assert decode_temporary_tracking(body) == (1, 45)
    assert decode_temporary_tracking(b"\x00\x00") == (0, 0)  # stop: no validity follows
    with pytest.raises(BodyError):
        decode_temporary_tracking(b"\x00\x01\x00")


@given(
    st.floats(2.0, 60.0),
    st.lists(st.floats(-0.3, 0.3), min_size=6, max_size=12),
    st.integers(1, 4),
    st.integers(5, 40),
)
def test_the_regular_interval_ignores_the_reports_of_a_window(interval_s, jitter_s, ask_after, window_s):
    """Reports every T (with jitter) and every second inside a window: the interval learnt is the median of the
    intervals between reports outside it, as the test computes them."""
    pace, time_s, outside = ReportPace(), 1_790_000_000.0, []
    for k, jitter in enumerate(jitter_s):
        time_s += interval_s + jitter if k else 0.0
        pace.observe(time_s)
        outside.append(time_s)
        if k == ask_after:
            assert pace.start(time_s, window_s, 0.0, TrackingSettings())
            assert not pace.start(time_s, window_s, 0.0, TrackingSettings())  # not while one runs
            end_s = time_s + window_s
            while time_s + 1.0 <= end_s:
                time_s += 1.0
                pace.observe(time_s)
                assert pace.tracking(time_s)
            outside.append(math.nan)  # the interval across the window's end does not count
    intervals = [b - a for a, b in zip(outside, outside[1:], strict=False) if not (math.isnan(a) or math.isnan(b))]
    expected = float(np.median(intervals[-5:]))
    assert pace.regular_interval_s() == pytest.approx(expected)
    assert pace.due(time_s, TrackingSettings()) is not None


@given(
    st.integers(2, 60),
    st.integers(5, 300),
    st.floats(-30.0, 30.0),
    st.floats(0.0, 10.0),
    st.floats(0.0, 2.0),
    st.floats(0.0, 10.0),
)
def test_a_late_terminals_tracked_reports_never_count_as_its_regular_interval(
    interval_s, validity_s, skew_s, uplink_s, queue_s, downlink_s
):
    """A terminal reports every T s, stamped in whole seconds of its own clock (``skew_s`` behind the gateway's).
    A report reaches the gateway ``uplink_s`` late, the request leaves ``queue_s`` after that, and reaches the
    terminal ``downlink_s`` later; the terminal then reports every second for the validity from that moment, and
    at its regular times after. Every tracked report is seen inside the window, every interval learnt is T, and
    once back at its pace the terminal is due to be checked again."""
    settings, pace = TrackingSettings(), ReportPace()
    regular_s = [1_790_000_000.0 + interval_s * k for k in range(4)]
    for time_s in regular_s:
        pace.observe(time_s)
    asked_s = regular_s[-1]
    age_at_request_s = skew_s + uplink_s + queue_s  # the gateway's clock when it sends, less the report's stamp
    assert pace.start(asked_s, validity_s, age_at_request_s, settings)
    received_s = asked_s + uplink_s + queue_s + downlink_s  # on the terminal's clock
    tracked_s = [math.floor(received_s + k) for k in range(1, validity_s + 1)]
    in_flight_s = [asked_s + interval_s * k for k in range(1, 100) if asked_s + interval_s * k <= received_s]
    after_s = [t for t in (asked_s + interval_s * k for k in range(1, 200)) if t > received_s + validity_s][:4]
    for time_s in in_flight_s + tracked_s:
        pace.observe(time_s)
        assert pace.tracking(time_s)
    for time_s in after_s:
        pace.observe(time_s)
    assert set(pace.intervals_s) == {interval_s}  # the window ended, and no 1 s interval counted
    assert pace.regular_interval_s() == interval_s and not pace.tracking(after_s[-1])
    assert pace.due(after_s[-1], settings) == (interval_s,) * len(pace.intervals_s)


def test_a_terminal_that_stays_at_the_tracked_pace_is_seen_fast_in_the_end():
    """Past the window's end (the validity from its first 1 s report, at 131 s) and the overrun, 1 s reports
    count as the terminal's own interval."""
    settings, pace = TrackingSettings(overrun_s=20.0), ReportPace()
    for k in range(4):
        pace.observe(100.0 + 10.0 * k)
    assert pace.start(130.0, 30, 0.0, settings)
    for time_s in range(131, 240):
        pace.observe(float(time_s))
        assert pace.tracking(time_s) == (time_s <= 131 + 30 + settings.overrun_s)
    assert pace.regular_interval_s() == 1.0 and pace.due(240.0, settings) is None  # 1 s: not slow


def test_a_terminal_that_refuses_is_not_asked_again():
    pace = ReportPace()
    for k in range(4):
        pace.observe(100.0 + 10.0 * k)
    assert pace.due(130.0, TrackingSettings()) == (10.0, 10.0, 10.0)
    pace.refuse()
    assert pace.due(140.0, TrackingSettings()) is None
    assert not pace.start(140.0, 30, 0.0, TrackingSettings())
    fast = ReportPace()
    for k in range(6):
        fast.observe(100.0 + 1.2 * k)
    assert fast.due(106.0, TrackingSettings()) is None  # 1.2 s: not slow


def _formula_1_m(speed_kmh: float, warning_speed_kmh: float) -> float:
    v, v_w = speed_kmh / 3.6, warning_speed_kmh / 3.6
    return REACTION_S * v + (v * v - v_w * v_w) / G_MPS2


@given(
    st.floats(60.0, 400.0),
    st.floats(0.0, 900.0),
    st.floats(40.0, 120.0),
    st.floats(2.0, 30.0),
    st.sampled_from(["M1", "M2", "N"]),
    st.floats(20.0, 300.0),
)
def test_tracking_is_asked_when_the_next_report_could_pass_the_warning_point(
    radius_m, distance_m, speed_kmh, interval_s, category, curve_m
):
    v_w1 = warning_speed(radius_m, category, 1)
    speed_mps = speed_kmh / 3.6
    point_m = _formula_1_m(speed_kmh, v_w1) + speed_mps * (min(interval_s, CAP_S) + DELAY_S)
    margin_m = distance_m - speed_mps * interval_s - point_m
    assume(abs(margin_m) > 0.01 and abs(speed_kmh - v_w1) > 0.01)  # not on the boundary itself
    curve = CurveAhead(distance_m, radius_m, distance_m + curve_m)
    settings = TrackingSettings()
    window = tracking_window_s([curve], speed_kmh, category, (interval_s,) * 3, 0.0, WarningSettings(), settings)
    assert (window is not None) == (speed_kmh > v_w1 and margin_m < 0)
    if window is not None:  # until the curve is left at its warning speed, and the margin
        leave_s = (distance_m + curve_m) / (v_w1 / 3.6) + settings.margin_s
        assert window == min(settings.max_window_s, math.ceil(leave_s))


def test_a_curve_behind_or_two_curves_ahead():
    settings, warning = TrackingSettings(), WarningSettings()
    passed = CurveAhead(0.0, 100.0, 0.0)
    assert tracking_window_s([passed], 90.0, "N", (10.0,) * 3, 0.0, warning, settings) is None
    near, far = CurveAhead(50.0, 100.0, 150.0), CurveAhead(120.0, 200.0, 400.0)
    assert warning_speed(200.0, "N", 1) < 90.0  # both warn at 90 km/h, and both are within reach
    window = tracking_window_s([near, far], 90.0, "N", (10.0,) * 3, 0.0, warning, settings)
    slowest_leave_s = max(150.0 / (warning_speed(100.0, "N", 1) / 3.6), 400.0 / (warning_speed(200.0, "N", 1) / 3.6))
    assert window == math.ceil(slowest_leave_s + settings.margin_s)
    gentle = CurveAhead(60.0, 200.0, 200.0)  # V_w 87 km/h, above 80 km/h: no warning point at all
    assert tracking_window_s([gentle], 80.0, "N", (10.0,) * 3, 0.0, warning, settings) is None


class _SteppedClock:
    """A simulator clock the test moves itself: waits end when it is moved past them, never on the wall clock."""

    def __init__(self, posix_s: float) -> None:
        self.now_s, self.posix_at_zero_s = 0.0, posix_s
        self.moved = asyncio.Event()

    def monotonic(self) -> float:
        return self.now_s

    def posix(self) -> float:
        return self.posix_at_zero_s + self.now_s

    async def wait(self, until: float, event: asyncio.Event | None = None) -> bool:
        while self.now_s < until:
            if event is not None and event.is_set():
                return True
            self.moved.clear()
            waits = [asyncio.ensure_future(self.moved.wait())]
            if event is not None:
                waits.append(asyncio.ensure_future(event.wait()))
            _, pending = await asyncio.wait(waits, return_when=asyncio.FIRST_COMPLETED)
            for waiting in pending:
                waiting.cancel()
        return False

    def move_to(self, now_s: float) -> None:
        self.now_s = now_s
        self.moved.set()


class _Platform:
    """A platform written from the byte layout: admits one terminal, asks it for 1 s tracking for ``validity_s``
    after its first report, and keeps what it hears."""

    def __init__(self, validity_s: int) -> None:
        self.validity_s, self.serial = validity_s, 0
        self.reports: list[tuple[float, float, float]] = []
        self.responses: list[tuple[int, int, int]] = []
        self.asked_serial = -1
        self.heard, self.left = asyncio.Event(), asyncio.Event()

    def send(self, writer: asyncio.StreamWriter, message_id: int, phone: str, body: bytes) -> int:
        self.serial += 1
        writer.write(wire(header_2013(message_id, phone, self.serial, len(body)) + body))
        return self.serial

    async def converse(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        buffer = b""
        while data := await reader.read(65536):
            buffer += data
            end = buffer.rfind(b"\x7e")
            complete, buffer = buffer[: end + 1], buffer[end + 1 :]
            for frame in read_frames(complete):
                self.hear(writer, frame)
            self.heard.set()
        self.left.set()

    async def until(self, heard: Callable[[], bool]) -> None:
        """Wait until what the platform has heard makes ``heard`` true."""
        while not heard():
            self.heard.clear()
            await asyncio.wait_for(self.heard.wait(), HANG_S)

    def hear(self, writer: asyncio.StreamWriter, frame) -> None:
        phone = "13800138000"
        if frame.message_id == 0x0100:
            self.send(writer, 0x8100, phone, struct.pack(">HB", frame.serial, 0) + b"CODE")
        elif frame.message_id == 0x0102:
            self.send(writer, 0x8001, phone, struct.pack(">HHB", frame.serial, 0x0102, 0))
        elif frame.message_id == 0x0200:
            _, _, lat, lon = struct.unpack_from(">IIII", frame.body)
            self.reports.append((lon / 1e6, lat / 1e6, bcd_posix_s(frame.body[22:28])))
            self.send(writer, 0x8001, phone, struct.pack(">HHB", frame.serial, 0x0200, 0))
            if len(self.reports) == 1:
                self.asked_serial = self.send(writer, 0x8202, phone, struct.pack(">HI", 1, self.validity_s))
        elif frame.message_id == 0x0001:
            self.responses.append(struct.unpack(">HHB", frame.body))


def bcd_posix_s(bcd: bytes) -> float:
    """The POSIX time of a report's BCD time (YYMMDDhhmmss, UTC+8)."""
    year, month, day, hour, minute, second = (int(f"{byte:02x}") for byte in bcd)
    return float(calendar.timegm((2000 + year, month, day, hour, minute, second))) - BEIJING_S


def test_the_simulated_terminal_reports_every_second_while_asked():
    """Track rows at 0 s and 4 s; asked after the first report for 1 s reports valid 2 s: reports at 0, 1, 2 and
    4 s, those at 1 s and 2 s on the track's line a quarter and a half of the way, each stamped with its time.

    The terminal's clock is the test's: it is moved on only once the platform has heard what the terminal does
    at the moment before (the answer to the request, then each report), so nothing depends on how fast the
    machine is. Moved from 2 s straight to 4 s, a report wrongly due at 3 s would still be sent, and seen."""
    lon_deg = np.array([9.0, 9.004])
    track = Track(np.array([0.0, 4.0]), lon_deg, np.array([50.0, 50.0]), np.array([14.4, 14.4]), np.array([90.0, 90.0]))
    start_s = 1_790_000_000.0
    platform, clock = _Platform(validity_s=2), _SteppedClock(start_s)

    async def run():
        server = await asyncio.start_server(platform.converse, "127.0.0.1", 0)
        port = server.sockets[0].getsockname()[1]
        async with server:
            terminals = [SimulatedTerminal("13800138000", track)]
            simulating = asyncio.ensure_future(simulate(terminals, "127.0.0.1", port, ramp_s=0.0, clock=clock))
            await platform.until(lambda: len(platform.responses) >= 1)  # the request taken up, at 0 s
            for now_s, reports in ((1.0, 2), (2.0, 3), (4.0, 4)):
                clock.move_to(now_s)
                await platform.until(lambda reports=reports: len(platform.reports) >= reports)
            clock.move_to(5.0)  # past the simulator's wait for the last answers
            stats = await asyncio.wait_for(simulating, HANG_S)
            await asyncio.wait_for(platform.left.wait(), HANG_S)
            return stats

    stats = asyncio.run(run())
    assert stats.refused == 0 and stats.tracking_requests == 1
    assert platform.responses == [(platform.asked_serial, 0x8202, 0)]
    expected = [(9.0, 0.0), (9.001, 1.0), (9.002, 2.0), (9.004, 4.0)]
    assert [lon for lon, _, _ in platform.reports] == pytest.approx([lon for lon, _ in expected], abs=2e-6)
    assert [time_s for _, _, time_s in platform.reports] == [start_s + offset_s for _, offset_s in expected]
