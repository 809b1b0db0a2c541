"""Vehicle sessions and settings in-process: expiry on an injected clock, the SQLite state store, lon/lat refusal.

The clock is a counter the test advances, so nothing depends on wall-clock time.
"""

from __future__ import annotations

import json
import os

import pytest
from fastapi.testclient import TestClient

from csws.networks import networks_dir
from service.app import create_app
from service.settings import ServiceSettings
from service.store import StoredVehicle, VehicleSetting, VehicleWrite
from service.store.sqlite import SQLiteStore

TRACK_NET = networks_dir() / "t7_left.net.xml"
IDLE_S = 60.0


class Clock:
    """Monotonic seconds that move only when told."""

    def __init__(self) -> None:
        self.now_s = 0.0

    def __call__(self) -> float:
        return self.now_s


@pytest.fixture
def clock() -> Clock:
    return Clock()


@pytest.fixture
def app(tmp_path, clock):
    settings = ServiceSettings(nets=[TRACK_NET], state_db=str(tmp_path / "vehicles.sqlite3"), session_idle_s=IDLE_S)
    return create_app(settings, clock=clock)


def _query(vehicle_id: str, **extra) -> dict:
    return {
        "vehicle_id": vehicle_id,
        "category": "N",
        "speed_kmh": 60.0,
        "lane_id": "approach_0",
        "lane_pos_m": 500.0,
        **extra,
    }


def test_idle_sessions_expire_and_the_engines_hold_no_vehicle_between_requests(app, clock) -> None:
    engine = app.state.service.networks[0].engine
    with TestClient(app) as client:
        client.post("/v1/warning", json=_query("idle", timestamp_s=100.0))
        clock.now_s = IDLE_S - 1.0
        client.post("/v1/warning", json=_query("busy"))
        assert client.get("/readyz").json()["vehicle_sessions"] == 2
        assert engine.statuses == {} and engine.held == {}
        clock.now_s = IDLE_S + 1.0
        assert client.get("/v1/vehicles/idle").status_code == 404
        assert client.get("/readyz").json()["vehicle_sessions"] == 1
        # A new session starts afresh: the old timestamp no longer makes an older fix stale.
        assert client.post("/v1/warning", json=_query("idle", timestamp_s=50.0)).json()["state"] == "active"


def test_a_stored_switch_outlives_the_session(app, clock) -> None:
    with TestClient(app) as client:
        client.put("/v1/vehicles/parked", json={"switched_on": False})
        clock.now_s = 10 * IDLE_S
        assert client.get("/v1/vehicles/parked").json()["switched_on"] is False
        assert client.post("/v1/warning", json=_query("parked")).json()["state"] == "off"


def test_the_sqlite_store_keeps_settings_and_writes_a_session_only_over_the_version_it_read(tmp_path, clock) -> None:
    path = tmp_path / "nested" / "vehicles.sqlite3"
    store = SQLiteStore(path, IDLE_S, clock)
    assert (
        store.write({"a": VehicleWrite(0, b"first", VehicleSetting(False, None)), "b": VehicleWrite(0, b"b")}) == set()
    )
    # A writer that read "a" before the first write finds its version moved: nothing of "a" is written.
    assert store.write({"a": VehicleWrite(0, b"late", VehicleSetting(True, None))}) == {"a"}
    assert store.write(
        {
            "a": VehicleWrite(1, b"second", VehicleSetting(True, None)),
            "b": VehicleWrite(0, b"stale", VehicleSetting(True, None)),
        }
    ) == {"b"}
    store.close()
    again = SQLiteStore(path, IDLE_S, clock)
    assert again.read({"a", "b", "c"}) == {
        "a": StoredVehicle(VehicleSetting(True, None), b"second", 2),
        "b": StoredVehicle(None, b"b", 1),
        "c": StoredVehicle(),
    }
    clock.now_s = IDLE_S + 1.0  # the sessions expire; the settings stay
    assert again.read({"a"}) == {"a": StoredVehicle(VehicleSetting(True, None))} and again.session_count() == 0


def test_lon_lat_on_networks_without_projection_is_refused(tmp_path) -> None:
    app = create_app(ServiceSettings(nets=[TRACK_NET], state_db=":memory:"))
    with TestClient(app) as client:
        response = client.post(
            "/v1/warning",
            json={"vehicle_id": "v", "category": "M1", "speed_kmh": 50.0, "position": {"lon": 9.7, "lat": 50.9}},
        )
    assert response.status_code == 422
    assert response.json()["detail"] == [
        {
            "loc": ["body", "position"],
            "type": "value_error",
            "msg": "the served networks are not geo-referenced: give the position as x and y in network metres",
        }
    ]


def test_settings_come_from_the_environment(monkeypatch) -> None:
    nets = [TRACK_NET, TRACK_NET.with_name("t7_right.net.xml")]
    for name, value in {
        "CSWS_NETS": os.pathsep.join(map(str, nets)),
        "CSWS_STATE_DB": ":memory:",
        "CSWS_SESSION_IDLE_S": "5",
        "CSWS_PORT": "9001",
    }.items():
        monkeypatch.setenv(name, value)
    settings = ServiceSettings()
    assert settings.nets == nets
    assert (settings.session_idle_s, settings.port, settings.state_db) == (5.0, 9001, ":memory:")


def test_the_bundled_test_tracks_are_served_when_asked(monkeypatch) -> None:
    monkeypatch.delenv("CSWS_NETS", raising=False)
    index = json.loads((networks_dir() / "index.json").read_text())
    served = {p.name for p in ServiceSettings(state_db=":memory:", test_tracks=True).nets}
    assert {n["net_file"] for n in index["networks"]} <= served


def test_networks_with_the_same_name_are_refused(tmp_path) -> None:
    with pytest.raises(ValueError, match="share the name 't7_left'"):
        create_app(ServiceSettings(nets=[TRACK_NET, TRACK_NET], state_db=":memory:"))


def test_a_fix_from_far_in_the_future_locks_no_vehicle_out(state) -> None:
    # One query with a wild timestamp (sent by anyone who knows the id) answers for itself;
    # the vehicle's next good fix is answered as usual, not as stale.
    with TestClient(create_app(ServiceSettings(nets=[TRACK_NET], **state))) as client:
        assert (
            client.post("/v1/warning", json=_query("victim", timestamp_s=1_700_000_000.0)).json()["state"] == "active"
        )
        client.post("/v1/warning", json=_query("victim", timestamp_s=1e308))
        answer = client.post("/v1/warning", json=_query("victim", timestamp_s=1_700_000_000.1)).json()
        assert answer["state"] == "active" and answer["fault"] is None
