"""The JT/T 808 gateway on loopback (the rig of tests/jt808_rig.py) served over TLS, and telling each fleet's
drivers in that fleet's own words: a terminal holds its conversation through TLS while plain TCP to the same port
gets no JT/T 808 answer; a fleet's level-1 text (``--texts``) is what its terminals' ``0x8300`` carries, GBK
encoded, and another fleet's terminal hears the default one.
"""

from __future__ import annotations

import argparse
import asyncio
import math
import shutil
import ssl
import subprocess
from pathlib import Path

import pytest
from jt808_rig import APPROACH_M, CATEGORY, FLEET, PHONE, PLATE, RADIUS_M, T0_S, Drive, Rig, build_net, lonlat
from jt808_terminal import Received, Terminal, general_response, header_2013, location_body, wire

from csws.gateways.jt808.terminals import add_terminal
from csws.gateways.jt808.texts import DriverTexts
from csws.standard import warning_speed
from service.jt808_cli import _tls
from service.jt808_settings import GatewaySettings

pytestmark = [pytest.mark.sumo, pytest.mark.slow]

#: A terminal of another fleet than the rig's, which has no texts of its own.
OTHER_FLEET, OTHER_PHONE = "globex", "13900000002"
#: The rig's fleet's own level-1 text, unlike any default.
FLEET_LEVEL_1 = "车队甲提示：前方急弯请慢行，限速{speed_kmh}公里"


@pytest.fixture(scope="module")
def net(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_net(tmp_path_factory.mktemp("jt808"))


def self_signed(folder: Path) -> tuple[Path, Path]:
    """A throwaway self-signed certificate for 127.0.0.1 and its key, PEM files in ``folder`` (by ``openssl``)."""
    openssl = shutil.which("openssl")
    if openssl is None:
        pytest.fail("the TLS test makes its certificate with openssl, and openssl is not on PATH")
    cert, key = folder / "cert.pem", folder / "key.pem"
    subprocess.run(
        [openssl, "req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes"]
        + ["-keyout", str(key), "-out", str(cert), "-days", "1", "-subj", "/CN=127.0.0.1"]
        + ["-addext", "subjectAltName=IP:127.0.0.1"],
        check=True,
        capture_output=True,
    )
    return cert, key


class TlsRig(Rig):
    """The rig with its gateway serving TLS with ``tls``."""

    def __init__(self, net: Path, folder: Path, tls: ssl.SSLContext) -> None:
        super().__init__(net, folder)
        self.tls = tls

    async def __aenter__(self) -> TlsRig:
        ready: asyncio.Future[int] = asyncio.get_running_loop().create_future()
        self.task = asyncio.create_task(self.gateway.serve(self.tls, ready=ready.set_result))
        self.port = await ready
        return self


def test_a_terminal_holds_its_conversation_over_tls_and_plain_tcp_to_the_tls_port_gets_no_answer(net, tmp_path):
    """Served with the context of ``--tls-cert``/``--tls-key``, a terminal trusting the certificate registers,
    authenticates and has its location report answered (0x8001, success); a plain-TCP heartbeat gets no frame."""
    cert, key = self_signed(tmp_path)
    server_context = _tls(argparse.Namespace(tls_cert=cert, tls_key=key))
    assert server_context is not None
    client_context = ssl.create_default_context(cafile=str(cert))

    async def run() -> tuple[int, tuple[int, int, int], tuple[int, int, int], bytes]:
        async with TlsRig(net, tmp_path, server_context) as rig:
            terminal = Terminal(PHONE, plate=PLATE)
            terminal.reader, terminal.writer = await asyncio.open_connection(
                "127.0.0.1", rig.port, ssl=client_context, server_hostname="127.0.0.1"
            )
            authenticated = general_response(await terminal.register_and_authenticate())
            lon, lat = lonlat(100.0)
            serial = await terminal.send(0x0200, location_body(lat, lon, 50.0, 90.0, T0_S))
            [response] = await terminal.receive(1)
            await terminal.close()
            reader, writer = await asyncio.open_connection("127.0.0.1", rig.port)
            writer.write(wire(header_2013(0x0002, PHONE, 1, 0)))
            await writer.drain()
            plain = b""
            try:
                while chunk := await asyncio.wait_for(reader.read(4096), 5.0):
                    plain += chunk
            except ConnectionResetError:
                pass
            writer.close()
            return serial, authenticated, general_response(response), plain

    serial, authenticated, answered, plain = asyncio.run(run())
    assert authenticated[2] == 0
    assert answered == (serial, 0x0200, 0)
    assert b"\x7e" not in plain  # no JT/T 808 frame: at most a TLS alert, then the connection closed


class Recording(Terminal):
    """A terminal keeping every frame it receives."""

    def __init__(self, phone: str) -> None:
        super().__init__(phone)
        self.received: list[Received] = []

    async def receive(self, count: int, timeout_s: float = 10.0) -> list[Received]:
        frames = await super().receive(count, timeout_s)
        self.received += frames
        return frames


def test_a_fleets_own_level_1_text_reaches_its_terminals_and_another_fleet_hears_the_default(net, tmp_path):
    """With the rig's fleet given its own level-1 text, its terminal's first 0x8300 is that text (V_w filled in),
    GBK encoded after a shown-and-spoken flag byte; a terminal of a fleet without texts gets the default level 1."""
    add_terminal(tmp_path / "terminals.json", OTHER_FLEET, OTHER_PHONE, vehicle_id="van-7", category=CATEGORY)
    settings = GatewaySettings(port=0, fleet_texts={FLEET: DriverTexts(level1=FLEET_LEVEL_1)})
    v_w1 = math.floor(warning_speed(RADIUS_M, CATEGORY, 1))
    speed_kmh = 80.0
    assert v_w1 < speed_kmh < warning_speed(RADIUS_M, CATEGORY, 2)  # level 1 only

    async def first_text(rig: Rig, phone: str) -> list[Received]:
        terminal = Recording(phone)
        await terminal.connect(rig.port)
        assert general_response(await terminal.register_and_authenticate())[2] == 0
        drive = Drive(rig, terminal, APPROACH_M - 480.0)
        while not await drive.report(speed_kmh):
            assert drive.x_m < APPROACH_M, "no warning before the curve"
        await terminal.close()
        return [frame for frame in terminal.received if frame.message_id == 0x8300]

    async def run() -> tuple[list[Received], list[Received]]:
        async with Rig(net, tmp_path, settings) as rig:  # lists the rig's terminal, of FLEET, beside the other
            return await first_text(rig, PHONE), await first_text(rig, OTHER_PHONE)

    own, other = asyncio.run(run())
    shown_and_spoken = bytes([0b1100])  # 2013: bit 2 display, bit 3 TTS; not an emergency (bit 0)
    assert [m.body for m in own] == [shown_and_spoken + f"车队甲提示：前方急弯请慢行，限速{v_w1}公里".encode("gbk")]
    assert [m.body for m in other] == [shown_and_spoken + f"前方弯道，请减速，建议车速{v_w1}公里".encode("gbk")]
