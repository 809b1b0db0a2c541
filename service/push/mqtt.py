"""Publication of events to an MQTT broker (``csws serve --mqtt mqtt://HOST:PORT``).

Each event goes to ``csws/{fleet}/{vehicle}/events`` with QoS 1, and the vehicle's state,
``{"state", "level", "time", "seq"}``, is published retained on ``csws/{fleet}/{vehicle}/state``, so
that an on-board unit or a dashboard that subscribes gets the vehicle's state at once: whenever its
system state or warning level changes, with the time and number of the event that changed it. In a topic a
vehicle id's ``+``, ``#`` and ``%`` are written ``%2B``, ``%23`` and ``%25`` (the wildcards cannot
stand in a topic name); fleet names and vehicle ids have no ``/``.

The cursor in the outbox moves past a batch of events only once the broker acknowledged every one of
its messages (PUBACK). A broker that is gone is reconnected to with backoff (1 s doubling to 30 s),
and the batch is published again: a subscriber gets each event at least once, in order per vehicle.
``mqtts://`` connects over TLS; a user and password in the URL log in.
"""

from __future__ import annotations

import logging
import ssl
import threading
import time
from collections.abc import Callable
from urllib.parse import unquote, urlsplit

import msgspec
import paho.mqtt.client as paho

from .lease import Lease
from .source import Event, EventSource, parse_event
from .state import PushStore
from .webhooks import BATCH, PushCounts

__all__ = ["MqttPublisher", "MqttDispatch", "events_topic", "state_topic", "check_mqtt_url"]

logger = logging.getLogger("csws.push")

#: The schemes of ``--mqtt`` and their default ports.
MQTT_SCHEMES = {"mqtt": 1883, "mqtts": 8883}
#: How long a batch may wait for a connection and its acknowledgements, s: well within the lease, which is
#: renewed between batches.
ACK_TIMEOUT_S = 3.0
#: Messages in flight at once (sent, PUBACK not yet come).
MAX_IN_FLIGHT = 1000
_TOPIC_ESCAPES = str.maketrans({"%": "%25", "+": "%2B", "#": "%23"})


def _topic_level(name: str) -> str:
    """A fleet name or vehicle id as one level of a topic (no wildcard characters)."""
    return name.translate(_TOPIC_ESCAPES)


def events_topic(fleet: str, vehicle_id: str) -> str:
    """The topic of a vehicle's events: ``csws/{fleet}/{vehicle}/events``."""
    return f"csws/{_topic_level(fleet)}/{_topic_level(vehicle_id)}/events"


def state_topic(fleet: str, vehicle_id: str) -> str:
    """The topic of a vehicle's retained state: ``csws/{fleet}/{vehicle}/state``."""
    return f"csws/{_topic_level(fleet)}/{_topic_level(vehicle_id)}/state"


def check_mqtt_url(url: str) -> str:
    """``url`` when it names a broker (``mqtt://HOST[:PORT]`` or ``mqtts://``); ValueError in one line otherwise."""
    parts = urlsplit(url)
    try:
        parts.port  # noqa: B018 - a port that is no number raises here
    except ValueError:
        raise ValueError(f"{url!r}: the port of an MQTT URL is a number") from None
    if parts.scheme not in MQTT_SCHEMES or not parts.hostname:
        raise ValueError(f"{url!r}: give the broker as mqtt://HOST:PORT (or mqtts:// for TLS)")
    return url


_STATE_ENCODER = msgspec.json.Encoder()


def _state_body(event: Event) -> bytes:
    """The retained state of a vehicle after ``event``: its system state, warning level, time and number."""
    return _STATE_ENCODER.encode({"state": event.state, "level": event.level, "time": event.time, "seq": event.seq})


class MqttPublisher:
    """A connection to the broker, kept up by paho's network thread (reconnecting with backoff)."""

    def __init__(self, url: str, client_id: str) -> None:
        parts = urlsplit(check_mqtt_url(url))
        self.client = paho.Client(paho.CallbackAPIVersion.VERSION2, client_id=client_id, clean_session=True)
        self.client.max_inflight_messages_set(MAX_IN_FLIGHT)
        self.client.max_queued_messages_set(0)
        self.client.reconnect_delay_set(min_delay=1, max_delay=30)
        self.connected = threading.Event()
        self.client.on_connect = lambda _client, _data, _flags, reason, _properties: (
            self.connected.set() if not reason.is_failure else None
        )
        self.client.on_disconnect = lambda *_arguments: self.connected.clear()
        self._acknowledged: set[int] = set()  # acknowledged before their batch waits for them
        self._awaited: set[int] = set()  # the batch's messages not yet acknowledged
        self._acknowledgement = threading.Condition()
        self.client.on_publish = self._acknowledged_one
        if parts.username:
            self.client.username_pw_set(unquote(parts.username), unquote(parts.password or "") or None)
        if parts.scheme == "mqtts":
            self.client.tls_set_context(ssl.create_default_context())
        self.client.connect_async(parts.hostname or "", parts.port or MQTT_SCHEMES[parts.scheme], keepalive=30)
        self.client.loop_start()

    def publish_all(self, messages: list[tuple[str, bytes, bool]], timeout_s: float) -> bool:
        """Publish (topic, payload, retain) with QoS 1, in order; whether the broker acknowledged them all
        within ``timeout_s`` (which includes waiting for a connection)."""
        if not self.connected.wait(timeout_s):
            return False
        infos = [self.client.publish(topic, payload, qos=1, retain=retain) for topic, payload, retain in messages]
        if any(info.rc != paho.MQTT_ERR_SUCCESS for info in infos):
            return False
        with self._acknowledgement:
            self._awaited = {info.mid for info in infos} - self._acknowledged
            self._acknowledged.clear()
            return self._acknowledgement.wait_for(lambda: not self._awaited, timeout_s)

    def _acknowledged_one(self, _client: paho.Client, _data: object, mid: int, *_arguments: object) -> None:
        """paho's network thread: the broker acknowledged the message ``mid`` (PUBACK)."""
        with self._acknowledgement:
            if mid not in self._awaited:
                self._acknowledged.add(mid)
                return
            self._awaited.discard(mid)
            if not self._awaited:
                self._acknowledgement.notify()

    def close(self) -> None:
        """Disconnect and stop the network thread."""
        self.client.disconnect()
        self.client.loop_stop()


class MqttDispatch:
    """One dispatcher's publication of the outbox to the broker: a :meth:`step` publishes the next events."""

    SINK = "mqtt"

    def __init__(
        self,
        source: EventSource,
        state: PushStore,
        publisher: MqttPublisher,
        lease: Lease,
        counts: PushCounts | None = None,
        clock: Callable[[], float] = time.time,
    ) -> None:
        self.source, self.state, self.publisher, self.lease, self.counts = source, state, publisher, lease, counts
        self.clock = clock
        self.failures = 0
        #: Per vehicle, the state and level retained last: a state is published again only when it changes.
        self._retained: dict[tuple[str, str], tuple[str, int]] = {}

    def _changed_states(self, events: list[Event]) -> dict[tuple[str, str], Event]:
        """Per vehicle whose state or level differs from the one retained, the event of its change to the state
        it ends the batch in (a vehicle first seen since the dispatcher started counts as changed)."""
        since: dict[tuple[str, str], Event] = {}
        for event in events:
            vehicle = (event.fleet, event.vehicle_id)
            if vehicle not in since or (since[vehicle].state, since[vehicle].level) != (event.state, event.level):
                since[vehicle] = event
        return {
            vehicle: event
            for vehicle, event in since.items()
            if self._retained.get(vehicle) != (event.state, event.level)
        }

    def step(self) -> float | None:
        """Publish the next events and the vehicles' states after them; the wait before the next step, s
        (None: nothing to do, the poll interval).

        When the broker does not acknowledge them all, the cursor stays and they go again after a wait
        (doubling from 1 s up to 30 s).
        """
        stored = self.source.events_after(None, self.state.cursor(self.SINK), BATCH)
        if not stored:
            return None
        pairs = [(event, item.body) for item in stored if (event := _parsed(item.body)) is not None]
        events = [event for event, _ in pairs]
        messages = [(events_topic(e.fleet, e.vehicle_id), body, False) for e, body in pairs]
        changed = self._changed_states(events)
        messages += [(state_topic(*vehicle), _state_body(e), True) for vehicle, e in changed.items()]
        self.lease.keep()
        if not self.publisher.publish_all(messages, ACK_TIMEOUT_S):
            self.failures += 1
            wait_s = min(2.0 ** (self.failures - 1), 30.0)
            logger.warning("the MQTT broker did not take %d events; again in %.0f s", len(events), wait_s)
            if self.counts is not None:
                self.counts.observe_push("mqtt", "retried", len(events))
            return wait_s
        self.failures = 0
        self._retained.update({vehicle: (e.state, e.level) for vehicle, e in changed.items()})
        self.state.advance(self.SINK, stored[-1].cursor, [], self.clock())
        if self.counts is not None:
            self.counts.observe_push("mqtt", "delivered", len(events))
            self.counts.set_push_gauges("mqtt", 0, max(0.0, self.clock() - events[-1].time) if events else 0.0)
        return 0.0


def _parsed(body: bytes) -> Event | None:
    """The event of a body, None (logged, skipped) for a body that is no event."""
    try:
        return parse_event(body)
    except (msgspec.ValidationError, msgspec.DecodeError) as error:
        logger.error("an event that is no event is not published: %s", error)
        return None
