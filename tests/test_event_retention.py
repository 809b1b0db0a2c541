"""Per-fleet retention of warning events (docs/events.md, "Retention"): each fleet's events kept for its own time.

Two fleets with different windows write events into each store; the truth is the windows themselves: an event
written more than its fleet's window ago must be gone from the fleet's stream, the stream of every fleet and the
vehicle's history (left out by the reads at once, and deleted by the store's trim), while the other fleet's events,
still within their window, are all kept. SQLite runs on a clock the test moves; Redis dates events by its own clock
(``TIME``), so its windows are short and the test waits them out.
"""

from __future__ import annotations

import json
import sqlite3
import time

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pydantic import ValidationError

from service.settings import ServiceSettings
from service.store import MAX_SESSION_IDLE_S, EventRetention, NewEvent, VehicleWrite, open_store
from service.store.redis import HISTORY_PREFIX, OUTBOX_KEY, RedisStore
from service.store.sqlite import SWEEP_PERIOD_S, SQLiteStore

#: The service's window and the short fleet's, s (SQLite, on the test's clock).
DEFAULT_S, SHORT_S = 10 * SWEEP_PERIOD_S, 2 * SWEEP_PERIOD_S


def _write(store, vehicle_key: str, version: int, seq: int, time_s: float) -> None:
    """One event of the vehicle kept as ``vehicle_key`` (its fleet the key's), written with its session."""
    fleet = vehicle_key.partition("/")[0]
    body = json.dumps({"fleet": fleet, "vehicle": vehicle_key, "seq": seq}).encode()
    write = VehicleWrite(version, b"session", events=(NewEvent(fleet, seq, time_s, body),))
    assert store.write({vehicle_key: write}) == set()


def _seen(store) -> dict[str, set[str]]:
    """Which vehicles' events each read returns: each fleet's stream, every fleet's, and the histories."""
    keys = ("short/old", "long/old", "short/new")
    return {
        "short": {e.vehicle_key for e in store.events_after("short", None, 100)},
        "long": {e.vehicle_key for e in store.events_after("long", None, 100)},
        "all": {e.vehicle_key for e in store.events_after(None, None, 100)},
        "history": {k for k in keys if store.vehicle_events(k, 0.0, 100)},
    }


def _rows(path) -> set[str]:
    """The vehicles whose events the SQLite file holds (what the trim left)."""
    with sqlite3.connect(path) as db:
        return {key for (key,) in db.execute("SELECT vehicle_id FROM vehicle_events")}


def test_sqlite_keeps_each_fleets_events_for_its_own_window(tmp_path) -> None:
    now = [1.8e9]
    path = tmp_path / "vehicles.sqlite3"
    store = SQLiteStore(path, 600.0, lambda: now[0], DEFAULT_S, {"short": SHORT_S})
    try:
        _write(store, "short/old", 0, 1, now[0])
        _write(store, "long/old", 0, 1, now[0])
        both = {"short": {"short/old"}, "long": {"long/old"}, "all": {"short/old", "long/old"}}
        assert _seen(store) == {**both, "history": {"short/old", "long/old"}}
        now[0] += SHORT_S  # the short window's last instant: still kept
        assert _seen(store) == {**both, "history": {"short/old", "long/old"}}
        now[0] += 1.0  # past the short window, within the service's: the reads leave it out before any trim
        gone = {"short": set(), "long": {"long/old"}, "all": {"long/old"}, "history": {"long/old"}}
        assert _seen(store) == gone
        _write(store, "short/new", 0, 1, now[0])  # a write after the sweep period trims
        trimmed = {"short": {"short/new"}, "long": {"long/old"}, "all": {"long/old", "short/new"}}
        assert _seen(store) == {**trimmed, "history": {"long/old", "short/new"}}
        assert _rows(path) == {"long/old", "short/new"}
        now[0] += DEFAULT_S - SHORT_S - 1.0  # the long fleet's first event at its window's last instant
        _write(store, "long/new", 0, 1, now[0])
        assert _rows(path) == {"long/old", "long/new"}  # the short fleet's newer event already past its window
        now[0] += SWEEP_PERIOD_S
        _write(store, "long/last", 0, 1, now[0])
        assert _rows(path) == {"long/new", "long/last"}
    finally:
        store.close()


def test_redis_keeps_each_fleets_events_for_its_own_window(redis_url) -> None:
    short_s, default_s = 0.6, 30.0
    store = RedisStore(redis_url, 600.0, default_s, {"short": short_s})
    try:
        _write(store, "short/old", 0, 1, time.time())
        _write(store, "long/old", 0, 1, time.time())
        kept = {"short": {"short/old"}, "long": {"long/old"}, "all": {"short/old", "long/old"}}
        assert _seen(store) == {**kept, "history": {"short/old", "long/old"}}
        time.sleep(short_s + 0.2)
        gone = {"short": set(), "long": {"long/old"}, "all": {"long/old"}, "history": {"long/old"}}
        assert _seen(store) == gone  # left out by the reads before any trim
        _write(store, "short/new", 0, 1, time.time())  # the write trims
        trimmed = {"short": {"short/new"}, "long": {"long/old"}, "all": {"long/old", "short/new"}}
        assert _seen(store) == {**trimmed, "history": {"long/old", "short/new"}}
        raw = store._redis
        assert raw.xlen(f"{OUTBOX_KEY}:short") == 1  # the fleet's stream trimmed to its window
        assert raw.xlen(OUTBOX_KEY) == 3  # every fleet's stream to the longest: the old short event still there
        assert raw.exists(HISTORY_PREFIX + "short/old") == 0  # the history past its fleet's window deleted
        assert raw.zcard(HISTORY_PREFIX + "long/old") == 1
    finally:
        store.close()


def test_the_stream_of_every_fleet_reads_past_a_page_of_expired_events(redis_url) -> None:
    store = RedisStore(redis_url, 600.0, 30.0, {"short": 0.3})
    try:
        for seq in range(1, 6):
            _write(store, "short/v", seq - 1, seq, time.time())
        _write(store, "long/v", 0, 1, time.time())
        time.sleep(0.5)
        assert [e.vehicle_key for e in store.events_after(None, None, 2)] == ["long/v"]
    finally:
        store.close()


@given(
    st.floats(1.0, MAX_SESSION_IDLE_S),
    st.dictionaries(st.sampled_from(["a", "b", "c.d"]), st.floats(1.0, MAX_SESSION_IDLE_S)),
    st.sampled_from(["a", "b", "c.d", "e", ""]),
)
def test_a_fleets_own_window_overrides_the_services(default_s, fleets_s, fleet) -> None:
    retention = EventRetention(default_s, fleets_s)
    assert retention.of(fleet) == fleets_s.get(fleet, default_s)
    assert retention.of_key(f"{fleet}/truck/7" if fleet else "truck") == retention.of(fleet)
    assert retention.longest_s == max([default_s, *fleets_s.values()])


def test_the_setting_reads_a_json_object_of_fleets(monkeypatch) -> None:
    monkeypatch.setenv("CSWS_EVENT_RETENTION_BY_FLEET", '{"acme": 86400, "beta": 3600.5}')
    assert ServiceSettings().event_retention_by_fleet == {"acme": 86400.0, "beta": 3600.5}
    for bad in ('{"acme": 0}', '{"acme/x": 60}', f'{{"acme": {MAX_SESSION_IDLE_S + 1}}}'):
        monkeypatch.setenv("CSWS_EVENT_RETENTION_BY_FLEET", bad)
        with pytest.raises(ValidationError):
            ServiceSettings()


def test_the_service_opens_its_store_with_the_fleets_windows(tmp_path, redis_url) -> None:
    fleets_s = {"acme": 86400.0, "trial": 3600.0}
    for where in ({"state_db": str(tmp_path / "vehicles.sqlite3")}, {"state": redis_url}):
        store = open_store(ServiceSettings(**where, event_retention_s=604800.0, event_retention_by_fleet=fleets_s))
        try:
            assert [store.event_retention.of(f) for f in ("acme", "trial", "other")] == [86400.0, 3600.0, 604800.0]
        finally:
            store.close()
