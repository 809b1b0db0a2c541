"""``csws jt808``: the JT/T 808 gateway, a TCP front of the same warning service as the HTTP API.

Terminals connect over TCP (optionally TLS), register (``0x0100`` -> ``0x8100`` with the
authentication code), authenticate (``0x0102``) and send location reports (``0x0200``, batches
``0x0704``) and heartbeats. Every message is answered by the general response ``0x8001`` as the
standard asks. Each report becomes a query of the terminal's vehicle (its fleet, vehicle id and
category from the terminal list, :mod:`csws.gateways.jt808.terminals`; a category the fleet set over
HTTP comes first) and is answered by the
same :class:`service.answers.WarningService` as ``POST /v1/warning`` (what each message does:
:mod:`service.jt808_messages`): the same state store, so a
vehicle switched off over HTTP is off here too, and a terminal that reconnects to another
gateway process keeps its session. When what the driver should be told changes, the gateway
sends a text message ``0x8300`` to display and speak (:mod:`csws.gateways.jt808.texts`). A
terminal that reports less often than every 1.5 s is asked for 1 s reports (``0x8202``) while its
vehicle nears a curve (:mod:`csws.gateways.jt808.tracking`), unless its fleet is switched off for it.

Reports of all connections are answered together: while the work thread answers one group, the
reports that arrive meanwhile wait for the next, so a busy gateway answers in batches without a
timer. Frames that cannot be read are dropped with a rate-limited log line; the connection
lives on. A connection idle for :attr:`GatewaySettings.idle_s` is closed, and a connection that
sends more than its share of frames per second has the excess dropped. Once a terminal has
authenticated, its connection speaks for it alone: a frame naming another terminal is refused.
"""

from __future__ import annotations

import asyncio
import signal
import ssl
import time
from collections import Counter, deque
from collections.abc import Callable
from typing import cast

from csws.gateways.jt808.frames import Frame, FrameError, FrameSplitter, FrameWriter, decode_frame
from csws.gateways.jt808.latency import StageTimes
from csws.gateways.jt808.messages import MessageId, ResponseResult, encode_general_response, encode_package_request
from csws.gateways.jt808.reassembly import Reassembler
from csws.gateways.jt808.terminals import Terminal, TerminalError, TerminalList
from csws.gateways.jt808.texts import Announcer
from csws.gateways.jt808.tracking import ReportPace

from .answers import WarningService
from .jt808_groups import Batcher, Waiting
from .jt808_messages import HANDLERS, admitted, log
from .jt808_settings import GatewaySettings
from .jt808_tracking import TrackingPlanner
from .work import WorkThread

__all__ = ["Conversation", "Gateway"]


class Conversation(asyncio.Protocol):
    """One terminal's connection: its frames in, the platform's answers and texts out.

    The connection is read by the event loop's own callbacks (no task and no timeout per read): every read
    is split into frames and answered at once, and what a read or an answer sends leaves in one write. A
    connection whose writes back up stops being read until they drain; one silent for
    :attr:`GatewaySettings.idle_s` is closed by a timer that looks at the time of its last read.
    """

    def __init__(self, gateway: Gateway) -> None:
        self.gateway = gateway
        self.transport: asyncio.Transport | None = None
        self.splitter = FrameSplitter()
        self.reassembler = Reassembler(wait_s=gateway.settings.package_wait_s, forgot=self._forgot)
        self.terminal: Terminal | None = None
        self.edition, self.phone, self.serial = 2013, "0", 0
        #: Writes the frames to the terminal (its phone and edition are those of its latest frame).
        self.writer = FrameWriter(self.phone, self.edition)
        self.announcer: Announcer | None = None
        #: The terminal's regular report interval and its tracking window (``0x8202``).
        self.pace = ReportPace()
        #: The connection's reports queued for their warning, oldest first (those started are dropped lazily).
        self.waiting: deque[Waiting] = deque()
        self.read_at = 0.0
        self.allowance, self.allowance_at = gateway.settings.frames_burst, time.perf_counter()
        self._outgoing: list[bytes] = []
        self._idle: asyncio.TimerHandle | None = None
        #: Asks for missing packages when the earliest unfinished message is due (:meth:`_ask_missing`).
        self._asking: asyncio.TimerHandle | None = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        """Take the connection, or close it at once beyond :attr:`GatewaySettings.max_connections`."""
        self.transport = cast(asyncio.Transport, transport)  # uvloop's transports do not subclass asyncio's
        self.read_at = time.perf_counter()
        if not self.gateway.admit(self):
            transport.close()
            return
        self._idle = asyncio.get_running_loop().call_later(self.gateway.settings.idle_s, self._check_idle)

    def connection_lost(self, exc: Exception | None) -> None:
        """Forget the connection: its reports not yet started are not evaluated, and are counted as shed (those
        started are answered)."""
        for timer in (self._idle, self._asking):
            if timer is not None:
                timer.cancel()
        for waiting in self.waiting:
            self.gateway.counts["shed"] += not waiting.started
            waiting.shed = True
        self.gateway.release(self)

    def data_received(self, data: bytes) -> None:
        """Handle the bytes ``data``; the connection ends once the terminal has deregistered."""
        if not self.received(data) and self.transport is not None:
            self.transport.close()

    def pause_writing(self) -> None:
        """Stop reading while the terminal does not take what was written (as ``drain`` would wait)."""
        if self.transport is not None:
            self.transport.pause_reading()

    def resume_writing(self) -> None:
        """Read again once the writes have drained."""
        if self.transport is not None and not self.transport.is_closing():
            self.transport.resume_reading()

    def _check_idle(self) -> None:
        """Close the connection if nothing came for :attr:`GatewaySettings.idle_s`; else look again when it could."""
        idle_s = self.gateway.settings.idle_s
        silent_s = time.perf_counter() - self.read_at
        if silent_s >= idle_s:
            if self.transport is not None:
                self.transport.close()
            return
        self._idle = asyncio.get_running_loop().call_later(idle_s - silent_s, self._check_idle)

    def closing(self) -> bool:
        """Whether the connection is gone or going."""
        return self.transport is None or self.transport.is_closing()

    def _next_serial(self) -> int:
        """The serial of the platform's next message on this connection."""
        self.serial = (self.serial + 1) & 0xFFFF
        return self.serial

    def send(self, message_id: int, body: bytes) -> None:
        """Queue the platform's message ``message_id`` with ``body`` for the terminal (:meth:`flush` sends)."""
        self._outgoing.append(self.writer.frame(message_id, self._next_serial(), body))

    def flush(self) -> None:
        """Write what :meth:`send` queued, in one write."""
        if self._outgoing and self.transport is not None and not self.transport.is_closing():
            self.transport.write(b"".join(self._outgoing))
        self._outgoing.clear()

    def respond(self, frame: Frame, result: ResponseResult) -> None:
        """The general response ``0x8001`` to ``frame``."""
        self.send(MessageId.PLATFORM_RESPONSE, encode_general_response(frame.serial, frame.message_id, result))

    def _allowed(self, now: float) -> bool:
        """Whether one more frame read at ``now`` (``time.perf_counter``) fits the connection's rate (a token
        bucket)."""
        settings = self.gateway.settings
        self.allowance = min(settings.frames_burst, self.allowance + (now - self.allowance_at) * settings.frames_per_s)
        self.allowance_at = now
        if self.allowance < 1.0:
            return False
        self.allowance -= 1.0
        return True

    def received(self, data: bytes) -> bool:
        """Handle the bytes ``data`` and send what they call for; False once the terminal has deregistered."""
        self.read_at = read_at = time.perf_counter()
        try:
            for escaped in self.splitter.feed(data):
                if not self._allowed(read_at):
                    self.gateway.counts["dropped"] += 1
                    log.warning(
                        "jt808: %s sends frames faster than %s/s; dropped",
                        self.phone,
                        self.gateway.settings.frames_per_s,
                    )
                    continue
                try:
                    if not self.handle(decode_frame(escaped)):
                        return False
                except FrameError as error:  # a handler meets what its body check did not foresee: dropped too
                    self.gateway.counts["dropped"] += 1
                    log.warning("jt808: frame dropped from %s: %s", self.phone, error)
            return True
        finally:
            self.flush()
            self._ask_when_due()

    def handle(self, frame: Frame) -> bool:
        """Answer one message; False when the terminal deregistered.

        Once a terminal has authenticated, the connection is its own: a frame naming another phone number
        (a registration or an authentication too) is refused with failure, answered to that number, and
        evaluated for no one; the answers and texts of the connection stay addressed to its terminal.
        """
        if self.terminal is not None and not self.terminal.speaks_as(frame.phone):
            self.gateway.counts["dropped"] += 1
            log.warning("jt808: %s sent a frame as %s; refused", self.terminal.phone, frame.phone)
            self._outgoing.append(
                FrameWriter(frame.phone, frame.edition).frame(
                    MessageId.PLATFORM_RESPONSE,
                    self._next_serial(),
                    encode_general_response(frame.serial, frame.message_id, ResponseResult.FAILURE),
                )
            )
            return True
        if frame.phone != self.phone or frame.edition != self.edition:
            self.edition, self.phone = frame.edition, frame.phone
            self.writer = FrameWriter(frame.phone, frame.edition)
        handler = self.gateway.handlers.get(frame.message_id)
        if handler is None:
            self.respond(frame, ResponseResult.NOT_SUPPORTED)
            return True
        if frame.subpackaged:
            whole = self._package(frame)
            if whole is None:
                return True
            frame = whole
        return handler(self, frame)

    def _package(self, frame: Frame) -> Frame | None:
        """A package of a sub-packaged message: the whole message once it is complete (answered by its handler under
        the completing package's serial); else None, the package answered on its own (JT/T 808-2013, 7.12: each
        package may have its general response), with success, or with failure while the terminal is not admitted
        (not yet authenticated, or revoked since), whose packages are not kept.

        A package of a message longer than :data:`csws.gateways.jt808.reassembly.MAX_PACKAGES` packages is
        answered with result 2 (message error) and not kept.
        """
        if admitted(self, frame) is None:  # answered with failure
            self.reassembler.clear()
            return None
        try:
            whole = self.reassembler.add(frame)
        except FrameError as error:
            self.gateway.counts["dropped"] += 1
            log.warning("jt808: package dropped from %s: %s", self.phone, error)
            self.respond(frame, ResponseResult.MESSAGE_ERROR)
            return None
        if whole is None:
            self.respond(frame, ResponseResult.SUCCESS)
        return whole

    def _ask_when_due(self) -> None:
        """Have :meth:`_ask_missing` called when the earliest unfinished message has waited for its packages."""
        due_s = self.reassembler.next_due_s()
        if due_s is None or self._asking is not None or self.closing():
            return
        self._asking = asyncio.get_running_loop().call_later(max(0.0, due_s - time.monotonic()), self._ask_missing)

    def _ask_missing(self) -> None:
        """Ask for the missing packages of the messages that have waited (the re-send request ``0x8003``, 7.12), and
        forget those asked for in vain (:meth:`csws.gateways.jt808.reassembly.Reassembler.missing_due`)."""
        self._asking = None
        for message in self.reassembler.missing_due():
            body = encode_package_request(message.first_serial, message.package_numbers, self.edition)
            self.send(MessageId.PACKAGE_REQUEST, body)
        self.flush()
        self._ask_when_due()

    def _forgot(self, message_id: int) -> None:
        """Count and log an unfinished message forgotten (its packages asked for in vain, or one too many open)."""
        self.gateway.counts["dropped"] += 1
        log.warning("jt808: %s left a sub-packaged 0x%04x unfinished; forgotten", self.phone, message_id)


class Gateway:
    """The JT/T 808 gateway over a warning service.

    Parameters
    ----------
    service, work
        The warning service and the work thread it runs on (as the HTTP app has them).
    terminals
        The admitted terminals.
    settings
        Limits and texts.
    clock
        POSIX seconds now, for the age of reports.
    """

    def __init__(
        self,
        service: WarningService,
        work: WorkThread,
        terminals: TerminalList,
        settings: GatewaySettings,
        clock: Callable[[], float] = time.time,
    ) -> None:
        #: Where reports' time went, stage by stage (:meth:`stages`).
        self.times = StageTimes()
        planner = TrackingPlanner(service, settings.tracking)
        self.batcher = Batcher(service, work, settings.batch_window_s, self.times, planner)
        self.terminals, self.settings, self.clock = terminals, settings, clock
        self.handlers = HANDLERS
        #: The open connections.
        self.conversations: set[Conversation] = set()
        #: What the gateway did so far: connections, reports evaluated and shed, texts told, tracking requests sent,
        #: frames dropped.
        self.counts: Counter[str] = Counter()
        #: Whether the terminal file was checked for changes in this turn of the event loop (:meth:`current_terminals`).
        self.terminals_checked = False
        self._tracks: dict[str, bool] = {}

    def admit(self, conversation: Conversation) -> bool:
        """Count a new connection; False beyond :attr:`GatewaySettings.max_connections` (it is closed)."""
        self.counts["connections"] += 1
        if len(self.conversations) >= self.settings.max_connections:
            log.warning("jt808: more than %d connections; one refused", self.settings.max_connections)
            return False
        self.conversations.add(conversation)
        return True

    def release(self, conversation: Conversation) -> None:
        """Forget a connection that ended."""
        self.conversations.discard(conversation)

    def current_terminals(self) -> TerminalList:
        """The admitted terminals as the terminal file lists them, looked at (one ``stat``) once per turn of the event
        loop rather than once per frame.

        A revocation holds from the first turn of the loop that begins after it was written: a terminal that
        waits for the answer to its last frame, as the standard's terminals do, has its next frame refused. Only a
        frame read in the very turn the file was rewritten may still pass.
        """
        if not self.terminals_checked:
            try:
                self.terminals.refresh()
            except TerminalError as error:
                log.warning("jt808: %s; the terminals read before stay admitted", error)
            self.terminals_checked = True
            asyncio.get_running_loop().call_soon(self._next_turn)
        return self.terminals

    def _next_turn(self) -> None:
        """Have the next turn of the event loop check the terminal file again."""
        self.terminals_checked = False

    def tracks(self, fleet: str) -> bool:
        """Whether ``fleet``'s slow terminals are asked for temporary tracking (:meth:`GatewaySettings.tracks`, kept
        per fleet)."""
        tracks = self._tracks.get(fleet)
        if tracks is None:
            tracks = self._tracks[fleet] = self.settings.tracks(fleet)
        return tracks

    def _conversation(self) -> Conversation:
        return Conversation(self)

    async def serve(self, tls: ssl.SSLContext | None = None, ready: Callable[[int], None] | None = None) -> None:
        """Listen on the settings' address until cancelled; ``ready(port)`` once listening. The connections still
        open are closed when it ends."""
        loop = asyncio.get_running_loop()
        server = await loop.create_server(
            self._conversation, self.settings.host, self.settings.port, ssl=tls, backlog=4096
        )
        serving = asyncio.current_task()
        if serving is not None:  # SIGTERM stops it as Ctrl-C does, so that what it did is told
            loop.add_signal_handler(signal.SIGTERM, serving.cancel)
        lagging = loop.create_task(self._sample_loop_lag())
        async with server:
            if ready is not None:
                ready(server.sockets[0].getsockname()[1])
            try:
                await server.serve_forever()
            except asyncio.CancelledError:
                pass
            finally:
                lagging.cancel()
                for conversation in list(self.conversations):
                    if conversation.transport is not None:
                        conversation.transport.close()

    async def _sample_loop_lag(self, period_s: float = 0.01) -> None:
        """Count how late the event loop wakes a sleeper (``loop_lag``): the delay before a terminal's bytes are read
        and before a text leaves, which the other stages do not see."""
        while True:
            asked = time.perf_counter()
            await asyncio.sleep(period_s)
            self.times.add("loop_lag", time.perf_counter() - asked - period_s)

    def summary(self) -> str:
        """One line of what the gateway did."""
        counts = self.counts
        return (
            f"{counts['connections']} connection(s), {counts['evaluated']} report(s) evaluated, "
            f"{counts['shed']} shed, {counts['told']} text(s) told, {counts['tracked']} tracking request(s), "
            f"{counts['dropped']} frame(s) dropped"
        )

    def stages(self) -> str:
        """One line of where reports' time went: p50/p99 of each stage (:class:`StageTimes`)."""
        return self.times.line()
