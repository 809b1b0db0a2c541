"""Delivery of events to the fleets' webhooks: signed JSON POSTs, retried in order per vehicle.

Each event goes to every webhook of its fleet as the body of a POST (``application/json``, the event
as the outbox keeps it) with the headers

* ``X-CSWS-Signature: t=<unix s>,v1=<hex>``: the HMAC-SHA256 with the fleet's secret of ``f"{t}."``
  followed by the body (:func:`signature`); a receiver computes it, compares in constant time, and
  refuses a ``t`` far from its clock (say 5 minutes) against replay;
* ``Idempotency-Key: <fleet>:<vehicle_id>:<seq>``: the same for every delivery of one event, which
  may come more than once (after a timeout, or a crash of the service).

A 2xx answer delivers it. Anything else, a timeout or a refused connection is retried later
(:class:`service.push.policy.RetryPolicy`); meanwhile the vehicle's later events wait behind it, in
order, while other vehicles' events go on. A webhook that cannot be reached at all (no connection,
a timeout) is paused until its next retry, so that one dead receiver costs one timeout per retry
and not one per event. After the last try an event is a dead letter.
"""

from __future__ import annotations

import hashlib
import hmac
import http.client
import logging
import random
import threading
import zlib
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import NamedTuple, Protocol
from urllib.parse import quote, urlsplit

import msgspec

from csws import __version__

from .addresses import UnsafeTarget, pinned_connection
from .lease import Lease
from .policy import RetryPolicy
from .source import Event, EventSource, StoredEvent, parse_event
from .state import Pending, PushStore, QueuedRow
from .targets import Webhook

__all__ = ["signature", "idempotency_key", "PushCounts", "WebhookSender", "WebhookDispatch", "Attempt", "BATCH"]

logger = logging.getLogger("csws.push")

#: Events read from the outbox at a time.
BATCH = 500
#: The wait between reads of the outbox while no fleet has a webhook, s: the outbox is still read (its cursor moves
#: past what nobody subscribed to), but not at the poll interval of a dispatcher with somewhere to deliver; a webhook
#: added gets its fleet's events from at most this long before it was added.
IDLE_WITHOUT_WEBHOOKS_S = 1.0
#: Queued events tried per webhook in one pass, before new events get their turn.
RETRIES_PER_PASS = 500
#: Connections per webhook over which new events go out at once (retries take the first), each vehicle's always
#: over the same one, in order: the round trips of one overlap those of the others.
LANES = 4
#: The most of a webhook's answer read, bytes: the status is what counts; a longer answer closes the connection.
MAX_ANSWER_BYTES = 64 * 1024
_PRINTABLE = "".join(chr(code) for code in range(0x20, 0x7F) if chr(code) != "%")


def signature(secret: str, body: bytes, unix_s: int) -> str:
    """The ``X-CSWS-Signature`` of ``body`` sent at ``unix_s``: ``t=<unix s>,v1=<hex HMAC-SHA256>``."""
    digest = hmac.new(secret.encode("utf-8"), f"{unix_s}.".encode() + body, hashlib.sha256).hexdigest()
    return f"t={unix_s},v1={digest}"


def idempotency_key(event: Event) -> str:
    """The ``Idempotency-Key`` of an event: ``<fleet>:<vehicle_id>:<seq>``, the same at every delivery; a character
    of the vehicle id that is no printable ASCII (or is ``%``) is percent-encoded, as a header's value must be."""
    return f"{event.fleet}:{quote(event.vehicle_id, safe=_PRINTABLE)}:{event.seq}"


class PushCounts(Protocol):
    """Where push counts what it does (:class:`service.metrics.Metrics`)."""

    def observe_push(self, sink: str, outcome: str, count: int = 1) -> None:
        """Count ``count`` events of the kind of sink ``sink`` with ``outcome``."""

    def set_push_gauges(self, sink: str, waiting: int, lag_s: float) -> None:
        """The events waiting for the sinks of a kind, and the lag of its last delivery, s."""


class Attempt(NamedTuple):
    """What came of one delivery: whether it went out, why not, and whether the receiver answered at all."""

    ok: bool
    error: str = ""
    answered: bool = True


class WebhookSender:
    """POSTs to webhooks over kept-alive connections, each opened to an address checked at that moment."""

    def __init__(self, allow_private: bool, timeout_s: float, clock: Callable[[], float], lanes: int = LANES) -> None:
        self.allow_private, self.timeout_s, self.clock, self.lanes = allow_private, timeout_s, clock, lanes
        self._connections: dict[tuple[str, int], http.client.HTTPConnection] = {}

    def post(self, webhook: Webhook, body: bytes, key: str, lane: int = 0) -> Attempt:
        """Deliver ``body`` to ``webhook`` once over the connection of ``lane``, signed now; a kept connection that
        went stale is opened anew."""
        headers = {
            "Content-Type": "application/json",
            "User-Agent": f"csws/{__version__}",
            "Idempotency-Key": key,
            "X-CSWS-Signature": signature(webhook.secret, body, int(self.clock())),
        }
        kept = (webhook.url, lane) in self._connections
        attempt = self._post_once((webhook.url, lane), body, headers)
        if not attempt.answered and kept:
            attempt = self._post_once((webhook.url, lane), body, headers)
        return attempt

    def _post_once(self, lane: tuple[str, int], body: bytes, headers: dict[str, str]) -> Attempt:
        """One POST over the kept connection of a webhook's lane, or a new one."""
        url = lane[0]
        try:
            connection = self._connections.get(lane) or pinned_connection(url, self.allow_private, self.timeout_s)
            self._connections[lane] = connection
            parts = urlsplit(url)
            connection.request("POST", (parts.path or "/") + (f"?{parts.query}" if parts.query else ""), body, headers)
            response = connection.getresponse()
            response.read(MAX_ANSWER_BYTES)
        except UnsafeTarget as error:
            self._close(lane)
            return Attempt(False, str(error), answered=False)
        except (OSError, http.client.HTTPException) as error:
            self._close(lane)
            return Attempt(False, f"{type(error).__name__}: {error}", answered=False)
        if response.will_close or not response.isclosed():  # to be closed, or an answer longer than read
            self._close(lane)
        if 200 <= response.status < 300:
            return Attempt(True)
        return Attempt(False, f"HTTP {response.status}")

    def _close(self, lane: tuple[str, int]) -> None:
        """Close the connection of a webhook's lane, if open."""
        connection = self._connections.pop(lane, None)
        if connection is not None:
            connection.close()

    def close(self) -> None:
        """Close every connection."""
        for lane in list(self._connections):
            self._close(lane)


class WebhookDispatch:
    """One dispatcher's delivery to all webhooks: a :meth:`step` reads new events and retries those due.

    The webhooks share one cursor in the outbox (``webhooks``): a new webhook receives the events after
    it, and each event read goes out to each webhook of its fleet at once or into that webhook's queue.
    """

    SINK = "webhooks"

    def __init__(
        self,
        source: EventSource,
        state: PushStore,
        webhooks: Callable[[], list[Webhook]],
        lease: Lease,
        sender: WebhookSender,
        policy: RetryPolicy,
        counts: PushCounts | None = None,
    ) -> None:
        self.source, self.state, self.webhooks, self.lease = source, state, webhooks, lease
        self.sender, self.policy, self.counts = sender, policy, counts
        self.clock = sender.clock
        self.rng = random.Random()
        self._paused_until_s: dict[str, float] = {}
        self._lag_s = 0.0
        self._pool = ThreadPoolExecutor(sender.lanes, thread_name_prefix="csws-push-lane")
        self._counting = threading.Lock()

    def close(self) -> None:
        """Stop the lanes' threads and close the connections."""
        self._pool.shutdown()
        self.sender.close()

    def step(self) -> float | None:
        """Retry what is due, then deliver the next events of the outbox; 0 when there may be more to do at once,
        None when there was nothing to do (wait the poll interval), :data:`IDLE_WITHOUT_WEBHOOKS_S` when nothing
        was stored and no fleet has a webhook."""
        webhooks = self.webhooks()
        worked = any([self._retry(webhook) for webhook in webhooks])
        stored = self.source.events_after(None, self.state.cursor(self.SINK), BATCH)
        if stored:
            self._deliver_new(webhooks, stored)
        if self.counts is not None:
            waiting = sum(self.state.queued_count(webhook.sink) for webhook in webhooks)
            self.counts.set_push_gauges("webhook", waiting, self._lag_s)
        if worked or stored:
            return 0.0
        return None if webhooks else IDLE_WITHOUT_WEBHOOKS_S

    def _deliver_new(self, webhooks: list[Webhook], stored: list[StoredEvent]) -> None:
        """Send each event to the webhooks of its fleet, or queue it; then move the cursor past them all."""
        events = [(item, _parsed(item)) for item in stored]
        by_fleet: dict[str, list[tuple[StoredEvent, Event]]] = {}
        for item, event in events:
            if event is not None:
                by_fleet.setdefault(event.fleet, []).append((item, event))
        queued = [row for webhook in webhooks for row in self._send_or_queue(webhook, by_fleet.get(webhook.fleet, []))]
        self.state.advance(self.SINK, stored[-1].cursor, queued, self.clock())

    def _send_or_queue(self, webhook: Webhook, events: list[tuple[StoredEvent, Event]]) -> list[QueuedRow]:
        """Send the events to one webhook over its lanes at once, and the rows to queue: those that failed and
        those behind them. A vehicle's events always take the same lane, in order."""
        if not events:
            return []
        waiting = self.state.waiting_vehicles(webhook.sink)
        lanes: list[list[tuple[StoredEvent, Event]]] = [[] for _ in range(self.sender.lanes)]
        for item, event in events:
            lanes[zlib.crc32(item.vehicle_key.encode()) % len(lanes)].append((item, event))
        sent = self._pool.map(lambda lane: self._send_lane(webhook, lane, lanes[lane], waiting), range(len(lanes)))
        return [row for rows in sent for row in rows]

    def _send_lane(
        self, webhook: Webhook, lane: int, events: list[tuple[StoredEvent, Event]], waiting: set[str]
    ) -> list[QueuedRow]:
        """Send one lane's events to a webhook, in order; the rows to queue."""
        queued: list[QueuedRow] = []
        for item, event in events:
            paused_until_s = self._paused_until_s.get(webhook.sink, 0.0)
            now_s = self.clock()
            if item.vehicle_key in waiting or paused_until_s > now_s:
                queued.append((webhook.sink, item.vehicle_key, item.body, 0, max(now_s, paused_until_s), ""))
                continue
            self.lease.keep()
            attempt = self.sender.post(webhook, item.body, idempotency_key(event), lane)
            if attempt.ok:
                self._delivered(event)
                continue
            next_s = self._failed(webhook, attempt, 1)
            queued.append((webhook.sink, item.vehicle_key, item.body, 1, next_s, attempt.error))
            waiting.add(item.vehicle_key)
        return queued

    def _retry(self, webhook: Webhook) -> bool:
        """Try the first queued event of each vehicle whose time has come, and the next ones as they go out."""
        tried = 0
        while tried < RETRIES_PER_PASS and self._paused_until_s.get(webhook.sink, 0.0) <= self.clock():
            due = self.state.due(webhook.sink, self.clock(), RETRIES_PER_PASS - tried)
            if not due:
                break
            for pending in due:
                tried += 1
                if not self._retry_one(webhook, pending):
                    return True
        return tried > 0

    def _retry_one(self, webhook: Webhook, pending: Pending) -> bool:
        """Try one queued event again; whether the webhook answered (else it is paused)."""
        event = _parsed(pending)
        if event is None:
            self.state.delivered(pending.number)
            return True
        self.lease.keep()
        attempt = self.sender.post(webhook, pending.body, idempotency_key(event))
        if attempt.ok:
            self.state.delivered(pending.number)
            self._delivered(event)
            return True
        tries, now_s = pending.tries + 1, self.clock()
        if self.policy.gives_up(tries, pending.queued_s, now_s):
            self.state.dead(pending, tries, attempt.error, now_s)
            self._count("dead_lettered")
            logger.warning(
                "webhook %s: event %s given up after %d tries: %s", webhook.url, pending.vehicle, tries, attempt.error
            )
        else:
            self.state.failed(pending.number, tries, self._failed(webhook, attempt, tries), attempt.error)
        return attempt.answered

    def _failed(self, webhook: Webhook, attempt: Attempt, tries: int) -> float:
        """Count a failed try and return when to try again; a webhook that did not answer pauses till then."""
        self._count("retried")
        next_s = self.clock() + self.policy.delay_s(tries, self.rng)
        if not attempt.answered:
            self._paused_until_s[webhook.sink] = next_s
        return next_s

    def _delivered(self, event: Event) -> None:
        """Count a delivered event, and the lag from its time to now."""
        self._lag_s = max(0.0, self.clock() - event.time)
        self._count("delivered")

    def _count(self, outcome: str) -> None:
        """Count an event of the webhooks with ``outcome`` (delivered, retried, dead_lettered), from any lane."""
        if self.counts is not None:
            with self._counting:
                self.counts.observe_push("webhook", outcome)


def _parsed(item: StoredEvent | Pending) -> Event | None:
    """The event of an outbox row, None (logged, skipped) for a body that is no event."""
    try:
        return parse_event(item.body)
    except (msgspec.ValidationError, msgspec.DecodeError) as error:
        logger.error(
            "an event of %s that is no event is skipped: %s",
            item.vehicle_key if isinstance(item, StoredEvent) else item.vehicle,
            error,
        )
        return None
