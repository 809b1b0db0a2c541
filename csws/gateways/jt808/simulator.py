"""Simulated JT/T 808 terminals: many vehicles reporting along recorded tracks, for tests, benchmarks and smoke tests.

Each terminal connects, registers (``0x0100``), authenticates with the code it was given
(``0x0102``), then sends a location report (``0x0200``) at each time of its track, paced by the
wall clock and stamped with the time it is sent. It reads what the platform sends back and
times it: the general response (``0x8001``) from the report's last byte, and each text message
(``0x8300``) from the last byte of the report before it. A track is a recorded trajectory:
times, lon/lat, speed and heading (for example SUMO's, sampled at the terminal's rate).
"""

from __future__ import annotations

import asyncio
import csv
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from csws.errors import CswsError

from .frames import Frame, FrameError, FrameSplitter, decode_frame, encode_frame
from .messages import LocationReport, MessageId, encode_location

__all__ = ["TRACK_COLUMNS", "SimulatedTerminal", "SimulationStats", "Track", "TrackError", "read_tracks", "simulate"]

#: Status bits of a report: 1 positioned.
_POSITIONED = 1 << 1
#: A registration body (2013): province, city, maker, model, terminal id, plate colour, plate.
_REGISTRATION = bytes(4) + b"CSWS0" + b"SIM".ljust(20, b"\x00") + b"0000000" + b"\x01"


class TrackError(CswsError, ValueError):
    """A tracks file that cannot be read."""


@dataclass(frozen=True)
class Track:
    """A terminal's recorded track: one row per report.

    Attributes
    ----------
    time_s
        Seconds from the track's start of each report (increasing).
    lon_deg, lat_deg, speed_kmh, heading_deg
        The report's fix.
    """

    time_s: np.ndarray
    lon_deg: np.ndarray
    lat_deg: np.ndarray
    speed_kmh: np.ndarray
    heading_deg: np.ndarray


@dataclass(frozen=True)
class SimulatedTerminal:
    """A terminal: its phone number and track."""

    phone: str
    track: Track


@dataclass
class SimulationStats:
    """What the terminals saw, all together.

    Attributes
    ----------
    response_s
        Seconds from each report's last byte to its general response.
    text_s
        Seconds from the last byte of the report before each text message to the text's arrival. A
        text does not name its report: one that takes longer than the reporting interval is timed
        from a later report, so beyond the interval this understates (the gateway's own ``text``
        stage, :mod:`.latency`, does not).
    texts
        Each text received, decoded.
    refused
        Terminals whose registration or authentication was refused, or that could not connect.
    """

    response_s: list[float] = field(default_factory=list)
    text_s: list[float] = field(default_factory=list)
    texts: list[str] = field(default_factory=list)
    refused: int = 0


class _Connection:
    """One simulated terminal's connection and what it has received."""

    def __init__(self, phone: str, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.phone, self.reader, self.writer = phone, reader, writer
        self.serial = 0
        self.sent_at: dict[int, float] = {}
        self.last_report_at = 0.0
        self.frames: asyncio.Queue[Frame] = asyncio.Queue()

    def send(self, message_id: int, body: bytes) -> int:
        self.serial = (self.serial + 1) & 0xFFFF
        self.writer.write(encode_frame(Frame(message_id, self.phone, self.serial, body)))
        return self.serial

    async def read_all(self, stats: SimulationStats) -> None:
        """Read the platform's frames until the connection ends, timing responses and texts."""
        splitter = FrameSplitter()
        while data := await self.reader.read(65536):
            now = time.perf_counter()
            for escaped in splitter.feed(data):
                try:
                    frame = decode_frame(escaped)
                except FrameError:
                    continue
                if frame.message_id == MessageId.PLATFORM_RESPONSE and frame.body[2:4] == b"\x02\x00":
                    sent = self.sent_at.pop(int.from_bytes(frame.body[:2], "big"), None)
                    if sent is not None:
                        stats.response_s.append(now - sent)
                elif frame.message_id == MessageId.TEXT_MESSAGE:
                    stats.text_s.append(now - self.last_report_at)
                    stats.texts.append(frame.body[1:].decode("gbk", "replace"))
                else:
                    await self.frames.put(frame)


async def _admit(connection: _Connection) -> bool:
    """Register and authenticate; whether the platform admitted the terminal."""
    connection.send(MessageId.REGISTRATION, _REGISTRATION)
    registration = await asyncio.wait_for(connection.frames.get(), 30.0)
    if registration.message_id != MessageId.REGISTRATION_RESPONSE or registration.body[2] != 0:
        return False
    connection.send(MessageId.AUTHENTICATION, registration.body[3:])
    response = await asyncio.wait_for(connection.frames.get(), 30.0)
    return response.message_id == MessageId.PLATFORM_RESPONSE and response.body[4] == 0


async def _drive(terminal: SimulatedTerminal, host: str, port: int, delay_s: float, stats: SimulationStats) -> None:
    """One terminal's whole run: connect after ``delay_s``, be admitted, report along the track, leave."""
    await asyncio.sleep(delay_s)
    try:
        reader, writer = await asyncio.open_connection(host, port)
    except OSError:
        stats.refused += 1
        return
    connection = _Connection(terminal.phone, reader, writer)
    reading = asyncio.create_task(connection.read_all(stats))
    try:
        if not await _admit(connection):
            stats.refused += 1
            return
        track, start = terminal.track, time.perf_counter()
        for row, offset_s in enumerate(track.time_s.tolist()):
            await asyncio.sleep(max(0.0, start + offset_s - time.perf_counter()))
            report = LocationReport(
                0, _POSITIONED, float(track.lat_deg[row]), float(track.lon_deg[row]), 0,
                float(track.speed_kmh[row]), int(round(float(track.heading_deg[row]))) % 360, time.time(),
            )  # fmt: skip
            serial = connection.send(MessageId.LOCATION, encode_location(report))
            connection.last_report_at = connection.sent_at[serial] = time.perf_counter()
            await writer.drain()
        await asyncio.sleep(1.0)  # the last answers
    except (OSError, TimeoutError):
        stats.refused += 1
    finally:
        writer.close()
        reading.cancel()


async def simulate(
    terminals: Sequence[SimulatedTerminal], host: str, port: int, ramp_s: float = 5.0
) -> SimulationStats:
    """Run ``terminals`` against the gateway at ``host:port``; what they saw.

    The terminals connect spread over ``ramp_s`` seconds (as a fleet's terminals come online),
    then each reports at its track's times from its own start.
    """
    stats = SimulationStats()
    delays_s = np.linspace(0.0, ramp_s, len(terminals), endpoint=False).tolist()
    await asyncio.gather(*(_drive(t, host, port, delay, stats) for t, delay in zip(terminals, delays_s, strict=True)))
    return stats


#: The columns of a tracks CSV file, in any order.
TRACK_COLUMNS = ("phone", "time_s", "lon_deg", "lat_deg", "speed_kmh", "heading_deg")


def read_tracks(path: str | Path) -> list[SimulatedTerminal]:
    """The terminals and tracks of a CSV file with :data:`TRACK_COLUMNS` (one row per report).

    Raises
    ------
    TrackError
        One line naming the file and the row, for a missing column or a value that is not a number.
    """
    rows: dict[str, list[list[float]]] = {}
    try:
        with open(path, newline="", encoding="utf-8") as file:
            reader = csv.DictReader(file)
            missing = set(TRACK_COLUMNS) - set(reader.fieldnames or ())
            if missing:
                raise TrackError(f"{path}: columns {sorted(missing)} missing (needs {', '.join(TRACK_COLUMNS)})")
            for number, row in enumerate(reader, start=2):
                try:
                    values = [float(row[name]) for name in TRACK_COLUMNS[1:]]
                except (TypeError, ValueError):
                    raise TrackError(f"{path}:{number}: not a number in {row}") from None
                rows.setdefault(row["phone"], []).append(values)
    except (OSError, UnicodeDecodeError) as error:
        raise TrackError(f"{path}: cannot read tracks ({error})") from None
    terminals = []
    for phone, reports in rows.items():
        table = np.array(sorted(reports))
        terminals.append(SimulatedTerminal(phone, Track(table[:, 0] - table[0, 0], *table[:, 1:].T)))
    return terminals
