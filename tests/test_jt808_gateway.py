"""The JT/T 808 gateway on loopback: a terminal written from the standard's layout drives a constructed road.

Truth is constructed here: a straight of 1,500 m, an arc of R 150 m and a straight, geo-referenced in
UTM 32N; the terminal's fixes from its constant speed (lon/lat by pyproj, not by csws); V_w from the
standard's tables and S_w from formula (1) computed by the test. A slow terminal honours temporary
tracking (0x8202) as the standard lays it out, read here byte by byte. The gateway is the real one
(:class:`service.jt808.Gateway` over the app's warning service and a SQLite state store) on a real
TCP socket; the HTTP API of the same app switches the vehicle off.
"""

from __future__ import annotations

import asyncio
import math
import re
import struct
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pyproj
import pytest
from builders import edge_xml, node_xml
from fastapi.testclient import TestClient
from jt808_terminal import Received, Terminal, general_response, location_body, wire

import service.jt808
from csws.gateways.jt808.latency import StageTimes
from csws.gateways.jt808.terminals import TerminalList, add_terminal, revoke_terminal
from csws.gateways.jt808.tracking import TrackingSettings
from csws.geometry import arc, sample_pieces, straight
from csws.standard import warning_speed
from csws.sumo.netbuild import netconvert
from csws.warning.rules import WarningSettings
from service.app import create_app
from service.jt808 import Gateway, GatewaySettings
from service.keys import add_key
from service.settings import ServiceSettings

APPROACH_M, RADIUS_M, ARC_DEG = 1500.0, 150.0, 60.0
PIECES = (straight(APPROACH_M), arc(RADIUS_M, ARC_DEG, "left"), straight(300.0))
UTM32 = "+proj=utm +zone=32 +ellps=WGS84 +datum=WGS84 +units=m +no_defs"
#: Network (0, 0) at UTM 32N (550000, 5635000).
ORIGIN_E, ORIGIN_N = 550_000.0, 5_635_000.0
REACTION_S, G_MPS2 = 0.8, 9.8  # formula (1), 6.1
CATEGORY, PHONE, FLEET = "N", "13800138000", "acme"
#: How far the fitted curve start may lie from the constructed one, m.
START_TOLERANCE_M = 1.5
T0_S = 1_790_000_000.0
#: The gateway's default settings, on a port the system picks.
ON_A_FREE_PORT = GatewaySettings(port=0)

pytestmark = [pytest.mark.sumo, pytest.mark.slow]


@pytest.fixture(scope="module")
def net(tmp_path_factory: pytest.TempPathFactory) -> Path:
    xy, _ = sample_pieces(PIECES, 2.0, (0.0, 0.0), 0.0)
    folder = tmp_path_factory.mktemp("jt808")
    path = netconvert(
        f"<nodes>{node_xml('A', xy[0]) + node_xml('B', xy[-1])}</nodes>",
        f"<edges>{edge_xml('r', 'A', 'B', xy)}</edges>",
        folder / "r.net.xml",
    )
    text = re.sub(r'netOffset="[^"]*"', f'netOffset="{-ORIGIN_E:.2f},{-ORIGIN_N:.2f}"', path.read_text())
    path.write_text(text.replace('projParameter="!"', f'projParameter="{UTM32}"'))
    return path


def lonlat(x_m: float) -> tuple[float, float]:
    """The lon/lat of the road's point ``x_m`` along the straight (y = 0)."""
    to_wgs84 = pyproj.Transformer.from_crs(pyproj.CRS.from_proj4(UTM32), "EPSG:4326", always_xy=True)
    return to_wgs84.transform(ORIGIN_E + x_m, ORIGIN_N)


def formula_1_m(speed_kmh: float, warning_speed_kmh: float) -> float:
    v, v_w = speed_kmh / 3.6, warning_speed_kmh / 3.6
    return REACTION_S * v + (v * v - v_w * v_w) / G_MPS2


class Rig:
    """The app (HTTP and warning service), its gateway on a free port, and a clock the test sets."""

    def __init__(self, net: Path, folder: Path, gateway_settings: GatewaySettings = ON_A_FREE_PORT) -> None:
        self.terminals_file = folder / "terminals.json"
        add_terminal(self.terminals_file, FLEET, PHONE, vehicle_id="truck-18", category=CATEGORY, plate="京A12345")
        self.api_key = add_key(folder / "keys.json", FLEET, "admin")
        settings = ServiceSettings(nets=[net], state_db=str(folder / "state.db"), api_keys_file=folder / "keys.json")
        self.app = create_app(settings)
        self.now_s = T0_S
        self.gateway = Gateway(
            self.app.state.service,
            self.app.state.work,
            TerminalList(self.terminals_file),
            gateway_settings,
            clock=lambda: self.now_s,
        )

    async def __aenter__(self) -> Rig:
        ready: asyncio.Future[int] = asyncio.get_running_loop().create_future()
        self.task = asyncio.create_task(self.gateway.serve(ready=ready.set_result))
        self.port = await ready
        return self

    async def __aexit__(self, *_: object) -> None:
        self.task.cancel()
        await asyncio.gather(self.task, return_exceptions=True)


class Drive:
    """A terminal reporting along the straight every ``interval_s`` (1 s by default), the test's clock following
    its reports: each reaches the gateway ``uplink_s`` late, and a request the terminal ``downlink_s`` after the
    report that brought it. Asked for temporary tracking (0x8202: WORD interval, DWORD validity, both in s), it
    answers with its general response (0x0001) and, from the moment the request reached it, reports at the
    interval asked for until the validity ends; or, as ``tracking_answer`` says, answers with another result, or
    does not change its interval."""

    def __init__(
        self,
        rig: Rig,
        terminal: Terminal,
        x_m: float,
        interval_s: float = 1.0,
        tracking_answer: tuple[int, bool] = (0, True),
        uplink_s: float = 0.0,
        downlink_s: float = 0.0,
    ) -> None:
        self.rig, self.terminal, self.x_m, self.interval_s = rig, terminal, x_m, interval_s
        self.tracking_result, self.honours = tracking_answer
        self.time_s, self.reports, self.uplink_s, self.downlink_s = T0_S, 0, uplink_s, downlink_s
        self.tracking_interval_s, self.tracked_from_s, self.tracked_until_s = 0.0, -math.inf, -math.inf
        #: Each tracking request: the distance to the curve at the report before it, its interval and validity.
        self.asked: list[tuple[float, int, int]] = []

    def _step_s(self) -> float:
        step_s = max(self.tracking_interval_s, self.tracked_from_s + self.tracking_interval_s - self.time_s)
        tracked = self.tracking_interval_s and self.time_s + step_s <= self.tracked_until_s
        return min(step_s, self.interval_s) if tracked else self.interval_s

    async def report(self, speed_kmh: float) -> list[tuple[float, str]]:
        """One report (after an interval at ``speed_kmh``); the texts (0x8300) it brought, each with the
        distance to the curve at the report."""
        if self.reports:
            step_s = self._step_s()
            self.x_m += speed_kmh / 3.6 * step_s
            self.time_s += step_s
        self.rig.now_s = self.time_s + self.uplink_s
        self.reports += 1
        lon, lat = lonlat(self.x_m)
        answered = self.rig.gateway.counts["evaluated"] + 1
        serial = await self.terminal.send(0x0200, location_body(lat, lon, speed_kmh, 90.0, self.time_s))
        [response] = await self.terminal.receive(1)
        assert general_response(response) == (serial, 0x0200, 0)
        await self._answered(answered)
        texts = []
        while True:
            try:
                [message] = await self.terminal.receive(1, timeout_s=0.3)
            except (AssertionError, TimeoutError):
                return texts
            if message.message_id == 0x8202:
                await self._track(message)
                continue
            assert message.message_id == 0x8300
            assert message.body[0] & 0b1100 == 0b1100  # shown and spoken
            texts.append((APPROACH_M - self.x_m, message.body[1:].decode("gbk")))

    async def _answered(self, count: int, timeout_s: float = 60.0) -> None:
        """Wait until the gateway has answered ``count`` reports: the texts and the tracking request of the last
        are then written, and come before anything of the next report however loaded the machine."""
        deadline = time.monotonic() + timeout_s
        while self.rig.gateway.counts["evaluated"] < count:
            assert time.monotonic() < deadline, "the gateway did not answer the report"
            await asyncio.sleep(0.005)

    async def _track(self, message: Received) -> None:
        assert len(message.body) == 6
        interval_s, validity_s = struct.unpack(">HI", message.body)
        self.asked.append((APPROACH_M - self.x_m, interval_s, validity_s))
        if self.honours:
            received_s = self.time_s + self.uplink_s + self.downlink_s
            self.tracking_interval_s, self.tracked_from_s = float(interval_s), received_s
            self.tracked_until_s = self.tracked_from_s + validity_s
        await self.terminal.send(0x0001, struct.pack(">HHB", message.serial, 0x8202, self.tracking_result))


def test_a_terminal_is_warned_at_level_1_then_level_2_where_formula_1_says(net, tmp_path):
    v_w1, v_w2 = (warning_speed(RADIUS_M, CATEGORY, level) for level in (1, 2))
    slow_kmh, fast_kmh = 80.0, 95.0
    assert v_w1 < slow_kmh < v_w2 < fast_kmh  # 80 km/h: level 1 only; 95 km/h: level 2
    delay_s = WarningSettings().system_delay_s

    async def run() -> tuple[list[tuple[float, str]], StageTimes]:
        async with Rig(net, tmp_path) as rig:
            terminal = Terminal(PHONE)
            await terminal.connect(rig.port)
            assert general_response(await terminal.register_and_authenticate())[2] == 0
            drive = Drive(rig, terminal, APPROACH_M - 480.0)
            texts: list[tuple[float, str]] = []
            while not texts:
                assert drive.x_m < APPROACH_M, "no warning before the curve"
                texts += await drive.report(slow_kmh)
            texts += await drive.report(fast_kmh)
            await terminal.close()
            return texts, rig.gateway.times

    texts, times = asyncio.run(run())
    # Each report's time from read to answer holds its group's evaluation, so every quantile does too.
    for answered_ms, evaluated_ms in zip(
        times.percentiles_ms("answered"), times.percentiles_ms("evaluate"), strict=True
    ):
        assert answered_ms >= evaluated_ms > 0.0
    assert not any(math.isnan(ms) for ms in times.percentiles_ms("text"))
    assert [("弯道超速" in t, "前方弯道" in t) for _, t in texts] == [(False, True), (True, False)]
    assert str(math.floor(v_w1)) in texts[0][1] and str(math.floor(v_w2)) in texts[1][1]
    sw_m, speed_mps = formula_1_m(slow_kmh, v_w1), slow_kmh / 3.6
    onset_m = texts[0][0]
    # Shown before S_w is reached, and at the last 1 s report that could be (learnt period).
    assert onset_m - speed_mps * delay_s >= sw_m - START_TOLERANCE_M
    assert onset_m <= sw_m + speed_mps * (1.0 + delay_s) + START_TOLERANCE_M
    # Level 2 at the first report above V_w2, inside formula (1)'s distance at that speed.
    assert texts[1][0] <= formula_1_m(fast_kmh, v_w2) + fast_kmh / 3.6 * (1.0 + delay_s)


#: The slow terminals' speed: above the curve's level-1 V_w, below its level-2 one.
SLOW_KMH = 80.0


def _warning_point_m(interval_s: float) -> float:
    """Where the warning must be on at the latest for a terminal reporting every ``interval_s``, m before the curve:
    S_w of formula (1) at :data:`SLOW_KMH`, plus the distance driven in the engine's latency (the period it learns,
    at most its cap, and the system delay)."""
    settings = WarningSettings()
    speed_mps = SLOW_KMH / 3.6
    period_s = min(interval_s, settings.max_update_period_s)
    return formula_1_m(SLOW_KMH, warning_speed(RADIUS_M, CATEGORY, 1)) + speed_mps * (
        period_s + settings.system_delay_s
    )


def _ask_m(interval_s: float) -> float:
    """Where a report is placed, m before the curve: the first from which the next regular report could pass the
    warning point. The next regular one would lie halfway to formula (1)'s point where the period is longer than
    the engine's cap (late), else half a second past the warning point."""
    speed_mps, sw_m = SLOW_KMH / 3.6, formula_1_m(SLOW_KMH, warning_speed(RADIUS_M, CATEGORY, 1))
    point_m = _warning_point_m(interval_s)
    return point_m + max(0.5 * speed_mps, speed_mps * interval_s - (point_m - sw_m) - sw_m / 2)


def _slow_drive(
    net: Path,
    folder: Path,
    interval_s: float,
    settings: GatewaySettings = ON_A_FREE_PORT,
    tracking_answer: tuple[int, bool] = (0, True),
):
    """A terminal at :data:`SLOW_KMH` reporting every ``interval_s``, from four intervals before :func:`_ask_m`
    until its first text; the drive (with the tracking requests it was sent) and the texts."""
    start_m = _ask_m(interval_s) + 4 * SLOW_KMH / 3.6 * interval_s

    async def run() -> tuple[Drive, list[tuple[float, str]]]:
        async with Rig(net, folder, settings) as rig:
            terminal = await _connected(rig)
            drive = Drive(rig, terminal, APPROACH_M - start_m, interval_s, tracking_answer)
            texts: list[tuple[float, str]] = []
            while not texts:
                assert drive.x_m < APPROACH_M, "no warning before the curve"
                texts += await drive.report(SLOW_KMH)
            await terminal.close()
            return drive, texts

    return asyncio.run(run())


@pytest.mark.parametrize("interval_s", [5.0, 10.0])
def test_a_slow_terminal_is_tracked_before_the_curve_and_warned_in_time(net, tmp_path, interval_s):
    v_w1, speed_mps = warning_speed(RADIUS_M, CATEGORY, 1), SLOW_KMH / 3.6
    sw_m, point_m = formula_1_m(SLOW_KMH, v_w1), _warning_point_m(interval_s)
    drive, texts = _slow_drive(net, tmp_path, interval_s)
    [(asked_m, tracking_s, validity_s)] = drive.asked  # once, and not again while its window runs
    # At the first report from which the next regular one could pass the warning point, not at the one before.
    assert asked_m == pytest.approx(_ask_m(interval_s), abs=START_TOLERANCE_M)
    assert asked_m - speed_mps * interval_s <= point_m < asked_m
    # 1 s reports until the curve is left at its level-1 V_w, and a margin.
    leave_s = (asked_m + RADIUS_M * math.radians(ARC_DEG)) / (v_w1 / 3.6)
    assert tracking_s == 1 and leave_s - 1.0 <= validity_s <= leave_s + 12.0
    [(onset_m, text)] = texts
    assert "前方弯道" in text and onset_m < asked_m
    # In time: shown before formula (1)'s point at the latest, and not before the warning point.
    assert onset_m - speed_mps * WarningSettings().system_delay_s >= sw_m - START_TOLERANCE_M
    assert onset_m <= point_m + START_TOLERANCE_M


def test_a_terminal_slower_than_the_cap_and_not_tracked_is_warned_late(net, tmp_path):
    """The same drive at 10 s with its fleet not tracked: the report after the one that would have asked lies
    halfway to formula (1)'s point, and the warning comes only there (the allowance stops at 5 s)."""
    interval_s, speed_mps = 10.0, SLOW_KMH / 3.6
    drive, texts = _slow_drive(net, tmp_path, interval_s, GatewaySettings(port=0, untracked_fleets=frozenset({FLEET})))
    assert drive.asked == []
    [(onset_m, text)] = texts
    assert "前方弯道" in text
    assert onset_m == pytest.approx(_ask_m(interval_s) - speed_mps * interval_s, abs=START_TOLERANCE_M)
    assert onset_m < formula_1_m(SLOW_KMH, warning_speed(RADIUS_M, CATEGORY, 1)) - START_TOLERANCE_M


@pytest.mark.parametrize("result, asked", [(0, 2), (3, 1)])
def test_a_terminal_that_refuses_tracking_is_not_asked_again(net, tmp_path, result, asked):
    """Windows of 5 s that end with their validity (no overrun: a terminal never seen at the tracked pace is let go
    only that much after the window's end), and a terminal at 10 s that keeps its interval: once a window has run
    out, the curve still ahead is asked for again, unless the terminal refused the first request (result 3: not
    supported)."""
    settings = GatewaySettings(port=0, tracking=TrackingSettings(max_window_s=5, overrun_s=0.0))
    drive, texts = _slow_drive(net, tmp_path, 10.0, settings, tracking_answer=(result, False))
    assert len(drive.asked) == asked and [validity_s for _, _, validity_s in drive.asked] == [5] * asked
    assert len(texts) == 1  # the reports go on being answered and warned


def test_a_late_terminals_tracked_reports_never_count_as_its_regular_interval(net, tmp_path, monkeypatch):
    """A terminal at 10 s whose reports reach the gateway 1.5 s late (not yet stale), and the 0x8202 the terminal
    2 s after that, asked for 5 s windows: it reports every second from the request's arrival until 5 s after,
    up to 3.5 s past the asking report's time plus the validity, then every 10 s again. The gateway's connection
    learns only 10 s intervals, never one of the 1 s ones, so it still takes the terminal for slow."""
    uplink_s, downlink_s, interval_s = 1.5, 2.0, 10.0
    conversations: list[service.jt808.Conversation] = []

    class Recorded(service.jt808.Conversation):
        def __init__(self, *args: Any) -> None:
            super().__init__(*args)
            conversations.append(self)

    monkeypatch.setattr(service.jt808, "Conversation", Recorded)
    settings = GatewaySettings(port=0, tracking=TrackingSettings(max_window_s=5))
    start_m = _ask_m(interval_s) + 4 * SLOW_KMH / 3.6 * interval_s

    async def run() -> Drive:
        async with Rig(net, tmp_path, settings) as rig:
            terminal = await _connected(rig)
            drive = Drive(rig, terminal, APPROACH_M - start_m, interval_s, uplink_s=uplink_s, downlink_s=downlink_s)
            asked_at_s = math.inf
            while drive.time_s < asked_at_s + uplink_s + downlink_s + 5.0 + 4 * interval_s:
                await drive.report(SLOW_KMH)
                if drive.asked and asked_at_s == math.inf:
                    asked_at_s = drive.time_s
                assert drive.reports < 60, "never asked for tracking"
            await terminal.close()
            return drive

    drive = asyncio.run(run())
    [conversation] = conversations
    assert drive.asked and all(validity_s == 5 for _, _, validity_s in drive.asked)
    assert set(conversation.pace.intervals_s) == {interval_s}
    assert conversation.pace.regular_interval_s() == interval_s


async def _connected(rig: Rig) -> Terminal:
    terminal = Terminal(PHONE)
    await terminal.connect(rig.port)
    assert general_response(await terminal.register_and_authenticate())[2] == 0
    return terminal


def test_a_vehicle_switched_off_over_http_is_told_so_once_and_never_warned(net, tmp_path):
    async def run() -> list[tuple[float, str]]:
        async with Rig(net, tmp_path) as rig:
            client = TestClient(rig.app, headers={"Authorization": f"Bearer {rig.api_key}"})
            assert client.put("/v1/vehicles/truck-18", json={"switched_on": False}).status_code == 200
            terminal = await _connected(rig)
            drive = Drive(rig, terminal, APPROACH_M - 200.0)
            texts = []
            while drive.x_m < APPROACH_M + 20.0:
                texts += await drive.report(95.0)
            await terminal.close()
            return texts

    texts = asyncio.run(run())
    assert [text for _, text in texts] == ["弯道预警已关闭"]


def test_a_revoked_terminal_is_refused_from_its_next_message(net, tmp_path):
    async def run() -> None:
        async with Rig(net, tmp_path) as rig:
            terminal = await _connected(rig)
            assert general_response(await _heartbeat(terminal))[2] == 0
            revoke_terminal(rig.terminals_file, PHONE)
            assert general_response(await _heartbeat(terminal))[2] == 1  # failure: no longer admitted
            serial = await terminal.send(0x0200, location_body(50.0, 9.0, 50.0, 90.0, T0_S))
            [response] = await terminal.receive(1)
            assert general_response(response) == (serial, 0x0200, 1)  # failure: no longer admitted
            registration = struct.pack(">HH", 0, 0) + bytes(5 + 20 + 7) + b"\x01"
            await terminal.send(0x0100, registration)
            [answer] = await terminal.receive(1)
            assert answer.message_id == 0x8100 and answer.body[2] == 4  # no such terminal
            await terminal.close()

    asyncio.run(run())


async def _heartbeat(terminal: Terminal):
    serial = await terminal.send(0x0002)
    [response] = await terminal.receive(1)
    assert general_response(response)[:2] == (serial, 0x0002)
    return response


def test_malformed_frames_are_dropped_and_the_connection_lives(net, tmp_path):
    async def run() -> None:
        async with Rig(net, tmp_path) as rig:
            terminal = await _connected(rig)
            good = wire(struct.pack(">HH", 0x0002, 0) + bytes.fromhex(PHONE.rjust(12, "0")) + b"\x00\x63")
            bad_check = good[:-2] + bytes([good[-2] ^ 0x55]) + good[-1:]
            bad_escape = b"\x7e\x00\x02\x7d\x05" + bytes(12) + b"\x7e"
            wrong_length = wire(struct.pack(">HH", 0x0200, 40) + bytes.fromhex(PHONE.rjust(12, "0")) + b"\x00\x64")
            no_flag = b"\x7e" + bytes(5000)
            for junk in (bad_check, bad_escape, wrong_length, b"\x7e\x7e", no_flag):
                terminal.writer.write(junk)
            await terminal.writer.drain()
            await _heartbeat(terminal)  # after the junk, a well-formed frame is answered
            unknown = await terminal.send(0x0900, b"\x01")
            [response] = await terminal.receive(1)
            assert general_response(response) == (unknown, 0x0900, 3)  # not supported
            await terminal.close()

    asyncio.run(run())


def test_reports_before_authentication_fail_and_a_batch_upload_is_answered(net, tmp_path):
    async def run() -> None:
        async with Rig(net, tmp_path) as rig:
            stranger = Terminal("13900000000")
            await stranger.connect(rig.port)
            serial = await stranger.send(0x0200, location_body(50.0, 9.0, 50.0, 90.0, T0_S))
            [response] = await stranger.receive(1)
            assert general_response(response) == (serial, 0x0200, 1)
            await stranger.close()
            terminal = await _connected(rig)
            items = [location_body(*reversed(lonlat(100.0 + 14.0 * k)), 50.0, 90.0, T0_S + k) for k in range(3)]
            batch = struct.pack(">HB", 3, 0) + b"".join(struct.pack(">H", len(i)) + i for i in items)
            serial = await terminal.send(0x0704, batch)
            [response] = await terminal.receive(1)
            assert general_response(response) == (serial, 0x0704, 0)
            await terminal.close()

    asyncio.run(run())


def test_an_idle_connection_is_closed(net, tmp_path):
    async def run() -> bytes:
        async with Rig(net, tmp_path) as rig:
            rig.gateway.settings = GatewaySettings(port=0, idle_s=0.3)
            terminal = Terminal(PHONE)
            await terminal.connect(rig.port)
            closed = await asyncio.wait_for(terminal.reader.read(10), 5.0)
            await terminal.close()
            return closed

    assert asyncio.run(run()) == b""  # closed by the gateway, well before the test's 5 s


class GatewayProcess:
    """``csws jt808`` in a process of its own on a free port."""

    def __init__(self, net: Path, terminals_file: Path, state_url: str) -> None:
        command = [sys.executable, "-m", "csws", "jt808", "--net", str(net), "--port", "0"]
        self.process = subprocess.Popen(
            [*command, "--terminals", str(terminals_file), "--state", state_url],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        assert self.process.stdout is not None
        line = self.process.stdout.readline()
        assert "JT/T 808 gateway" in line, line
        self.port = int(line.rsplit(":", 1)[1])

    def stop(self) -> None:
        self.process.terminate()
        self.process.wait(timeout=30)


@pytest.mark.redis
def test_a_terminal_that_reconnects_to_another_gateway_keeps_its_session(net, tmp_path, redis_url):
    """Warned on gateway A, then on gateway B just under V_w: the release rule holds the warning only
    if B has A's session (a vehicle new at that point, at that speed, is not warned)."""
    v_w1 = warning_speed(RADIUS_M, CATEGORY, 1)
    just_under_kmh = math.floor((v_w1 - 0.5) * 10) / 10  # within the release rule's 1 km/h, below V_w
    terminals_file = tmp_path / "terminals.json"
    add_terminal(terminals_file, FLEET, PHONE, vehicle_id="truck-18", category=CATEGORY)
    add_terminal(terminals_file, FLEET, "13900000001", vehicle_id="fresh", category=CATEGORY)
    gateways = [GatewayProcess(net, terminals_file, redis_url) for _ in range(2)]
    clock = {"k": 0}

    async def report(terminal: Terminal, x_m: float, speed_kmh: float) -> list[str]:
        clock["k"] += 1
        lon, lat = lonlat(x_m)
        serial = await terminal.send(0x0200, location_body(lat, lon, speed_kmh, 90.0, T0_S + clock["k"]))
        [response] = await terminal.receive(1)
        assert general_response(response) == (serial, 0x0200, 0)
        try:
            return [m.body[1:].decode("gbk") for m in await terminal.receive(1, timeout_s=1.0)]
        except (AssertionError, TimeoutError):
            return []

    async def run() -> tuple[list[str], list[str]]:
        on_a = Terminal(PHONE)
        await on_a.connect(gateways[0].port)
        registered = await on_a.register_and_authenticate()
        assert general_response(registered)[2] == 0
        x_m, texts = APPROACH_M - 480.0, []
        while not texts:
            x_m += 80.0 / 3.6
            assert x_m < APPROACH_M
            texts = await report(on_a, x_m, 80.0)
        await on_a.close()
        on_b = Terminal(PHONE)  # the same terminal, on the other gateway: authenticates with its code
        await on_b.connect(gateways[1].port)
        on_b.serial = on_a.serial
        await on_b.send(0x0102, on_a.auth_code)
        assert general_response((await on_b.receive(1))[0])[2] == 0
        held = await report(on_b, x_m + just_under_kmh / 3.6, just_under_kmh)
        await on_b.close()
        fresh = Terminal("13900000001")
        await fresh.connect(gateways[1].port)
        assert general_response(await fresh.register_and_authenticate())[2] == 0
        new = await report(fresh, x_m + just_under_kmh / 3.6, just_under_kmh)
        await fresh.close()
        return held, new

    try:
        held, new = asyncio.run(run())
    finally:
        for gateway in gateways:
            gateway.stop()
    assert len(held) == 1 and "前方弯道" in held[0]  # B goes on with A's session: the warning is held
    assert new == []
