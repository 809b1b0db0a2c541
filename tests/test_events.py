"""Warning events (docs/events.md): told from the answers, written to the outbox with the sessions, streamed and kept.

The truth is the answers themselves: each test drives vehicles with real requests to a real service on
loopback (SQLite and a real Redis), derives from the sequence of answers it got which events must exist
(a level or a state that changed), and compares with what the outbox, the stream and the history hold;
warning speeds with the standard's V_w at the truth's radius of the curve.
"""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path

import httpx
import numpy as np
import pytest
from browsers import WAIT_MS, Recorded
from builders import TRACK, write_geo_track
from hypothesis import given
from hypothesis import strategies as st
from markers import marks_its_tests
from servers import Server, Workers

from csws.networks import networks_dir
from csws.standard import Category, Level, warning_speed
from service.events import (
    CURVE_LEVEL,
    CURVE_ONSET,
    CURVE_RELEASE,
    STATE,
    EventTrail,
    Observed,
    answer_events,
)
from service.store import NewEvent, VehicleWrite
from service.store.redis import RedisStore
from service.store.sqlite import SWEEP_PERIOD_S, SQLiteStore

TRUTH = json.loads((networks_dir() / f"{TRACK}.truth.json").read_text())
ROUTE = TRUTH["route"]["edges"]
#: The speed of the drives, km/h: above category N's level-2 warning speed of the track's first curve.
SPEED_KMH = 75.0


def _route_lane(route_s: float) -> tuple[str, float]:
    """Lane and lane position of a route arc length, from the truth's lane table."""
    lane = next(lane for lane in reversed(TRUTH["lanes"]) if lane["start_s"] <= route_s)
    return lane["lane"], route_s - lane["start_s"]


def _query(vehicle_id: str, route_s: float, timestamp_s: float, speed_kmh: float = SPEED_KMH) -> dict:
    lane_id, lane_pos_m = _route_lane(route_s)
    return {
        "vehicle_id": vehicle_id,
        "category": "N",
        "speed_kmh": speed_kmh,
        "lane_id": lane_id,
        "lane_pos_m": lane_pos_m,
        "route": ROUTE,
        "timestamp_s": timestamp_s,
    }


def _expected_kinds(answers: list[dict]) -> list[tuple[str, int, str, float]]:
    """The events a sequence of answers of one vehicle must have made (kind, level, state, time): a state that
    changed (from standby, a new vehicle's), then a curve warning's level that changed (from 0)."""
    expected, level, state = [], 0, "standby"
    for answer, time_s in answers:
        if answer["state"] != state:
            expected.append((STATE, answer["level"], answer["state"], time_s))
        if answer["level"] != level:
            kind = CURVE_ONSET if level == 0 else CURVE_RELEASE if answer["level"] == 0 else CURVE_LEVEL
            expected.append((kind, answer["level"], answer["state"], time_s))
        level, state = answer["level"], answer["state"]
    return expected


def _drive(client: httpx.Client, vehicle_id: str, first_s: float = 700.0, last_s: float = 1470.0) -> list:
    """Drive a vehicle through the track's first curve at :data:`SPEED_KMH`, 10 m per query (timestamps as at
    that speed); each answer with its timestamp."""
    answers = []
    step_s = 10.0 / (SPEED_KMH / 3.6)
    for k, route_s in enumerate(np.arange(first_s, last_s, 10.0)):
        query = _query(vehicle_id, float(route_s), 1000.0 + k * step_s)
        response = client.post("/v1/warning", json=query)
        assert response.status_code == 200, response.text
        answers.append((response.json(), query["timestamp_s"]))
    return answers


def _history(client: httpx.Client, vehicle_id: str, since: float = 0.0, limit: int = 1000) -> list[dict]:
    response = client.get(f"/v1/vehicles/{vehicle_id}/events", params={"since": since, "limit": limit})
    assert response.status_code == 200, response.text
    assert response.json()["vehicle_id"] == vehicle_id
    return response.json()["events"]


def _stream(
    client: httpx.Client, wait_s: float = 0.3, arrivals: list | None = None, **options
) -> list[tuple[str, dict]]:
    """The events ``GET /v1/events`` sends within ``wait_s`` (then it ends): (id, event) each; when each arrived
    (``time.monotonic``) into ``arrivals``."""
    headers = options.pop("headers", {})
    received, cursor = [], None
    with client.stream("GET", "/v1/events", params={"wait_s": wait_s, **options}, headers=headers) as response:
        assert response.status_code == 200
        assert response.headers["content-type"].startswith("text/event-stream")
        for line in response.iter_lines():
            if line.startswith("id: "):
                cursor = line[4:]
            elif line.startswith("data: "):
                received.append((cursor, json.loads(line[6:])))
                if arrivals is not None:
                    arrivals.append(time.monotonic())
    return received


@pytest.fixture(scope="module")
def geo_net(tmp_path_factory) -> Path:
    return write_geo_track(tmp_path_factory.mktemp("served"))


@pytest.fixture(scope="module")
@marks_its_tests("slow")
def server(geo_net, tmp_path_factory):
    running = Server([geo_net], tmp_path_factory.mktemp("state") / "vehicles.sqlite3")
    yield running
    running.stop()


# ------------------------------------------------------------------ the events of a drive
def test_a_drive_through_a_curve_makes_onset_level_and_release_numbered_from_one(server) -> None:
    client = server.client
    answers = _drive(client, "drive-1")
    events = _history(client, "drive-1")
    expected = _expected_kinds(answers)
    assert [(e["kind"], e["level"], e["state"], e["time"]) for e in events] == expected
    assert [e["seq"] for e in events] == list(range(1, len(events) + 1))
    kinds = [e["kind"] for e in events]
    assert kinds.index(CURVE_ONSET) < kinds.index(CURVE_LEVEL) < kinds.index(CURVE_RELEASE)
    by_time = {time_s: answer for answer, time_s in answers}
    curve = TRUTH["curves"][0]
    for event in events:
        answer = by_time[event["time"]]
        assert (event["fleet"], event["vehicle_id"], event["network"]) == ("", "drive-1", answer["matched"]["network"])
        matched = answer["matched"]["position"]
        assert event["position"] == {"x": matched["x"], "y": matched["y"], "lon": matched["lon"], "lat": matched["lat"]}
        if event["level"] == 0:
            assert event["curve_id"] is None and event["v_w_kmh"] is None
            continue
        target = answer["target"]
        assert (event["curve_id"], event["v_w_kmh"], event["s_w_m"]) == (
            target["curve_id"],
            target["warning_speed_kmh"],
            target["warning_distance_m"],
        )
        if target["radius_m"] == pytest.approx(curve["radius_m"], rel=0.01):
            level = Level.LEVEL_1 if target["level"] == 1 else Level.LEVEL_2
            assert event["v_w_kmh"] == pytest.approx(warning_speed(target["radius_m"], Category.N, level), rel=1e-9)


def test_the_stream_sends_each_event_once_and_resumes_after_its_cursor(server) -> None:
    client = server.client
    _drive(client, "stream-1")
    history = _history(client, "stream-1")
    streamed = [(cursor, e) for cursor, e in _stream(client) if e["vehicle_id"] == "stream-1"]
    assert [e for _, e in streamed] == history
    middle = len(streamed) // 2
    resumed = _stream(client, headers={"Last-Event-ID": streamed[middle][0]}, after="0")
    assert [e for _, e in resumed if e["vehicle_id"] == "stream-1"] == history[middle + 1 :]
    assert client.get("/v1/events", params={"after": "1-0", "wait_s": 0}).status_code == 422  # Redis's, not SQLite's
    assert client.get("/v1/events", params={"after": "x", "wait_s": 0}).status_code == 422
    assert [e for _, e in _stream(client, after=streamed[-1][0])] == [
        e for _, e in _stream(client) if (e["vehicle_id"], e["seq"]) > ("stream-1", len(history))
    ]


def test_an_event_reaches_an_open_stream_within_the_poll(server) -> None:
    client = server.client
    last = _stream(client)[-1][0]
    received: list[tuple[str, dict]] = []
    arrivals: list[float] = []

    def listen() -> None:
        with httpx.Client(base_url=server.url, timeout=10.0) as listener:
            received.extend(_stream(listener, wait_s=2.0, arrivals=arrivals, after=last))

    thread = threading.Thread(target=listen)
    thread.start()
    time.sleep(0.5)
    sent_s = time.monotonic()
    client.post("/v1/warning", json=_query("live-1", 700.0, 5.0))
    thread.join()
    assert [e["vehicle_id"] for _, e in received] == ["live-1"]
    assert arrivals[0] - sent_s < 0.5  # the poll is 20 ms; the loaded machine gets the rest


def test_history_since_a_time_keeps_the_later_events_in_order(server) -> None:
    client = server.client
    _drive(client, "since-1")
    events = _history(client, "since-1")
    since = events[len(events) // 2]["time"]
    assert _history(client, "since-1", since=since) == [e for e in events if e["time"] >= since]
    assert _history(client, "since-1", limit=2) == events[:2]
    assert _history(client, "never-seen") == []


def test_concurrent_requests_of_one_vehicle_number_its_events_without_gaps_or_doubles(server) -> None:
    """Two clients send fixes of one vehicle at once, alternating a fix in the curve (level 2) and one far
    before it (level 0): requests conflict; the events must still be 1..n, each a change from the one before."""
    errors = []

    def send(offset: int) -> None:
        with httpx.Client(base_url=server.url, timeout=30.0) as own:
            for k in range(30):
                route_s = TRUTH["curves"][0]["start_s"] - 20.0 if (k + offset) % 2 else 200.0
                answer = own.post("/v1/warning", json=_query("busy-1", route_s, 0.0, speed_kmh=90.0))
                if answer.status_code != 200:
                    errors.append(answer.text)

    threads = [threading.Thread(target=send, args=(offset,)) for offset in (0, 1)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert not errors
    events = _history(server.client, "busy-1")
    assert [e["seq"] for e in sorted(events, key=lambda e: e["seq"])] == list(range(1, len(events) + 1))
    level = 0
    for event in sorted(events, key=lambda e: e["seq"]):
        if event["kind"] in (CURVE_ONSET, CURVE_LEVEL, CURVE_RELEASE):
            assert event["level"] != level
            assert (event["kind"] == CURVE_ONSET) == (level == 0)
            assert (event["kind"] == CURVE_RELEASE) == (event["level"] == 0)
            level = event["level"]
    assert len([e for e in events if e["kind"] == CURVE_ONSET]) >= 1


def test_a_switch_makes_a_state_event(server) -> None:
    client = server.client
    client.post("/v1/warning", json=_query("switched-1", 700.0, 10.0))
    assert client.put("/v1/vehicles/switched-1", json={"switched_on": False}).status_code == 200
    events = _history(client, "switched-1")
    assert [(e["kind"], e["state"]) for e in events] == [(STATE, "active"), (STATE, "off")]


def test_a_traccar_position_makes_events_like_any_query(server) -> None:
    answer = server.client.post("/v1/warning", json=_query("probe", 700.0, 1.0)).json()
    x, y = answer["matched"]["position"]["lon"], answer["matched"]["position"]["lat"]
    forward = {
        "position": {"latitude": y, "longitude": x, "speed": 30.0, "course": 90.0, "fixTime": "2026-11-26T02:00:00Z"},
        "device": {"uniqueId": "traccar-1", "category": "truck"},
    }
    served = server.client.post("/v1/traccar", json=forward)
    assert served.status_code == 200, served.text
    events = _history(server.client, "traccar-1")
    assert [(e["kind"], e["state"], e["seq"]) for e in events] == [(STATE, served.json()["state"], 1)]
    assert events[0]["time"] == 1795658400.0  # 2026-11-26T02:00:00Z


def test_the_live_map_lists_a_new_warning_from_the_stream(browser, server) -> None:
    recorded = Recorded(browser)
    page = recorded.page
    page.goto(f"{server.url}/map")
    page.wait_for_function("() => document.body.dataset.ready === 'true'", timeout=WAIT_MS)
    time.sleep(1.0)  # the page caught up with the events before it
    answer = server.client.post("/v1/warning", json=_query("mapped-1", TRUTH["curves"][0]["start_s"] - 20.0, 7.0))
    target = answer.json()["target"]
    page.wait_for_function("() => document.body.dataset.recentWarnings === '1'", timeout=WAIT_MS)
    listed = page.inner_text("#recent")
    assert "mapped-1" in listed and "curve_onset" in listed and f"level {target['level']}" in listed
    assert f"V_w {target['warning_speed_kmh']:.0f} km/h" in listed
    recorded.assert_offline()
    page.close()


# ------------------------------------------------------------------ durability
def test_a_service_killed_after_an_acknowledged_warning_keeps_its_events(geo_net, tmp_path) -> None:
    database = tmp_path / "vehicles.sqlite3"
    running = Server([geo_net], database)
    try:
        answers = _drive(running.client, "killed-1", last_s=TRUTH["curves"][0]["start_s"])
        assert any(answer["level"] > 0 for answer, _ in answers)
    finally:
        running.process.kill()  # SIGKILL: nothing gets the chance to finish
        running.process.wait(timeout=10)
        running.client.close()
    restarted = Server([geo_net], database)
    try:
        streamed = [e for _, e in _stream(restarted.client) if e["vehicle_id"] == "killed-1"]
        assert [(e["kind"], e["level"], e["state"], e["time"]) for e in streamed] == _expected_kinds(answers)
    finally:
        restarted.stop()


def test_two_replicas_of_two_workers_on_one_redis_stream_each_event_once(geo_net, redis_url) -> None:
    replicas = [Workers([geo_net], f"--state={redis_url}") for _ in range(2)]
    try:
        received: list[tuple[str, dict]] = []
        driven = threading.Event()

        def follow() -> None:
            """Streams one after the other, each resumed after the last event's id (Last-Event-ID), on new
            connections (any worker of the replica), until one ends after the drives."""
            while True:
                last_round = driven.is_set()
                headers = {"Last-Event-ID": received[-1][0]} if received else {}
                with httpx.Client(base_url=replicas[0].url, timeout=30.0) as listener:
                    received.extend(_stream(listener, wait_s=1.0, headers=headers))
                if last_round:
                    return

        listener = threading.Thread(target=follow)
        listener.start()
        vehicles = []
        for number, replica in enumerate(replicas):  # each replica, each of its two workers, drives one vehicle
            for k, client in enumerate(replica.clients()):
                vehicles.append(f"r{number}-{k}")
                _drive(client, vehicles[-1])
        driven.set()
        listener.join()
        with httpx.Client(base_url=replicas[1].url, timeout=30.0) as reader:
            history = [event for vehicle_id in vehicles for event in _history(reader, vehicle_id)]
        assert history
        assert sorted((e["vehicle_id"], e["seq"]) for _, e in received) == sorted(
            (e["vehicle_id"], e["seq"]) for e in history
        )
        assert len({cursor for cursor, _ in received}) == len(received)
        assert [cursor for cursor, _ in received] == sorted(
            (cursor for cursor, _ in received), key=lambda c: tuple(map(int, c.split("-")))
        )
    finally:
        for replica in replicas:
            replica.stop()


# ------------------------------------------------------------------ the outbox in each store
def _event_write(version: int, fleet: str, seq: int, time_s: float) -> VehicleWrite:
    body = json.dumps({"fleet": fleet, "seq": seq, "time": time_s}).encode()
    return VehicleWrite(version, b"session", events=(NewEvent(fleet, seq, time_s, body),))


@pytest.fixture(params=["sqlite", "redis"])
def outbox(request, tmp_path):
    """The kind of a store, and how to open one of that kind on its clock with a retention time (closed after)."""
    opened = []

    def open_store(clock, retention_s: float):
        if request.param == "sqlite":
            store = SQLiteStore(tmp_path / "vehicles.sqlite3", 600.0, clock, retention_s)
        else:
            store = RedisStore(request.getfixturevalue("redis_url"), 600.0, retention_s)
        opened.append(store)
        return store

    yield request.param, open_store
    for store in opened:
        store.close()


def test_a_write_refused_for_a_conflict_writes_no_event_and_fleets_are_apart(outbox) -> None:
    store = outbox[1](time.time, 3600.0)
    assert store.write({"a/v": _event_write(0, "a", 1, 10.0)}) == set()
    assert store.write({"a/v": _event_write(0, "a", 2, 11.0), "b/w": _event_write(0, "b", 1, 12.0)}) == {"a/v"}
    assert store.read(["a/v", "b/w", "c/x"])["a/v"].event_seq == 1
    assert [e.vehicle_key for e in store.events_after(None, None, 10)] == ["a/v", "b/w"]
    assert [json.loads(e.body)["seq"] for e in store.events_after("a", None, 10)] == [1]
    first = store.events_after(None, None, 1)
    assert [e.vehicle_key for e in store.events_after(None, first[0].cursor, 10)] == ["b/w"]
    assert store.events_after("c", None, 10) == []
    with pytest.raises(ValueError):
        store.events_after(None, "not-a-cursor", 10)


def test_the_outbox_forgets_events_past_the_retention(outbox) -> None:
    store_kind, open_store = outbox
    now = [time.time()]
    retention_s = SWEEP_PERIOD_S + 1.0 if store_kind == "sqlite" else 1.0
    store = open_store(lambda: now[0], retention_s)
    store.write({"a/old": _event_write(0, "a", 1, now[0])})
    assert len(store.vehicle_events("a/old", 0.0, 10)) == 1
    if store_kind == "sqlite":
        now[0] += retention_s + 1.0  # the store's clock: the sweep is due, the event past its retention
    else:
        time.sleep(retention_s + 0.2)
    store.write({"a/new": _event_write(0, "a", 1, time.time() if store_kind == "redis" else now[0])})
    assert [e.vehicle_key for e in store.events_after("a", None, 10)] == ["a/new"]
    assert store.vehicle_events("a/old", 0.0, 10) == []


# ------------------------------------------------------------------ the derivation
@given(st.lists(st.tuples(st.sampled_from([0, 1, 2]), st.sampled_from(["standby", "active", "fault"])), max_size=30))
def test_the_events_of_a_sequence_of_answers_retell_its_levels_and_states(answers) -> None:
    trail, level, state = EventTrail(), 0, "standby"
    for k, (new_level, new_state) in enumerate(answers):
        trail, events = answer_events("fleet/v", trail, Observed(float(k), new_level, new_state))
        for event in events:
            assert (event.fleet, event.vehicle_id, event.time) == ("fleet", "v", float(k))
            assert (event.level, event.state) == (new_level, new_state)
        kinds = [event.kind for event in events]
        assert (STATE in kinds) == (new_state != state)
        curve = [kind for kind in kinds if kind != STATE]
        if new_level == level:
            assert curve == []
        else:
            assert curve == [CURVE_ONSET if level == 0 else CURVE_RELEASE if new_level == 0 else CURVE_LEVEL]
        level, state = new_level, new_state
        assert (trail.level, trail.state) == (level, state)
