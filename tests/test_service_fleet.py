"""``GET /v1/fleet``: the vehicles with a live session, where they were last matched and what their latest
answer said, each fleet its own; on each state store. In-process (FastAPI's TestClient); the map page
that draws them is tested in a real browser (tests/test_map.py)."""

from __future__ import annotations

import pytest
from fastapi.testclient import TestClient

from csws.networks import networks_dir
from csws.road.matching import lane_point
from csws.road.roadmap import RoadMap
from service.app import create_app
from service.keys import Role, add_key
from service.settings import ServiceSettings

TRACK_NET = networks_dir() / "t7_left.net.xml"


def _query(vehicle_id: str, lane_pos_m: float, speed_kmh: float, lane_id: str = "approach_0") -> dict:
    return {
        "vehicle_id": vehicle_id,
        "category": "N",
        "speed_kmh": speed_kmh,
        "lane_id": lane_id,
        "lane_pos_m": lane_pos_m,
        "route": ["approach", "curve", "runout"],
    }


def test_each_vehicle_is_where_it_was_matched_with_its_latest_answer(state) -> None:
    track = RoadMap.load(TRACK_NET)
    with TestClient(create_app(ServiceSettings(nets=[TRACK_NET], **state))) as client:
        batch = [_query("far", 100.0, 60.0), _query("near", 885.0, 80.0), _query("near", 85.0, 80.0, "curve_0")]
        answers = client.post("/v1/warnings", json={"queries": batch}).json()["answers"]
        client.post(
            "/v1/warning",
            json={"vehicle_id": "lost", "category": "N", "speed_kmh": 50.0, "position": {"x": 500.0, "y": 400.0}},
        )
        fleet = {f["id"]: f for f in client.get("/v1/fleet").json()["features"]}
        assert set(fleet) == {"far", "near"}  # "lost" never matched: it has no place
        for answer, query in ((answers[0], batch[0]), (answers[2], batch[2])):
            shown = fleet[answer["vehicle_id"]]
            assert shown["geometry"]["coordinates"] == pytest.approx(
                lane_point(track, query["lane_id"], query["lane_pos_m"])
            )
            assert {k: shown["properties"][k] for k in ("state", "level", "speed_kmh", "category", "lane_id")} == {
                "state": answer["state"],
                "level": answer["level"],
                "speed_kmh": query["speed_kmh"],
                "category": "N",
                "lane_id": query["lane_id"],
            }
        assert fleet["near"]["properties"]["level"] > 0
        x, y = fleet["far"]["geometry"]["coordinates"]
        inside = client.get("/v1/fleet", params={"bbox": f"{x - 1},{y - 1},{x + 1},{y + 1}"}).json()["features"]
        assert [f["id"] for f in inside] == ["far"]
        assert client.get("/v1/fleet", params={"network": "nowhere"}).status_code == 422
        assert client.get("/v1/fleet", params={"bbox": "1,2,3"}).status_code == 422


def test_a_fleet_sees_only_its_own_vehicles(tmp_path) -> None:
    path = tmp_path / "api-keys.json"
    acme, other = add_key(path, "acme", Role.QUERY), add_key(path, "other", Role.QUERY)
    settings = ServiceSettings(nets=[TRACK_NET], api_keys_file=path, state_db=":memory:")
    with TestClient(create_app(settings)) as client:
        for key, vehicle_id in ((acme, "truck-1"), (other, "truck-1"), (other, "truck-2")):
            client.post("/v1/warning", json=_query(vehicle_id, 500.0, 70.0), headers={"Authorization": f"Bearer {key}"})
        seen = {
            key: sorted(
                f["id"] for f in client.get("/v1/fleet", headers={"Authorization": f"Bearer {key}"}).json()["features"]
            )
            for key in (acme, other)
        }
        assert seen == {acme: ["truck-1"], other: ["truck-1", "truck-2"]}
        assert client.get("/v1/fleet").status_code == 401
        assert client.get("/map").status_code == 200  # the page holds no data; it sends the key for it
        assert client.get("/static/map.js").status_code == 200
