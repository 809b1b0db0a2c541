"""Push of the service's events to the fleets' webhooks and to an MQTT broker.

The service writes its events (warnings, releases, changes of state) to a durable outbox in its
state store; push reads them after a durable cursor (:class:`source.EventSource`) and delivers them:

* to each webhook of the event's fleet (:mod:`.webhooks`), signed, retried with backoff in order per
  vehicle, and put in the dead letters after the last try; the webhooks are the service admin's
  (:mod:`.targets`, ``csws webhooks``), and reach no address the service must not (:mod:`.addresses`);
* to an MQTT broker (:mod:`.mqtt`): each event with QoS 1, the vehicle's state retained.

Every worker starts a dispatcher of each kind (:func:`start_push`); a lease (:mod:`.lease`) in the
push state (:mod:`.state`) lets one deliver at a time. See docs/push.md.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from .addresses import UnsafeTarget
from .lease import LEASE_S, Lease
from .mqtt import MqttDispatch, MqttPublisher
from .policy import RetryPolicy
from .runner import POLL_S, Runner
from .source import EventSource, StoredEvent
from .state import open_push_state, push_db_beside
from .targets import WebhookBook
from .webhooks import PushCounts, WebhookDispatch, WebhookSender

if TYPE_CHECKING:
    from ..settings import ServiceSettings

__all__ = [
    "EventSource",
    "StoredEvent",
    "PushConfig",
    "PushCounts",
    "RetryPolicy",
    "UnsafeTarget",
    "start_push",
    "push_config",
    "start_service_push",
]

logger = logging.getLogger("csws.push")


@dataclass(frozen=True)
class PushConfig:
    """Where and how to push.

    Attributes
    ----------
    state_db
        Where push keeps its state (cursors, retries, dead letters, leases): a SQLite file, or a Redis URL for
        replicas on several machines.
    webhooks_file
        The fleets' webhooks (:mod:`.targets`); None: no webhooks.
    mqtt_url
        The broker (``mqtt://HOST:PORT``); "": no MQTT.
    allow_private
        Whether webhooks may reach loopback and private addresses.
    policy
        Retries of the webhooks.
    lease_s, poll_s
        The lease's duration and the idle poll interval, s.
    """

    state_db: str
    webhooks_file: Path | None = None
    mqtt_url: str = ""
    allow_private: bool = False
    policy: RetryPolicy = RetryPolicy()
    lease_s: float = LEASE_S
    poll_s: float = POLL_S


def start_push(
    config: PushConfig,
    source: EventSource,
    counts: PushCounts | None = None,
    clock: Callable[[], float] = time.time,
) -> Callable[[], None]:
    """Start the dispatchers ``config`` asks for (none when it names no webhook file and no broker).

    Returns
    -------
    Callable
        What stops them: each finishes the delivery under way, gives its lease up and closes.
    """
    if config.webhooks_file is None and not config.mqtt_url:
        return lambda: None
    state = open_push_state(config.state_db)
    runners: list[Runner] = []
    closers: list[Callable[[], None]] = [state.close]
    if config.webhooks_file is not None:
        lease = Lease(state, "webhooks", config.lease_s, clock)
        sender = WebhookSender(config.allow_private, config.policy.timeout_s, clock)
        book = WebhookBook(config.webhooks_file)
        dispatch = WebhookDispatch(source, state, book.webhooks, lease, sender, config.policy, counts)
        runners.append(Runner("csws-push-webhooks", lease, dispatch.step, config.poll_s, _idle(counts, "webhook")))
        closers.insert(0, dispatch.close)
    if config.mqtt_url:
        lease = Lease(state, "mqtt", config.lease_s, clock)
        publisher = MqttPublisher(config.mqtt_url, client_id=f"csws-{lease.holder}")
        mqtt = MqttDispatch(source, state, publisher, lease, counts, clock)
        runners.append(Runner("csws-push-mqtt", lease, mqtt.step, config.poll_s, _idle(counts, "mqtt")))
        closers.insert(0, publisher.close)
    for runner in runners:
        runner.start()

    def stop() -> None:
        for runner in runners:
            runner.stop()
        for close in closers:
            close()

    return stop


def _idle(counts: PushCounts | None, sink: str) -> Callable[[], None] | None:
    """What zeroes the gauges of a dispatcher that does not hold its lease (the holder's count in the sum)."""
    if counts is None:
        return None
    return lambda: counts.set_push_gauges(sink, 0, 0.0)


def push_config(settings: ServiceSettings) -> PushConfig:
    """What the service's settings ask of push: its webhook file (by default ``webhooks.json`` beside the API key
    file), its broker, and where it keeps its state (by default the state store's Redis, else ``push.sqlite3``
    beside the state store's file)."""
    webhooks_file = settings.webhooks_file
    if webhooks_file is None and settings.api_keys_file is not None:
        webhooks_file = settings.api_keys_file.with_name("webhooks.json")
    return PushConfig(
        settings.push_db.strip() or settings.state or push_db_beside(settings.state_db),
        webhooks_file,
        settings.mqtt,
        settings.webhook_allow_private,
    )


def start_service_push(settings: ServiceSettings, store: EventSource, counts: PushCounts | None) -> Callable[[], None]:
    """Start push in a worker of the service, reading the outbox of its state store; what stops it (nothing to
    stop when neither webhooks nor MQTT are configured)."""
    config = push_config(settings)
    if config.webhooks_file is None and not config.mqtt_url:
        return lambda: None
    return start_push(config, store, counts)
