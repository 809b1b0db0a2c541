"""Simulated JT/T 808 terminals: many vehicles reporting along recorded tracks, for tests, benchmarks and smoke tests.

Each terminal connects, registers (``0x0100``), authenticates with the code it was given
(``0x0102``), then sends a location report (``0x0200``) at each time of its track, paced by the
wall clock and stamped with the time it is sent. It reads what the platform sends back and
times it: the general response (``0x8001``) from the report's last byte, and each text message
(``0x8300``) from the last byte of the report before it. A track is a recorded trajectory:
times, lon/lat, speed and heading (for example SUMO's, sampled at the terminal's rate).

A terminal honours temporary location tracking (``0x8202``) as the standard asks: it answers
with its general response (``0x0001``) and, until the window ends, reports every interval asked
for as well as at its track's times, at the track's point interpolated for that moment.

The pace and the reports' time stamps come from a :class:`Clock`: the wall clock
(:class:`WallClock`) for a real run, or one a test moves itself. The times of responses and texts
are always measured on the wall clock.
"""

from __future__ import annotations

import asyncio
import csv
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

import numpy as np

from csws.errors import CswsError

from .frames import Frame, FrameError, FrameSplitter, decode_frame, encode_frame
from .messages import (
    BodyError,
    LocationReport,
    MessageId,
    ResponseResult,
    decode_temporary_tracking,
    encode_general_response,
    encode_location,
)

__all__ = [
    "TRACK_COLUMNS",
    "Clock",
    "SimulatedTerminal",
    "SimulationStats",
    "Track",
    "TrackError",
    "WallClock",
    "read_tracks",
    "simulate",
]

#: Status bits of a report: 1 positioned.
_POSITIONED = 1 << 1
#: A registration body (2013): province, city, maker, model, terminal id, plate colour, plate.
_REGISTRATION = bytes(4) + b"CSWS0" + b"SIM".ljust(20, b"\x00") + b"0000000" + b"\x01"


class TrackError(CswsError, ValueError):
    """A tracks file that cannot be read."""


class Clock(Protocol):
    """What paces simulated terminals: a steady time to wait on, and the POSIX time reports are stamped with."""

    def monotonic(self) -> float:
        """Seconds on a steady clock, for the pace of reports and the end of tracking windows."""
        ...

    def posix(self) -> float:
        """POSIX seconds now, the time a report is stamped with."""
        ...

    async def wait(self, until: float, event: asyncio.Event | None = None) -> bool:
        """Wait until :meth:`monotonic` reaches ``until``; True as soon as ``event`` is set meanwhile."""
        ...


class WallClock:
    """The wall clock: ``time.perf_counter`` to wait on, ``time.time`` for the stamps."""

    def monotonic(self) -> float:
        """Seconds on ``time.perf_counter``."""
        return time.perf_counter()

    def posix(self) -> float:
        """POSIX seconds now (``time.time``)."""
        return time.time()

    async def wait(self, until: float, event: asyncio.Event | None = None) -> bool:
        """Sleep until ``until`` on ``time.perf_counter``; True as soon as ``event`` is set meanwhile."""
        wait_s = max(0.0, until - time.perf_counter())
        if event is None:
            await asyncio.sleep(wait_s)
            return False
        try:
            await asyncio.wait_for(event.wait(), wait_s)
        except TimeoutError:
            return False
        return True


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

    def at(self, offset_s: float) -> tuple[float, float, float, float]:
        """The lon, lat, speed and heading at ``offset_s`` from the start: a row's own at its time, else interpolated
        between the rows (the heading the short way round)."""
        row = int(np.searchsorted(self.time_s, offset_s))
        if row < len(self.time_s) and self.time_s[row] == offset_s:
            columns = (self.lon_deg, self.lat_deg, self.speed_kmh, self.heading_deg)
            lon, lat, speed, heading = (float(column[row]) for column in columns)
            return lon, lat, speed, heading
        lon, lat, speed, heading = (
            float(np.interp(offset_s, self.time_s, column))
            for column in (self.lon_deg, self.lat_deg, self.speed_kmh, np.unwrap(self.heading_deg, period=360.0))
        )
        return lon, lat, speed, heading % 360.0


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
    tracking_requests
        Temporary tracking requests (``0x8202``) received, each answered and honoured.
    refused
        Terminals whose registration or authentication was refused, or that could not connect.
    """

    response_s: list[float] = field(default_factory=list)
    text_s: list[float] = field(default_factory=list)
    texts: list[str] = field(default_factory=list)
    tracking_requests: int = 0
    refused: int = 0


class _Connection:
    """One simulated terminal's connection and what it has received."""

    def __init__(self, phone: str, reader: asyncio.StreamReader, writer: asyncio.StreamWriter, clock: Clock) -> None:
        self.phone, self.reader, self.writer, self.clock = phone, reader, writer, clock
        self.serial = 0
        self.sent_at: dict[int, float] = {}
        self.last_report_at = 0.0
        self.frames: asyncio.Queue[Frame] = asyncio.Queue()
        #: The interval of temporary tracking (s) and when its window ends (the clock's :meth:`Clock.monotonic`).
        self.tracking_interval_s, self.tracking_until = 0, 0.0
        #: Set when a tracking request changes when the next report is due.
        self.retracked = asyncio.Event()

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
                elif frame.message_id == MessageId.TEMPORARY_TRACKING:
                    stats.tracking_requests += 1
                    self.track(frame, self.clock.monotonic())
                else:
                    await self.frames.put(frame)

    def track(self, frame: Frame, now: float) -> None:
        """Honour a temporary tracking request (``0x8202``) received at ``now``, and answer it (``0x0001``)."""
        try:
            interval_s, validity_s = decode_temporary_tracking(frame.body)
        except BodyError:
            error = encode_general_response(frame.serial, frame.message_id, ResponseResult.MESSAGE_ERROR)
            self.send(MessageId.TERMINAL_RESPONSE, error)
            return
        self.tracking_interval_s, self.tracking_until = interval_s, now + validity_s if interval_s else 0.0
        self.send(
            MessageId.TERMINAL_RESPONSE,
            encode_general_response(frame.serial, frame.message_id, ResponseResult.SUCCESS),
        )
        self.retracked.set()

    def next_report_s(self, track: Track, last_s: float, started: float) -> float:
        """When the report after the one at ``last_s`` is due, s from the track's start: its next row's time, or
        sooner while a tracking window runs."""
        row = int(np.searchsorted(track.time_s, last_s, side="right"))
        if row == len(track.time_s):
            return math.inf  # the track has ended
        due_s = float(track.time_s[row])
        if self.tracking_interval_s and started + last_s + self.tracking_interval_s <= self.tracking_until:
            due_s = min(due_s, last_s + self.tracking_interval_s)
        return due_s


async def _admit(connection: _Connection) -> bool:
    """Register and authenticate; whether the platform admitted the terminal."""
    connection.send(MessageId.REGISTRATION, _REGISTRATION)
    registration = await asyncio.wait_for(connection.frames.get(), 30.0)
    if registration.message_id != MessageId.REGISTRATION_RESPONSE or registration.body[2] != 0:
        return False
    connection.send(MessageId.AUTHENTICATION, registration.body[3:])
    response = await asyncio.wait_for(connection.frames.get(), 30.0)
    return response.message_id == MessageId.PLATFORM_RESPONSE and response.body[4] == 0


async def _drive(
    terminal: SimulatedTerminal, host: str, port: int, delay_s: float, stats: SimulationStats, clock: Clock
) -> None:
    """One terminal's whole run: connect after ``delay_s``, be admitted, report along the track, leave."""
    await clock.wait(clock.monotonic() + delay_s)
    try:
        reader, writer = await asyncio.open_connection(host, port)
    except OSError:
        stats.refused += 1
        return
    connection = _Connection(terminal.phone, reader, writer, clock)
    reading = asyncio.create_task(connection.read_all(stats))
    try:
        if not await _admit(connection):
            stats.refused += 1
            return
        await _report_along(connection, terminal.track)
        await clock.wait(clock.monotonic() + 1.0)  # the last answers
    except (OSError, TimeoutError):
        stats.refused += 1
    finally:
        writer.close()
        reading.cancel()


async def _report_along(connection: _Connection, track: Track) -> None:
    """Report at the track's times (and every tracking interval while a window runs), paced by the connection's
    clock."""
    clock = connection.clock
    started, last_s, due_s = clock.monotonic(), None, float(track.time_s[0])
    while math.isfinite(due_s):
        connection.retracked.clear()
        if await clock.wait(started + due_s, connection.retracked):
            if last_s is not None:  # a tracking request may make the next report due sooner
                due_s = connection.next_report_s(track, last_s, started)
            continue
        lon, lat, speed_kmh, heading_deg = track.at(due_s)
        report = LocationReport(0, _POSITIONED, lat, lon, 0, speed_kmh, int(round(heading_deg)) % 360, clock.posix())
        serial = connection.send(MessageId.LOCATION, encode_location(report))
        connection.last_report_at = connection.sent_at[serial] = time.perf_counter()
        await connection.writer.drain()
        last_s = due_s
        due_s = connection.next_report_s(track, last_s, started)


async def simulate(
    terminals: Sequence[SimulatedTerminal], host: str, port: int, ramp_s: float = 5.0, clock: Clock | None = None
) -> SimulationStats:
    """Run ``terminals`` against the gateway at ``host:port``; what they saw.

    The terminals connect spread over ``ramp_s`` seconds (as a fleet's terminals come online),
    then each reports at its track's times from its own start, paced by ``clock`` (the wall clock
    by default).
    """
    stats, clock = SimulationStats(), clock if clock is not None else WallClock()
    delays_s = np.linspace(0.0, ramp_s, len(terminals), endpoint=False).tolist()
    drives = (_drive(t, host, port, delay, stats, clock) for t, delay in zip(terminals, delays_s, strict=True))
    await asyncio.gather(*drives)
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
