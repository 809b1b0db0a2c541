"""The rig of the JT/T 808 gateway tests: a constructed road, the app and its gateway on loopback, and a terminal
driving the road.

Truth is constructed here: a straight of 1,500 m, an arc of R 150 m and a straight, geo-referenced in
UTM 32N; the terminal's fixes from its constant speed (lon/lat by pyproj, not by csws); S_w from formula (1)
computed here. A terminal honours temporary tracking (0x8202) as the standard lays it out, read byte by byte.
The gateway is the real one (:class:`service.jt808.Gateway` over the app's warning service and a SQLite state
store) on a real TCP socket, its clock set by the test.
"""

from __future__ import annotations

import asyncio
import math
import re
import struct
import time
from pathlib import Path

import pyproj
from builders import edge_xml, node_xml
from jt808_terminal import Received, Terminal, general_response, location_body

from csws.gateways.jt808.terminals import TerminalList, add_terminal
from csws.geometry import arc, sample_pieces, straight
from csws.sumo.netbuild import netconvert
from service.app import create_app
from service.jt808 import Gateway
from service.jt808_settings import GatewaySettings
from service.keys import add_key
from service.settings import ServiceSettings

APPROACH_M, RADIUS_M, ARC_DEG = 1500.0, 150.0, 60.0
PIECES = (straight(APPROACH_M), arc(RADIUS_M, ARC_DEG, "left"), straight(300.0))
UTM32 = "+proj=utm +zone=32 +ellps=WGS84 +datum=WGS84 +units=m +no_defs"
#: Network (0, 0) at UTM 32N (550000, 5635000).
ORIGIN_E, ORIGIN_N = 550_000.0, 5_635_000.0
REACTION_S, G_MPS2 = 0.8, 9.8  # formula (1), 6.1
CATEGORY, PHONE, FLEET = "N", "13800138000", "acme"
#: The plate the terminal is listed with, and registers with.
PLATE = "京A12345"
#: How far the fitted curve start may lie from the constructed one, m.
START_TOLERANCE_M = 1.5
T0_S = 1_790_000_000.0
#: The gateway's default settings, on a port the system picks.
ON_A_FREE_PORT = GatewaySettings(port=0)


def build_net(folder: Path) -> Path:
    """The constructed road (:data:`PIECES`) as a SUMO network in ``folder``, geo-referenced in UTM 32N."""
    xy, _ = sample_pieces(PIECES, 2.0, (0.0, 0.0), 0.0)
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
        add_terminal(self.terminals_file, FLEET, PHONE, vehicle_id="truck-18", category=CATEGORY, plate=PLATE)
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
        # Everything the gateway sends for this report is written by now; a heartbeat's answer comes after it.
        beat = await self.terminal.send(0x0002)
        texts = []
        while True:
            [message] = await self.terminal.receive(1)
            if message.message_id == 0x8001 and general_response(message)[:2] == (beat, 0x0002):
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


async def connected(rig: Rig) -> Terminal:
    """A terminal of :data:`PHONE` connected to the rig's gateway, registered and authenticated."""
    terminal = Terminal(PHONE, plate=PLATE)
    await terminal.connect(rig.port)
    assert general_response(await terminal.register_and_authenticate())[2] == 0
    return terminal


async def heartbeat(terminal: Terminal) -> Received:
    """Send a heartbeat (0x0002) and take its general response."""
    serial = await terminal.send(0x0002)
    [response] = await terminal.receive(1)
    assert general_response(response)[:2] == (serial, 0x0002)
    return response
