"""Push through a running service: a real ``csws`` service on loopback, with an API key's fleet, its webhook and a
real ``mosquitto``, driven through a curve of a constructed track. The truth is the service's own answers: each
level and state they show changing must reach the webhook (signed, in order, once) and the broker, and the state
retained on the broker must be the last answer's.
"""

from __future__ import annotations

import json
from collections.abc import Iterator

import numpy as np
import pytest
from builders import TRACK, write_geo_track
from markers import marks_its_tests
from push_receivers import Mosquitto, Receiver, Subscriber, signature_holds, wait_until
from servers import Server

from csws.networks import networks_dir
from service.keys import Role, add_key
from service.push.targets import add_webhook

FLEET = "acme"
TRUTH = json.loads((networks_dir() / f"{TRACK}.truth.json").read_text())
#: Above category N's level-2 warning speed of the track's first curve, km/h.
SPEED_KMH = 75.0


@pytest.fixture(scope="module")
def broker(tmp_path_factory) -> Iterator[Mosquitto]:
    running = Mosquitto(tmp_path_factory.mktemp("broker"))
    yield running
    running.stop()


@pytest.fixture(scope="module")
def receiver() -> Iterator[Receiver]:
    running = Receiver()
    yield running
    running.stop()


@pytest.fixture(scope="module")
@marks_its_tests("slow")
def pushing(tmp_path_factory, broker, receiver) -> Iterator[tuple[Server, str, str]]:
    """A service with one fleet key, the fleet's webhook at the receiver and the broker; (server, key, secret)."""
    folder = tmp_path_factory.mktemp("service")
    keys = folder / "api-keys.json"
    key = add_key(keys, FLEET, Role.QUERY)
    secret = add_webhook(folder / "webhooks.json", FLEET, receiver.url, allow_private=True)
    assert secret is not None
    running = Server(
        [write_geo_track(folder)],
        folder / "vehicles.sqlite3",
        api_keys_file=str(keys),
        webhooks_file=str(folder / "webhooks.json"),
        webhook_allow_private="1",
        mqtt=broker.url,
    )
    yield running, key, secret
    running.stop()


def _drive(server: Server, key: str, vehicle_id: str) -> list[dict]:
    """A drive through the track's first curve, 10 m per query; the answers."""
    route = TRUTH["route"]["edges"]
    answers = []
    for k, route_s in enumerate(np.arange(700.0, 1470.0, 10.0)):
        lane = next(lane for lane in reversed(TRUTH["lanes"]) if lane["start_s"] <= route_s)
        query = {
            "vehicle_id": vehicle_id,
            "category": "N",
            "speed_kmh": SPEED_KMH,
            "lane_id": lane["lane"],
            "lane_pos_m": float(route_s) - lane["start_s"],
            "route": route,
            "timestamp_s": 1000.0 + k * 10.0 / (SPEED_KMH / 3.6),
        }
        response = server.client.post("/v1/warning", json=query, headers={"Authorization": f"Bearer {key}"})
        assert response.status_code == 200, response.text
        answers.append(response.json())
    return answers


def _changes(answers: list[dict]) -> list[tuple[int, str]]:
    """(level, state) after each answer that changed either, from a new vehicle's (0, standby)."""
    changes, last = [], (0, "standby")
    for answer in answers:
        now = (answer["level"], answer["state"])
        if now != last:
            changes.append(now)
        last = now
    return changes


def test_a_warned_drive_reaches_the_fleets_webhook_and_broker_with_the_state_retained(pushing, receiver, broker):
    server, key, secret = pushing
    events_topic, state_topic = f"csws/{FLEET}/truck-1/events", f"csws/{FLEET}/truck-1/state"
    live = Subscriber(broker, events_topic)
    try:
        answers = _drive(server, key, "truck-1")
        changes = _changes(answers)
        assert any(level == 2 for level, _ in changes)  # the drive is warned at level 2
        wait_until(lambda: len(receiver.accepted()) >= len(changes) and len(live.messages) >= len(changes))
    finally:
        live.close()
    posted = [json.loads(request["body"]) for request in receiver.accepted()]
    assert all(signature_holds(secret, request) for request in receiver.accepted())
    assert [event["seq"] for event in posted] == list(range(1, len(posted) + 1))
    assert [request["key"] for request in receiver.accepted()] == [f"{FLEET}:truck-1:{e['seq']}" for e in posted]
    assert [(event["level"], event["state"]) for event in posted] == changes
    assert {event["fleet"] for event in posted} == {FLEET}
    assert [json.loads(payload) for _, payload, _ in live.messages] == posted
    late = Subscriber(broker, state_topic)
    try:
        wait_until(lambda: bool(late.messages))
    finally:
        late.close()
    (_, payload, retained), *_ = late.messages
    state = json.loads(payload)
    assert retained and (state["level"], state["state"]) == (answers[-1]["level"], answers[-1]["state"])
    assert state["seq"] == posted[-1]["seq"]
