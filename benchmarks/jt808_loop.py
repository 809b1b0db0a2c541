"""The JT/T 808 gateway's event-loop work per report, without sockets: reading a report and handing back its answer.

``python -m benchmarks.jt808_loop [TERMINALS] [--rounds N]`` feeds each of ``TERMINALS`` admitted
terminals one location report (``0x0200``) a round, as one read of its connection, through the
gateway's own connection code (:class:`service.jt808.Conversation`: splitting, checking, the
admission check, the ``0x8001`` answer, queueing the report), then hands each queued report its
answer as a finished group would (telling the driver where the level changes, about one report in
ten). A stand-in transport takes the writes and a stand-in batcher the queued reports, so what is
timed is the loop thread's Python work per report (its thread CPU), without the kernel's socket
calls or the event loop's own, and without the group's evaluation on the work thread.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import tempfile
import time
from pathlib import Path
from typing import Any, cast

from csws.gateways.jt808.frames import Frame, encode_frame
from csws.gateways.jt808.messages import STATUS_POSITIONED, LocationReport, MessageId, encode_location
from csws.gateways.jt808.terminals import NewTerminal, TerminalList, add_terminals
from service.jt808 import Conversation, Gateway
from service.jt808_groups import AnswerSummary, Waiting
from service.jt808_settings import GatewaySettings

__all__ = ["run_loop_path"]

#: The reports' clock of the first round, POSIX s.
T0_S = 1_790_000_000.0
#: Every this many rounds a terminal's answer changes level, so that about one answer in this many is told.
LEVEL_EVERY = 10


class _Transport:
    """A connection's transport that takes the writes and counts their bytes."""

    def __init__(self) -> None:
        self.written_bytes, self.closed = 0, False

    def write(self, data: bytes) -> None:
        self.written_bytes += len(data)

    def is_closing(self) -> bool:
        return self.closed

    def close(self) -> None:
        self.closed = True

    def pause_reading(self) -> None:
        """Nothing to pause: the benchmark reads only what it feeds."""

    def resume_reading(self) -> None:
        """Nothing to resume."""


class _Queue:
    """A batcher that keeps the queued reports for the benchmark to answer."""

    def __init__(self) -> None:
        self.waiting: list[Waiting] = []

    def queue(self, waiting: Waiting) -> None:
        self.waiting.append(waiting)


def _report_frame(phone: str, serial: int, round_number: int, offset: int) -> bytes:
    """The ``0x0200`` frame of ``phone``'s report of round ``round_number``, as a terminal writes it."""
    report = LocationReport(
        alarm_flags=0,
        status_flags=STATUS_POSITIONED,
        lat_deg=50.86 + offset * 1e-5 + round_number * 1e-4,
        lon_deg=9.70 + offset * 1e-5,
        altitude_m=200,
        speed_kmh=50.0 + offset % 30,
        heading_deg=(offset * 7) % 360,
        time_s=T0_S + round_number,
    )
    return encode_frame(Frame(MessageId.LOCATION, phone, serial, encode_location(report)))


async def _connected(gateway: Gateway, terminals: TerminalList, phones: list[str]) -> list[Conversation]:
    """One authenticated connection per phone."""
    conversations = []
    for phone in phones:
        conversation = Conversation(gateway)
        conversation.connection_made(cast(Any, _Transport()))
        code = terminals.auth_code(cast(Any, terminals.terminal(phone))).encode()
        assert conversation.received(encode_frame(Frame(MessageId.AUTHENTICATION, phone, 1, code)))
        assert conversation.terminal is not None, "the terminal is admitted"
        conversations.append(conversation)
    return conversations


async def _measure(terminals: int, rounds: int, folder: Path) -> dict[str, Any]:
    phones = [f"1380{i:07d}" for i in range(terminals)]
    add_terminals(folder / "terminals.json", "bench", [NewTerminal(p, "N", f"t{p}") for p in phones])
    listed = TerminalList(folder / "terminals.json")
    clock = {"now_s": T0_S}
    settings = GatewaySettings(frames_per_s=1e9, frames_burst=1e9)  # the rounds come faster than real seconds
    gateway = Gateway(cast(Any, None), cast(Any, None), listed, settings, clock=lambda: clock["now_s"])
    queue = _Queue()
    gateway.batcher = cast(Any, queue)
    conversations = await _connected(gateway, listed, phones)
    frames = [
        [_report_frame(phone, 2 + r, r, i) for i, phone in enumerate(phones)] for r in range(rounds)
    ]  # built before the clock starts: the terminals' work, not the gateway's
    read_s = answer_s = 0.0
    for round_number, round_frames in enumerate(frames):
        clock["now_s"] = T0_S + round_number + 0.2
        started = time.thread_time()
        for conversation, frame in zip(conversations, round_frames, strict=True):
            gateway.terminals_checked = False  # each read in a turn of its own: the terminal file looked at each time
            conversation.received(frame)
        read_s += time.thread_time() - started
        level = (round_number // LEVEL_EVERY) % 3
        answer = AnswerSummary("active", level, 60.0 if level else None)
        started = time.thread_time()
        for waiting in queue.waiting:
            waiting.started = True
            waiting.deliver(answer)
        answer_s += time.thread_time() - started
        queue.waiting.clear()
    reports = terminals * rounds
    return {
        "terminals": terminals,
        "reports": reports,
        "evaluated": gateway.counts["evaluated"],
        "told": gateway.counts["told"],
        "read_us_per_report": read_s / reports * 1e6,
        "handback_us_per_report": answer_s / reports * 1e6,
        "loop_us_per_report": (read_s + answer_s) / reports * 1e6,
        "load_1min": os.getloadavg()[0],
    }


def run_loop_path(terminals: int = 1000, rounds: int = 30) -> dict[str, Any]:
    """The loop thread's CPU per report (µs) to read ``terminals`` terminals' reports for ``rounds`` rounds and to
    hand back their answers."""
    with tempfile.TemporaryDirectory() as temporary:
        return asyncio.run(_measure(terminals, rounds, Path(temporary)))


def main(argv: list[str] | None = None) -> None:
    """``python -m benchmarks.jt808_loop [TERMINALS] [--rounds N]``: print the figures."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.jt808_loop", description=__doc__.split("\n\n")[0])
    parser.add_argument("terminals", type=int, nargs="?", default=1000, help="connected terminals")
    parser.add_argument("--rounds", type=int, default=30, help="reports per terminal")
    args = parser.parse_args(argv)
    for name, value in run_loop_path(args.terminals, args.rounds).items():
        print(f"{name}: {value:.4g}" if isinstance(value, float) else f"{name}: {value}")


if __name__ == "__main__":
    main()
