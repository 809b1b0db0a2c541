"""The JT/T 808 gateway on loopback (the rig of tests/jt808_rig.py: a constructed road, the real gateway, a
terminal written from the standard's layout): warnings where formula (1) says, a vehicle switched off over HTTP,
revoked and unknown terminals, malformed frames, idle connections, and two gateway processes on one Redis.
"""

from __future__ import annotations

import asyncio
import math
import os
import struct
import subprocess
import sys
from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from jt808_rig import (
    APPROACH_M,
    CATEGORY,
    FLEET,
    PHONE,
    RADIUS_M,
    START_TOLERANCE_M,
    T0_S,
    Drive,
    Rig,
    build_net,
    connected,
    formula_1_m,
    heartbeat,
    lonlat,
)
from jt808_terminal import Terminal, general_response, header_2013, location_body, wire

from csws.gateways.jt808.latency import StageTimes
from csws.gateways.jt808.terminals import add_terminal, revoke_terminal
from csws.standard import warning_speed
from csws.warning.rules import WarningSettings
from service.jt808_cli import loop_factory
from service.jt808_settings import GatewaySettings

pytestmark = [pytest.mark.sumo, pytest.mark.slow]


@pytest.fixture(scope="module")
def net(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_net(tmp_path_factory.mktemp("jt808"))


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


def test_a_terminal_at_a_steady_speed_above_both_warning_speeds_hears_each_level_where_formula_1_says(net, tmp_path):
    """At 95 km/h, above both levels' V_w, reporting every 1 s: level 1 at the last report that could show it before
    S_w(V_w1), then level 2 likewise before S_w(V_w2), each within one report interval of travel of formula (1)."""
    speed_kmh = 95.0
    v_w1, v_w2 = (warning_speed(RADIUS_M, CATEGORY, level) for level in (1, 2))
    assert v_w1 < v_w2 < speed_kmh
    delay_s, speed_mps = WarningSettings().system_delay_s, speed_kmh / 3.6

    async def run() -> list[tuple[float, str]]:
        async with Rig(net, tmp_path) as rig:
            terminal = await connected(rig)
            drive = Drive(rig, terminal, APPROACH_M - 600.0)
            texts: list[tuple[float, str]] = []
            while len(texts) < 2:
                assert drive.x_m < APPROACH_M, f"only {texts} before the curve"
                texts += await drive.report(speed_kmh)
            await terminal.close()
            return texts

    (level_1_m, level_1), (level_2_m, level_2) = asyncio.run(run())
    assert "前方弯道" in level_1 and "弯道超速" in level_2
    for onset_m, v_w in ((level_1_m, v_w1), (level_2_m, v_w2)):
        sw_m = formula_1_m(speed_kmh, v_w)
        assert onset_m - speed_mps * delay_s >= sw_m - START_TOLERANCE_M  # on before S_w is reached
        assert onset_m <= sw_m + speed_mps * (1.0 + delay_s) + START_TOLERANCE_M  # at the last report that could


#: The slow terminals' speed: above the curve's level-1 V_w, below its level-2 one.


def test_a_vehicle_switched_off_over_http_is_told_so_once_and_never_warned(net, tmp_path):
    async def run() -> list[tuple[float, str]]:
        async with Rig(net, tmp_path) as rig:
            client = TestClient(rig.app, headers={"Authorization": f"Bearer {rig.api_key}"})
            assert client.put("/v1/vehicles/truck-18", json={"switched_on": False}).status_code == 200
            terminal = await connected(rig)
            drive = Drive(rig, terminal, APPROACH_M - 200.0)
            texts = []
            while drive.x_m < APPROACH_M + 20.0:
                texts += await drive.report(95.0)
            await terminal.close()
            return texts

    texts = asyncio.run(run())
    assert [text for _, text in texts] == ["弯道预警已关闭"]


def test_a_category_set_over_http_is_the_terminals_too(net, tmp_path):
    """The terminal list says N; the fleet sets M1 over HTTP. At a speed above N's V_w and below M1's, the
    vehicle is warned only while it is an N: one vehicle, one category, whichever way it talks."""
    speed_kmh = 85.0
    assert warning_speed(RADIUS_M, CATEGORY, 1) < speed_kmh < warning_speed(RADIUS_M, "M1", 1)

    async def drive(category: str | None) -> list[tuple[float, str]]:
        async with Rig(net, tmp_path / (category or "listed")) as rig:
            if category is not None:
                client = TestClient(rig.app, headers={"Authorization": f"Bearer {rig.api_key}"})
                setting = {"switched_on": True, "category": category}
                assert client.put("/v1/vehicles/truck-18", json=setting).status_code == 200
            terminal = await connected(rig)
            drive = Drive(rig, terminal, APPROACH_M - 300.0)
            texts = []
            while drive.x_m < APPROACH_M:
                texts += await drive.report(speed_kmh)
            await terminal.close()
            return texts

    assert ["前方弯道" in text for _, text in asyncio.run(drive(None))] == [True]
    assert asyncio.run(drive("M1")) == []


def test_a_revoked_terminal_is_refused_from_its_next_message(net, tmp_path):
    async def run() -> None:
        async with Rig(net, tmp_path) as rig:
            terminal = await connected(rig)
            assert general_response(await heartbeat(terminal))[2] == 0
            revoke_terminal(rig.terminals_file, PHONE)
            assert general_response(await heartbeat(terminal))[2] == 1  # failure: no longer admitted
            serial = await terminal.send(0x0200, location_body(50.0, 9.0, 50.0, 90.0, T0_S))
            [response] = await terminal.receive(1)
            assert general_response(response) == (serial, 0x0200, 1)  # failure: no longer admitted
            registration = struct.pack(">HH", 0, 0) + bytes(5 + 20 + 7) + b"\x01"
            await terminal.send(0x0100, registration)
            [answer] = await terminal.receive(1)
            assert answer.message_id == 0x8100 and answer.body[2] == 4  # no such terminal
            await terminal.close()

    asyncio.run(run())


def test_malformed_frames_are_dropped_and_the_connection_lives(net, tmp_path):
    async def run() -> None:
        async with Rig(net, tmp_path) as rig:
            terminal = await connected(rig)
            good = wire(struct.pack(">HH", 0x0002, 0) + bytes.fromhex(PHONE.rjust(12, "0")) + b"\x00\x63")
            bad_check = good[:-2] + bytes([good[-2] ^ 0x55]) + good[-1:]
            bad_escape = b"\x7e\x00\x02\x7d\x05" + bytes(12) + b"\x7e"
            wrong_length = wire(struct.pack(">HH", 0x0200, 40) + bytes.fromhex(PHONE.rjust(12, "0")) + b"\x00\x64")
            no_flag = b"\x7e" + bytes(5000)
            for junk in (bad_check, bad_escape, wrong_length, b"\x7e\x7e", no_flag):
                terminal.writer.write(junk)
            await terminal.writer.drain()
            await heartbeat(terminal)  # after the junk, a well-formed frame is answered
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
            terminal = await connected(rig)
            items = [location_body(*reversed(lonlat(100.0 + 14.0 * k)), 50.0, 90.0, T0_S + k) for k in range(3)]
            batch = struct.pack(">HB", 3, 0) + b"".join(struct.pack(">H", len(i)) + i for i in items)
            serial = await terminal.send(0x0704, batch)
            [response] = await terminal.receive(1)
            assert general_response(response) == (serial, 0x0704, 0)
            await terminal.close()

    asyncio.run(run())


@pytest.mark.parametrize("loop", ["asyncio", "uvloop"])
def test_the_frames_of_one_read_are_answered_in_order_and_a_deregistration_ends_the_connection(net, tmp_path, loop):
    """Three heartbeats and a deregistration (0x0003) in one TCP write: four general responses, each naming its
    frame's serial and message id with success, in the order sent; then the gateway closes the connection. On the
    standard event loop and on uvloop alike."""

    async def run() -> tuple[list[tuple[int, int, int]], list[tuple[int, int, int]], bytes]:
        async with Rig(net, tmp_path) as rig:
            terminal = await connected(rig)
            sent = []
            for message_id in (0x0002, 0x0002, 0x0002, 0x0003):
                terminal.serial += 1
                sent.append((terminal.serial, message_id, 0))
                terminal.writer.write(wire(header_2013(message_id, PHONE, terminal.serial, 0)))
            await terminal.writer.drain()
            answered = [general_response(r) for r in await terminal.receive(4)]
            closed = await asyncio.wait_for(terminal.reader.read(10), 5.0)
            await terminal.close()
            return sent, answered, closed

    with asyncio.Runner(loop_factory=loop_factory(loop)) as runner:
        sent, answered, closed = runner.run(run())
    assert answered == sent
    assert closed == b""


def test_connections_beyond_the_cap_are_closed_and_the_one_admitted_lives(net, tmp_path):
    """With room for one connection, a second is closed at once while the first is answered; once the first
    has gone, a new connection is admitted again."""

    async def refused(port: int) -> bool:
        terminal = Terminal("13900000000")
        await terminal.connect(port)
        try:
            await terminal.send(0x0002)
            return await asyncio.wait_for(terminal.reader.read(10), 5.0) == b""
        except ConnectionError:
            return True
        finally:
            await terminal.close()

    async def run() -> tuple[bool, int, bool]:
        async with Rig(net, tmp_path, GatewaySettings(port=0, max_connections=1)) as rig:
            first = await connected(rig)
            second_refused = await refused(rig.port)
            first_result = general_response(await heartbeat(first))[2]
            await first.close()
            for _ in range(100):  # the gateway learns of the close on one of its next turns
                if not rig.gateway.conversations:
                    break
                await asyncio.sleep(0.01)
            third = await connected(rig)
            third_answered = general_response(await heartbeat(third))[2] == 0
            await third.close()
            return second_refused, first_result, third_answered

    assert asyncio.run(run()) == (True, 0, True)


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
        # The container image names an API key file the gateway's compose example does not mount: it reads none.
        no_keys = {**os.environ, "CSWS_API_KEYS_FILE": str(terminals_file.parent / "no-such-api-keys.json")}
        self.process = subprocess.Popen(
            [*command, "--terminals", str(terminals_file), "--state", state_url],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            env=no_keys,
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
