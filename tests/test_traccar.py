"""``POST /v1/traccar``: Traccar's JSON position forwarding, answered as the same fix sent to ``/v1/warning``.

The payloads are written here from Traccar's documented format (``{"position": {...}, "device":
{...}}``, speed in knots, ``course``, ``fixTime`` in ISO 8601, ``valid``, ``outdated``, free
attributes and many fields csws does not read); lon/lat of the geo-referenced Table 7 track by
pyproj, not by csws.
"""

from __future__ import annotations

from datetime import UTC, datetime

import pyproj
import pytest
from builders import UTM32, write_geo_track
from fastapi.testclient import TestClient

from csws.standard import Category
from service.app import create_app
from service.settings import ServiceSettings
from service.traccar import KNOT_KMH, IdSource, Ignored, TraccarForward, query_of

#: Network (0, 0) of the geo track lies at UTM 32N (550000, 5635000) (tests/builders.py).
ORIGIN_E, ORIGIN_N = 550_000.0, 5_635_000.0
FIX_TIME = "2026-11-26T02:00:00.000+00:00"


def lonlat(x_m: float, y_m: float) -> tuple[float, float]:
    to_wgs84 = pyproj.Transformer.from_crs(pyproj.CRS.from_proj4(UTM32), "EPSG:4326", always_xy=True)
    return to_wgs84.transform(ORIGIN_E + x_m, ORIGIN_N + y_m)


def forward(x_m: float = 600.0, knots: float = 40.0, **changes) -> dict:
    """A forwarded position as Traccar writes it, with the fields it always sends."""
    lon, lat = lonlat(x_m, 0.0)
    position = {
        "id": 12345,
        "attributes": {"batteryLevel": 85, "distance": 15.4, "totalDistance": 12500.5, "motion": True},
        "deviceId": 10,
        "protocol": "osmand",
        "serverTime": FIX_TIME,
        "deviceTime": FIX_TIME,
        "fixTime": FIX_TIME,
        "outdated": False,
        "valid": True,
        "latitude": lat,
        "longitude": lon,
        "altitude": 210.0,
        "speed": knots,
        "course": 90.0,
        "address": None,
        "accuracy": 4.0,
        "network": None,
    }
    device = {
        "id": 10,
        "attributes": {},
        "groupId": 0,
        "name": "truck-18",
        "uniqueId": "866123456789012",
        "status": "online",
        "lastUpdate": FIX_TIME,
        "positionId": 12345,
        "phone": None,
        "model": "GT06",
        "contact": None,
        "category": "truck",
        "disabled": False,
    }
    position.update(changes.pop("position", {}))
    device.update(changes.pop("device", {}))
    return {"position": position, "device": device}


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory):
    net = write_geo_track(tmp_path_factory.mktemp("traccar"))
    with TestClient(create_app(ServiceSettings(nets=[net], state_db=":memory:"))) as client:
        yield client


def test_a_forwarded_position_is_answered_as_the_same_fix_in_km_h(client):
    answer = client.post("/v1/traccar", json=forward(x_m=600.0, knots=40.0))
    assert answer.status_code == 200
    lon, lat = lonlat(600.0, 0.0)
    same = {
        "vehicle_id": "twin",
        "category": "N",
        "speed_kmh": 40.0 * 1.852,
        "position": {"lon": lon, "lat": lat},
        "heading_deg": 90.0,
        "accuracy_m": 4.0,
        "timestamp_s": datetime(2026, 11, 26, 2, tzinfo=UTC).timestamp(),
    }
    expected = client.post("/v1/warning", json=same).json()
    got = answer.json()
    assert got["vehicle_id"] == "866123456789012"
    assert {k: v for k, v in got.items() if k != "vehicle_id"} == {
        k: v for k, v in expected.items() if k != "vehicle_id"
    }
    assert got["matched"] is not None and got["state"] == "active"


def test_invalid_and_outdated_positions_are_not_evaluated(client):
    for flag, value, reason in (("valid", False, "invalid"), ("outdated", True, "outdated")):
        answer = client.post("/v1/traccar", json=forward(position={flag: value}))
        assert answer.status_code == 202 and answer.json()["ignored"] == reason


def test_a_position_without_course_has_no_heading(client):
    payload = forward()
    del payload["position"]["course"]
    assert client.post("/v1/traccar", json=payload).status_code == 200
    parsed = query_of(TraccarForward.model_validate(payload), IdSource.UNIQUE_ID, 0.0)
    assert not isinstance(parsed, Ignored) and parsed.heading_deg is None


def test_the_category_comes_from_the_attribute_then_the_traccar_category():
    def category(device: dict) -> Category | None:
        parsed = query_of(TraccarForward.model_validate(forward(device=device)), IdSource.UNIQUE_ID, 0.0)
        assert not isinstance(parsed, Ignored)
        return parsed.category

    assert category({"category": "truck"}) == Category.N
    assert category({"category": "bus"}) == Category.M3
    assert category({"category": "car"}) == Category.M1
    assert category({"category": "person"}) is None
    assert category({"category": "truck", "attributes": {"cswsCategory": "M2"}}) == Category.M2


def test_a_device_of_no_category_is_a_422_that_says_so(client):
    answer = client.post("/v1/traccar", json=forward(device={"category": "person", "uniqueId": "walker"}))
    assert answer.status_code == 422 and "category" in answer.text


def test_the_vehicle_id_can_be_the_device_name(client):
    assert client.post("/v1/traccar?vehicle_id=name", json=forward()).json()["vehicle_id"] == "truck-18"
    bad = client.post("/v1/traccar?vehicle_id=name", json=forward(device={"name": "a/b"}))
    assert bad.status_code == 422 and bad.json()["detail"][0]["loc"] == ["body", "device", "name"]


@pytest.mark.parametrize(
    ("payload", "where"),
    [
        ({"device": {"uniqueId": "x"}}, ["body", "position"]),
        (
            {"position": {"latitude": 95.0, "longitude": 9.0}, "device": {"uniqueId": "x"}},
            ["body", "position", "latitude"],
        ),
        (
            {"position": {"latitude": 50.0, "longitude": 9.0, "speed": -1.0}, "device": {"uniqueId": "x"}},
            ["body", "position", "speed"],
        ),
    ],
)
def test_payloads_not_in_traccars_format_are_a_422_naming_the_field(client, payload, where):
    answer = client.post("/v1/traccar", json=payload)
    assert answer.status_code == 422 and answer.json()["detail"][0]["loc"] == where


def test_knots_are_converted_exactly():
    parsed = query_of(TraccarForward.model_validate(forward(knots=10.0)), IdSource.UNIQUE_ID, 0.0)
    assert not isinstance(parsed, Ignored) and parsed.speed_kmh == pytest.approx(18.52) and KNOT_KMH == 1.852
