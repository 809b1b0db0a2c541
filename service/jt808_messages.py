"""What a JT/T 808 gateway does with each message a terminal sends: the handlers of a connection
(:class:`service.jt808.Conversation`).

Registration hands out the terminal's authentication code, authentication admits it, heartbeats and
location reports are answered by the general response ``0x8001`` at once; each positioned report
becomes a query of the terminal's vehicle (:func:`report_query`), queued for its group
(:mod:`service.jt808_groups`), and its answer tells the driver what changed (``0x8300``) and asks a
slow terminal for temporary tracking (``0x8202``) where a curve needs it.
"""

from __future__ import annotations

import logging
import time
import unicodedata
from collections.abc import Callable
from functools import partial
from typing import TYPE_CHECKING, TypeVar

from csws.gateways.jt808.frames import Frame
from csws.gateways.jt808.messages import (
    BodyError,
    LocationReport,
    MessageId,
    Registration,
    RegistrationResult,
    ResponseResult,
    decode_authentication,
    decode_location,
    decode_location_batch,
    decode_registration,
    decode_terminal_response,
    encode_registration_response,
    encode_temporary_tracking,
    encode_text_message,
)
from csws.gateways.jt808.terminals import Terminal
from csws.gateways.jt808.texts import Announcer
from csws.state import SystemState

from .decoding import DecodedPosition, DecodedQuery
from .guard import OncePerInterval
from .jt808_groups import AnswerSummary, Waiting

if TYPE_CHECKING:
    from .jt808 import Conversation

__all__ = ["HANDLERS", "MAX_PENDING_REPORTS", "MAX_REPORT_AGE_S", "NOT_ANSWERED", "admitted", "log", "report_query"]

_Body = TypeVar("_Body")

log = logging.getLogger("csws.jt808")
log.addFilter(OncePerInterval())

#: Reports of one connection waiting for their warnings beyond this many are shed, oldest first: a
#: gateway that falls behind answers the newest position, not a queue of old ones.
MAX_PENDING_REPORTS = 8
#: A report older than this when it arrives is not given to the latency allowance (a terminal clock
#: that is off would otherwise push every warning forward), s.
MAX_REPORT_AGE_S = 30.0


#: What the driver is told of a report that could not be answered: a fault (5.5.3), said once it has lasted
#: (:class:`csws.gateways.jt808.texts.Announcer`), as the system cannot warn then.
NOT_ANSWERED = AnswerSummary(SystemState.FAULT.value, 0, None)


def report_query(terminal: Terminal, report: LocationReport, now_s: float) -> DecodedQuery:
    """The query of ``terminal``'s vehicle for ``report`` (its fix, speed, heading and time)."""
    age_s = now_s - report.time_s
    return DecodedQuery(
        vehicle_id=terminal.vehicle_id,
        category=terminal.category,
        speed_kmh=min(report.speed_kmh, 250.0),
        position=DecodedPosition(lon=report.lon_deg, lat=report.lat_deg),
        heading_deg=float(report.heading_deg % 360),
        timestamp_s=report.time_s,
        age_s=age_s if 0.0 <= age_s <= MAX_REPORT_AGE_S else None,
    )


def _body(conversation: Conversation, frame: Frame, decode: Callable[[bytes, int], _Body], what: str) -> _Body | None:
    """``decode`` of ``frame``'s body in its edition; None where the body is unreadable, answered with result 2
    (message error) and logged as ``what``."""
    try:
        return decode(frame.body, frame.edition)
    except BodyError as error:
        log.warning("jt808: %s of %s unreadable: %s", what, frame.phone, error)
        conversation.respond(frame, ResponseResult.MESSAGE_ERROR)
        return None


def _register(conversation: Conversation, frame: Frame) -> bool:
    """``0x0100`` -> ``0x8100``: the authentication code of a listed terminal; result 4 for a terminal not listed
    (or revoked), result 2 for a listed one whose registration names another plate than the list's
    (:func:`_plate_differs`), and an unreadable registration a ``0x8001`` with result 2."""
    terminals = conversation.gateway.current_terminals()
    registration = _body(conversation, frame, decode_registration, "registration")
    if registration is None:
        return True
    terminal = terminals.terminal(frame.phone)
    if terminal is None or terminal.revoked:
        body = encode_registration_response(frame.serial, RegistrationResult.NO_SUCH_TERMINAL)
    elif _plate_differs(terminal, registration):
        log.warning("jt808: %s registers plate %r, listed with %r", frame.phone, registration.plate, terminal.plate)
        body = encode_registration_response(frame.serial, RegistrationResult.NO_SUCH_VEHICLE)
    else:
        body = encode_registration_response(frame.serial, RegistrationResult.SUCCESS, terminals.auth_code(terminal))
    conversation.send(MessageId.REGISTRATION_RESPONSE, body)
    return True


def _plate_differs(terminal: Terminal, registration: Registration) -> bool:
    """Whether a registration names a plate, and the terminal list another one for its terminal: a terminal fitted
    to another vehicle than the list says, whose reports would be warned for the listed vehicle's category.

    A plate colour of 0 marks a vehicle without plates, whose identification field holds its VIN instead (the
    registration's layout in JT/T 808): nothing to compare. Neither is an empty field on either side. Letters are
    compared without regard to case, width, spaces and the separator dot some plates are written with."""
    if registration.plate_colour == 0 or not registration.plate or not terminal.plate:
        return False
    return _plate_key(registration.plate) != _plate_key(terminal.plate)


def _plate_key(plate: str) -> str:
    """A plate as compared: full-width letters, digits and spaces as their ASCII forms (NFKC), upper case, without
    spaces and separator dots."""
    return "".join(character for character in unicodedata.normalize("NFKC", plate).upper() if character not in " ·.")


def _authenticate(conversation: Conversation, frame: Frame) -> bool:
    """``0x0102`` -> ``0x8001``: success for a listed terminal with its current code, failure otherwise."""
    terminals = conversation.gateway.current_terminals()
    code = _body(conversation, frame, decode_authentication, "authentication")
    if code is None:
        return True
    conversation.terminal = terminals.admitted(frame.phone, code)
    conversation.respond(frame, ResponseResult.SUCCESS if conversation.terminal else ResponseResult.FAILURE)
    return True


def _heartbeat(conversation: Conversation, frame: Frame) -> bool:
    """``0x0002`` -> ``0x8001``: success while the terminal is admitted."""
    if admitted(conversation, frame) is not None:
        conversation.respond(frame, ResponseResult.SUCCESS)
    return True


def _terminal_response(conversation: Conversation, frame: Frame) -> bool:
    """``0x0001``, the terminal's general response: taken without an answer. A terminal that refuses temporary
    tracking (``0x8202``) is not asked again on this connection."""
    try:
        response = decode_terminal_response(frame.body)
    except BodyError as error:
        log.warning("jt808: general response of %s unreadable: %s", frame.phone, error)
        return True
    if response.message_id == MessageId.TEMPORARY_TRACKING and response.result != ResponseResult.SUCCESS:
        conversation.pace.refuse()
        log.warning("jt808: %s refused temporary tracking (result %d)", frame.phone, response.result)
    return True


def _deregister(conversation: Conversation, frame: Frame) -> bool:
    """``0x0003`` -> ``0x8001``, then the connection ends."""
    conversation.respond(frame, ResponseResult.SUCCESS)
    return False


def admitted(conversation: Conversation, frame: Frame) -> Terminal | None:
    """The conversation's terminal if it is still admitted; a failure response otherwise."""
    terminal = conversation.terminal
    if terminal is not None:
        listed = conversation.gateway.current_terminals().terminal(terminal.phone)
        if listed is None or listed.revoked or listed.generation != terminal.generation:
            conversation.terminal = terminal = None
    if terminal is None:
        conversation.respond(frame, ResponseResult.FAILURE)
    return terminal


def _locations(conversation: Conversation, frame: Frame) -> bool:
    """``0x0200`` and ``0x0704`` -> ``0x8001``, then the warning of the newest live report."""
    terminal = admitted(conversation, frame)
    if terminal is None:
        return True
    try:
        if frame.message_id == MessageId.LOCATION:
            reports = [decode_location(frame.body)]
        else:
            kind, reports = decode_location_batch(frame.body)
            reports = reports if kind == 0 else []  # 1: back-filled from a blind area, too old to warn
    except BodyError as error:
        log.warning("jt808: location report of %s unreadable: %s", frame.phone, error)
        conversation.respond(frame, ResponseResult.MESSAGE_ERROR)
        return True
    conversation.respond(frame, ResponseResult.SUCCESS)
    positioned = [report for report in reports if report.positioned]
    if positioned:
        _queue(conversation, terminal, positioned)
    return True


def _queue(conversation: Conversation, terminal: Terminal, reports: list[LocationReport]) -> None:
    """Queue ``reports`` for their warnings in time order, shedding the oldest not yet started beyond
    :data:`MAX_PENDING_REPORTS`, so that reading and answering ``0x8001`` never wait for a warning."""
    gateway, waiting, pace = conversation.gateway, conversation.waiting, conversation.pace
    now_s, read_at = gateway.clock(), conversation.read_at
    tracks = gateway.tracks(terminal.fleet)
    for report in reports if len(reports) == 1 else sorted(reports, key=lambda r: r.time_s):
        query = report_query(terminal, report, now_s)
        pace.observe(report.time_s)
        intervals_s = pace.due(report.time_s, gateway.settings.tracking) if tracks else None
        entry = Waiting(query, terminal.fleet, partial(_tell, conversation, terminal, report, read_at), intervals_s)
        waiting.append(entry)
        gateway.batcher.queue(entry)
    while waiting and waiting[0].started:
        waiting.popleft()
    if len(waiting) > MAX_PENDING_REPORTS:
        shed = len(waiting) - MAX_PENDING_REPORTS
        for _ in range(shed):
            waiting.popleft().shed = True
        gateway.counts["shed"] += shed
        log.warning("jt808: the gateway falls behind; %d old report(s) of %s shed", shed, terminal.phone)


def _tell(
    conversation: Conversation, terminal: Terminal, report: LocationReport, read_at: float, answer: AnswerSummary | None
) -> None:
    """Tell the driver when ``report``'s answer changes the indication (``0x8300``), at once.

    Counted in the gateway's stage times: ``answered`` from the report's bytes read to its answer
    here, ``text`` from read to its ``0x8300`` handed to the connection (where one was due).
    """
    gateway = conversation.gateway
    gateway.counts["evaluated"] += 1
    gateway.times.add("answered", time.perf_counter() - read_at)
    if conversation.closing():
        return
    if answer is None:  # the state store unreachable, or a report the networks cannot answer: no warning can come
        answer = NOT_ANSWERED
    if conversation.announcer is None:
        conversation.announcer = Announcer(gateway.settings.texts(terminal.fleet))
    told = conversation.announcer.update(answer.state, answer.level, answer.warning_speed_kmh, report.time_s)
    if told is not None:
        text, urgent = told
        conversation.send(MessageId.TEXT_MESSAGE, encode_text_message(text, conversation.edition, emergency=urgent))
        gateway.counts["told"] += 1
        gateway.times.add("text", time.perf_counter() - read_at)
    window_s = answer.tracking_window_s
    settings = gateway.settings.tracking
    if window_s is not None and conversation.pace.start(
        report.time_s, window_s, gateway.clock() - report.time_s, settings
    ):
        conversation.send(MessageId.TEMPORARY_TRACKING, encode_temporary_tracking(settings.interval_s, window_s))
        gateway.counts["tracked"] += 1
    conversation.flush()


#: What each message the gateway reads is answered by; any other gets result 3, not supported.
HANDLERS: dict[int, Callable[[Conversation, Frame], bool]] = {
    MessageId.TERMINAL_RESPONSE: _terminal_response,
    MessageId.REGISTRATION: _register,
    MessageId.AUTHENTICATION: _authenticate,
    MessageId.HEARTBEAT: _heartbeat,
    MessageId.DEREGISTRATION: _deregister,
    MessageId.LOCATION: _locations,
    MessageId.LOCATION_BATCH: _locations,
}
