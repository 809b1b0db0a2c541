"""Push of events to webhooks and MQTT (service.push), against real receivers on loopback.

The webhook receiver is a real HTTP server that fails, times out and recovers on a script; the test
checks every signature with its own HMAC-SHA256 and the order of each vehicle's events by their
numbers. The MQTT tests start a real ``mosquitto`` (the Debian package; tests/system-packages.sh
installs it) on a free loopback port (tests/push_receivers.py).
"""

from __future__ import annotations

import ipaddress
import json
import socket
import time
from collections.abc import Callable, Iterator
from dataclasses import replace
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st
from push_receivers import (
    FLEET,
    Mosquitto,
    Receiver,
    Subscriber,
    event_body,
    signature_holds,
    wait_until,
    write_events,
)

from csws.cli import main as csws_main
from service.metrics import Metrics
from service.push import PushConfig, RetryPolicy, push_config, start_push, start_service_push
from service.push.addresses import UnsafeTarget, address_refusal, resolved_addresses
from service.push.lease import Lease, LeaseLost
from service.push.source import MemoryOutbox, StoredEvent
from service.push.state import PushState, open_push_state
from service.push.targets import add_webhook
from service.push.webhooks import IDLE_WITHOUT_WEBHOOKS_S
from service.settings import ServiceSettings


@pytest.fixture
def receiver_factory() -> Iterator[Callable[..., Receiver]]:
    receivers: list[Receiver] = []

    def make(script: Callable[[int, str], tuple[int, float]] = lambda number, key: (200, 0.0)) -> Receiver:
        receivers.append(Receiver(script))
        return receivers[-1]

    yield make
    for receiver in receivers:
        receiver.stop()


def quick_config(tmp_path: Path, state: dict[str, str] | None = None, **changes) -> PushConfig:
    """Push to the webhooks of tmp_path's file, loopback allowed, with quick retries; its state in a SQLite file in
    tmp_path, or in the Redis of ``state`` (the ``state`` fixture's settings)."""
    policy = changes.pop("policy", RetryPolicy(max_tries=50, first_delay_s=0.05, max_delay_s=0.2, timeout_s=0.3))
    return PushConfig(
        (state or {}).get("state") or str(tmp_path / "push.sqlite3"),
        webhooks_file=tmp_path / "webhooks.json",
        allow_private=True,
        policy=policy,
        **changes,
    )


def in_order_per_vehicle(requests: list[dict]) -> dict[str, list[int]]:
    """The numbers of each vehicle's events in the order the requests arrived."""
    numbers: dict[str, list[int]] = {}
    for request in requests:
        event = json.loads(request["body"])
        assert request["key"] == f"{event['fleet']}:{event['vehicle_id']}:{event['seq']}"
        numbers.setdefault(event["vehicle_id"], []).append(event["seq"])
    return numbers


def test_a_receiver_that_fails_times_out_and_recovers_gets_every_event_in_order(tmp_path, receiver_factory, state):
    # Requests 1-6 are refused (500), 7-9 answered after the delivery's timeout, then all are taken.
    def script(number: int, key: str) -> tuple[int, float]:
        return (500, 0.0) if number <= 6 else (200, 0.6) if number <= 9 else (200, 0.0)

    receiver = receiver_factory(script)
    secret = add_webhook(tmp_path / "webhooks.json", FLEET, receiver.url, allow_private=True)
    assert secret is not None
    outbox, vehicles, count = MemoryOutbox(), ["truck-1", "truck-2", "bus-3"], 20
    write_events(outbox, vehicles, count)
    stop = start_push(quick_config(tmp_path), outbox)
    try:
        wait_until(
            lambda: (
                {r["key"] for r in receiver.accepted()}
                >= {f"{FLEET}:{v}:{s}" for v in vehicles for s in range(1, count + 1)}
            )
        )
    finally:
        stop()
    assert all(signature_holds(secret, request) for request in receiver.requests)
    for vehicle, numbers in in_order_per_vehicle(receiver.accepted()).items():
        assert numbers == sorted(numbers), vehicle  # never an earlier event after a later one
        assert sorted(set(numbers)) == list(range(1, count + 1))
    assert len(receiver.requests) > len(vehicles) * count  # the failures were retried


def test_other_vehicles_go_on_while_one_vehicle_is_refused(tmp_path, receiver_factory):
    refused_until_s = time.time() + 1.0

    def script(number: int, key: str) -> tuple[int, float]:
        return (500, 0.0) if key.startswith(f"{FLEET}:stuck:") and time.time() < refused_until_s else (200, 0.0)

    receiver = receiver_factory(script)
    add_webhook(tmp_path / "webhooks.json", FLEET, receiver.url, allow_private=True)
    outbox = MemoryOutbox()
    write_events(outbox, ["stuck", "free"], 5)
    stop = start_push(quick_config(tmp_path), outbox)
    try:
        wait_until(lambda: len({r["key"] for r in receiver.accepted() if ":free:" in r["key"]}) == 5, 0.9)
        assert not any(":stuck:" in r["key"] for r in receiver.accepted())  # stuck's first event still refused
        wait_until(lambda: len({r["key"] for r in receiver.accepted()}) == 10)
    finally:
        stop()
    assert in_order_per_vehicle(receiver.accepted())["stuck"] == [1, 2, 3, 4, 5]


def test_a_vehicle_id_that_is_no_header_value_is_percent_encoded_in_the_idempotency_key(tmp_path, receiver_factory):
    receiver = receiver_factory()
    add_webhook(tmp_path / "webhooks.json", FLEET, receiver.url, allow_private=True)
    outbox, vehicle = MemoryOutbox(), "Lkw ä\r\n%1"
    outbox.write(FLEET, vehicle, event_body(vehicle, 1))
    stop = start_push(quick_config(tmp_path), outbox)
    try:
        wait_until(lambda: len(receiver.requests) == 1)
    finally:
        stop()
    assert receiver.requests[0]["key"] == f"{FLEET}:Lkw %C3%A4%0D%0A%251:1"
    assert json.loads(receiver.requests[0]["body"])["vehicle_id"] == vehicle


def test_an_event_never_taken_is_a_dead_letter_after_the_last_try(tmp_path, receiver_factory, capsys, state):
    receiver = receiver_factory(lambda number, key: (503, 0.0))
    add_webhook(tmp_path / "webhooks.json", FLEET, receiver.url, allow_private=True)
    outbox, tries = MemoryOutbox(), 3
    write_events(outbox, ["truck-1", "truck-2"], 2)
    policy = RetryPolicy(max_tries=tries, first_delay_s=0.02, max_delay_s=0.05, timeout_s=0.5)
    config = quick_config(tmp_path, state, policy=policy)
    stop = start_push(config, outbox)
    kept = open_push_state(config.state_db)
    try:
        wait_until(lambda: len(kept.dead_letters()) == 4)
    finally:
        stop()
    letters = kept.dead_letters()
    kept.close()
    assert all(letter.tries == tries and letter.error == "HTTP 503" for letter in letters)
    per_key: dict[str, int] = {}
    for request in receiver.requests:
        per_key[request["key"]] = per_key.get(request["key"], 0) + 1
    assert per_key == {f"{FLEET}:{v}:{s}": tries for v in ("truck-1", "truck-2") for s in (1, 2)}
    for vehicle in ("truck-1", "truck-2"):  # given up in order: a vehicle's second event only after its first
        assert [json.loads(letter.body)["seq"] for letter in letters if letter.vehicle == f"{FLEET}/{vehicle}"] == [
            1,
            2,
        ]
    assert csws_main(["webhooks", "dead-letters", "--db", config.state_db, "--fleet", FLEET, "--json"]) == 0
    shown = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [(row["event"]["vehicle_id"], row["event"]["seq"], row["tries"]) for row in shown] == [
        (json.loads(letter.body)["vehicle_id"], json.loads(letter.body)["seq"], tries) for letter in letters
    ]


def test_two_workers_on_each_of_two_replicas_deliver_each_event_once_per_subscriber(
    tmp_path, receiver_factory, state, mosquitto
):
    # Four dispatchers on one push state (a SQLite file: workers of one machine; a Redis: replicas too), each
    # with its own connections and its own holder name, push to a webhook and to the broker at once.
    receiver = receiver_factory()
    add_webhook(tmp_path / "webhooks.json", FLEET, receiver.url, allow_private=True)
    seen = Subscriber(mosquitto, f"csws/{FLEET}/+/events")
    outbox, vehicles, count = MemoryOutbox(), [f"truck-{n}" for n in range(10)], 30
    # A receiver slower than the timeout is retried (at least once, by design): here the answer may wait for the
    # loaded machine, so the timeout is long and a second delivery can come only from two dispatchers at once.
    policy = RetryPolicy(max_tries=50, first_delay_s=0.05, max_delay_s=0.2, timeout_s=10.0)
    config = replace(quick_config(tmp_path, state, policy=policy), mqtt_url=mosquitto.url)
    stoppers = [start_push(config, outbox) for _ in range(4)]
    try:
        for seq in range(1, count + 1):  # written while they run
            for vehicle in vehicles:
                outbox.write(FLEET, vehicle, event_body(vehicle, seq))
            time.sleep(0.005)
        wait_until(lambda: len(receiver.requests) >= len(vehicles) * count and len(seen.messages) >= 300)
        time.sleep(0.5)  # time for any second delivery to show
    finally:
        for stop in stoppers:
            stop()
        seen.close()
    expected = sorted(f"{FLEET}:{v}:{s}" for v in vehicles for s in range(1, count + 1))
    assert sorted(request["key"] for request in receiver.requests) == expected
    assert all(numbers == list(range(1, count + 1)) for numbers in in_order_per_vehicle(receiver.requests).values())
    published = [json.loads(payload) for _, payload, _ in seen.messages]
    assert sorted(f"{e['fleet']}:{e['vehicle_id']}:{e['seq']}" for e in published) == expected


def test_a_dispatcher_that_stops_hands_over_and_nothing_is_lost(tmp_path, receiver_factory, state):
    receiver = receiver_factory()
    add_webhook(tmp_path / "webhooks.json", FLEET, receiver.url, allow_private=True)
    outbox, config = MemoryOutbox(), quick_config(tmp_path, state)
    first, second = start_push(config, outbox), start_push(config, outbox)
    write_events(outbox, ["truck-1"], 50)
    wait_until(lambda: len(receiver.requests) >= 50)
    first()  # gives its lease up: the other takes over
    write_events(outbox, ["truck-2"], 50)
    try:
        wait_until(lambda: len({r["key"] for r in receiver.requests}) == 100)
    finally:
        second()


class CountingOutbox(MemoryOutbox):
    """An outbox that counts how often it is read."""

    def __init__(self) -> None:
        super().__init__()
        self.reads = 0

    def events_after(self, fleet: str | None, after: str | None, limit: int) -> list[StoredEvent]:
        self.reads += 1
        return super().events_after(fleet, after, limit)


def test_without_webhooks_the_outbox_is_read_seldom_and_a_webhook_added_gets_what_follows(tmp_path, receiver_factory):
    outbox = CountingOutbox()
    stop = start_push(quick_config(tmp_path), outbox)
    try:
        write_events(outbox, ["truck-0"], 5)
        idle_s = 2.0
        time.sleep(idle_s)
        # At the poll interval (10 ms) that would be some 200 reads: without a webhook, one a second and the drain.
        assert outbox.reads <= idle_s / IDLE_WITHOUT_WEBHOOKS_S + 3
        receiver = receiver_factory()
        add_webhook(tmp_path / "webhooks.json", FLEET, receiver.url, allow_private=True)
        written = iter(range(1, 10_000))

        def one_more_and_arrived() -> bool:
            """Write one more event until the first arrives: a webhook added gets what its fleet writes once the
            dispatcher has read the file again (about a second), and only then."""
            outbox.write(FLEET, "truck-1", event_body("truck-1", next(written)))
            return bool(receiver.requests)

        wait_until(one_more_and_arrived)
        write_events(outbox, ["truck-2"], 5)
        wait_until(lambda: sum(r["key"].startswith(f"{FLEET}:truck-2:") for r in receiver.requests) == 5)
    finally:
        stop()


# --- What a webhook may reach ---------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("url", "reason"),
    [
        ("http://169.254.169.254/latest/meta-data", "metadata"),
        ("http://[fe80::1]/hook", "link-local"),
        ("http://[fd00:ec2::254]/hook", "metadata"),
        ("http://0.0.0.0/hook", "unspecified"),
        ("http://224.0.0.1/hook", "multicast"),
        ("http://255.255.255.255/hook", "broadcast"),
        ("http://[::ffff:169.254.169.254]/hook", "metadata"),
        ("http://127.0.0.1:8080/hook", "loopback or private"),
        ("http://10.1.2.3/hook", "loopback or private"),
        ("ftp://example.com/hook", "http:// or https://"),
        ("file:///etc/passwd", "http:// or https://"),
    ],
)
def test_refused_webhook_urls(tmp_path, url, reason):
    with pytest.raises(UnsafeTarget, match=reason):
        add_webhook(tmp_path / "webhooks.json", FLEET, url, allow_private=False)
    assert not (tmp_path / "webhooks.json").exists()


def test_link_local_is_refused_even_where_private_addresses_are_allowed(tmp_path):
    for url in ("http://169.254.10.10/hook", "http://[fe80::1]/hook"):
        with pytest.raises(UnsafeTarget, match="link-local"):
            add_webhook(tmp_path / "webhooks.json", FLEET, url, allow_private=True)


def test_the_cli_refuses_in_one_line_with_a_non_zero_status(tmp_path, capsys):
    status = csws_main(
        ["webhooks", "add", "--fleet", FLEET, "http://169.254.169.254/", "--file", str(tmp_path / "w.json")]
    )
    error = capsys.readouterr().err
    assert status != 0 and error.count("\n") == 1 and "metadata" in error


def _resolving(monkeypatch: pytest.MonkeyPatch, name: str, address: str) -> None:
    """Make ``name`` resolve to ``address`` (the system's resolver for any other name)."""
    real = socket.getaddrinfo

    def getaddrinfo(host, port, *args, **kwargs):
        if host == name:
            family = socket.AF_INET6 if ":" in address else socket.AF_INET
            return [(family, socket.SOCK_STREAM, 6, "", (address, port))]
        return real(host, port, *args, **kwargs)

    monkeypatch.setattr(socket, "getaddrinfo", getaddrinfo)


def test_a_name_resolving_to_link_local_is_refused(tmp_path, monkeypatch):
    _resolving(monkeypatch, "hooks.example.test", "169.254.169.254")
    with pytest.raises(UnsafeTarget, match="'hooks.example.test' is 169.254.169.254"):
        resolved_addresses("https://hooks.example.test/csws", allow_private=True)


def test_a_name_that_resolves_elsewhere_later_is_refused_at_the_connection(tmp_path, monkeypatch, receiver_factory):
    receiver = receiver_factory()
    _resolving(monkeypatch, "rebinding.example.test", "127.0.0.1")
    url = receiver.url.replace("127.0.0.1", "rebinding.example.test")
    add_webhook(tmp_path / "webhooks.json", FLEET, url, allow_private=True)
    _resolving(monkeypatch, "rebinding.example.test", "169.254.169.254")
    outbox, config = MemoryOutbox(), quick_config(tmp_path)
    outbox.write(FLEET, "truck-1", event_body("truck-1", 1))
    stop = start_push(config, outbox)
    state = PushState(config.state_db)
    try:
        wait_until(
            lambda: any(
                "link-local" in p.error or "metadata" in p.error
                for p in state.due(f"webhook {FLEET} {url}", time.time() + 60, 10)
            )
        )
    finally:
        stop()
        state.close()
    assert receiver.requests == []


@given(st.integers(min_value=0, max_value=2**16 - 1), st.booleans())
def test_every_link_local_address_is_refused_in_either_family(low_bits, allow_private):
    address = ipaddress.IPv4Address((169 << 24) | (254 << 16) | low_bits)
    mapped = ipaddress.IPv6Address(f"::ffff:{address}")
    assert address_refusal(address, allow_private) is not None
    assert address_refusal(mapped, allow_private) == address_refusal(address, allow_private)


@given(st.ip_addresses(v=4), st.booleans())
def test_a_global_address_is_refused_only_when_special(address, allow_private):
    refusal = address_refusal(address, allow_private)
    if address.is_global and not address.is_multicast and str(address) != "100.100.100.200":
        assert refusal is None
    if address.is_private and not (address.is_link_local or address.is_unspecified or address.is_multicast):
        assert (refusal is None) == (allow_private and str(address) != "255.255.255.255")


# --- MQTT -----------------------------------------------------------------------------------------------------------


@pytest.fixture
def mosquitto(tmp_path: Path) -> Iterator[Mosquitto]:
    broker = Mosquitto(tmp_path)
    yield broker
    broker.stop()


def test_mqtt_events_in_order_and_the_state_retained_for_a_late_subscriber(tmp_path, mosquitto):
    events_seen = Subscriber(mosquitto, "csws/+/+/events")
    outbox, vehicles, count = MemoryOutbox(), ["truck-1", "bus#2"], 40
    write_events(outbox, vehicles, count)  # state or level changes at every event
    changed_at = 7  # "steady" goes from level 0 to level 2 at its 7th event and stays there
    for seq in range(1, count + 1):
        outbox.write(FLEET, "steady", event_body("steady", seq, level=2 if seq >= changed_at else 0, state="active"))
    stop = start_push(PushConfig(str(tmp_path / "push.sqlite3"), mqtt_url=mosquitto.url), outbox)
    try:
        wait_until(lambda: len(events_seen.messages) >= 3 * count)
        late = Subscriber(mosquitto, f"csws/{FLEET}/+/state")
        wait_until(lambda: len(late.messages) == 3)
    finally:
        stop()
        events_seen.close()
    topics = [f"csws/{FLEET}/truck-1/events", f"csws/{FLEET}/bus%232/events", f"csws/{FLEET}/steady/events"]
    for topic in topics:
        numbers = [json.loads(payload)["seq"] for seen, payload, _ in events_seen.messages if seen == topic]
        assert numbers == list(range(1, count + 1))
    expected = {
        f"csws/{FLEET}/truck-1/state": (count, count % 3, "active" if count % 3 else "standby"),
        f"csws/{FLEET}/bus%232/state": (count, count % 3, "active" if count % 3 else "standby"),
        f"csws/{FLEET}/steady/state": (changed_at, 2, "active"),
    }
    retained = {topic: json.loads(payload) for topic, payload, is_retained in late.messages if is_retained}
    assert set(retained) == set(expected)
    for topic, state in retained.items():
        assert set(state) == {"state", "level", "time", "seq"}
        assert (state["seq"], state["level"], state["state"]) == expected[topic]
    late.close()


def test_mqtt_events_written_while_the_broker_is_down_arrive_after_it_is_back(tmp_path, mosquitto):
    outbox = MemoryOutbox()
    stop = start_push(PushConfig(str(tmp_path / "push.sqlite3"), mqtt_url=mosquitto.url), outbox)
    try:
        write_events(outbox, ["truck-1"], 5)
        state = PushState(tmp_path / "push.sqlite3")
        wait_until(lambda: state.cursor("mqtt") == f"{5:020d}")
        mosquitto.stop()
        write_events(outbox, ["truck-2"], 5)
        time.sleep(0.5)
        assert state.cursor("mqtt") == f"{5:020d}"  # nothing acknowledged, nothing passed
        mosquitto.start()
        seen = Subscriber(mosquitto, "csws/+/truck-2/events")
        wait_until(lambda: {json.loads(p)["seq"] for _, p, _ in seen.messages} == {1, 2, 3, 4, 5}, 60.0)
        wait_until(lambda: state.cursor("mqtt") == f"{10:020d}")
        state.close()
        seen.close()
    finally:
        stop()


# --- In the service -------------------------------------------------------------------------------------------------


def test_the_service_pushes_from_its_store_and_counts_in_its_metrics(tmp_path, receiver_factory):
    receiver = receiver_factory()
    keys_file = tmp_path / "api-keys.json"
    add_webhook(keys_file.with_name("webhooks.json"), FLEET, receiver.url, allow_private=True)
    settings = ServiceSettings(
        api_keys_file=keys_file, state_db=str(tmp_path / "vehicles.sqlite3"), webhook_allow_private=True
    )
    assert push_config(settings).webhooks_file == tmp_path / "webhooks.json"
    assert push_config(settings).state_db == str(tmp_path / "push.sqlite3")
    outbox, metrics = MemoryOutbox(), Metrics()
    write_events(outbox, ["truck-1"], 7)
    stop = start_service_push(settings, outbox, metrics)
    try:
        wait_until(lambda: len(receiver.requests) == 7)
    finally:
        stop()
    assert 'csws_push_events_total{sink="webhook",outcome="delivered"} 7' in metrics.lines()


def test_a_broker_url_must_be_mqtt():
    with pytest.raises(ValueError, match="mqtt://HOST:PORT"):
        ServiceSettings(mqtt="http://127.0.0.1:1883")
    assert ServiceSettings(mqtt=" mqtt://127.0.0.1:1883 ").mqtt == "mqtt://127.0.0.1:1883"


def test_a_lease_not_renewed_goes_to_another_dispatcher_only_once_it_expired(tmp_path, state):
    store = open_push_state((state or {}).get("state") or str(tmp_path / "push.sqlite3"))
    duration_s = 0.5
    first, second = Lease(store, "webhooks", duration_s), Lease(store, "webhooks", duration_s)
    try:
        assert first.hold() and not second.hold()
        time.sleep(duration_s / 2)
        assert first.hold() and not second.hold()  # renewed: still the first's
        time.sleep(duration_s * 1.5)  # the first stopped renewing, as a dead worker does
        assert second.hold()
        with pytest.raises(LeaseLost):
            first.keep()
        second.release()
        assert first.hold()  # given up: free at once
    finally:
        store.close()
