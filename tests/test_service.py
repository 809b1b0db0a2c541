"""The HTTP service, served by a real uvicorn on loopback, against the library and the tracks' truth.

The served networks (``served_nets`` of conftest.py): the Table 7 track made geo-referenced (a
UTM projection added to its location), and the side roads of tests/builders.py placed 10 km east of it.
Every answer is compared with what the library (MapMatcher + Engine) gives for the
same input, and positions and distances with the track's generator-written truth.
"""

from __future__ import annotations

import json
import subprocess
import sys
from itertools import pairwise

import httpx
import numpy as np
import pytest
from builders import FRONTAGE_OFFSET_M, LANE_WIDTH_M, SIDE_X_M, TRACK
from servers import Server

from csws.engine import Engine, VehicleInput
from csws.networks import networks_dir
from csws.road.roadmap import RoadMap
from csws.standard import Category, Level, warning_speed

TRUTH = json.loads((networks_dir() / f"{TRACK}.truth.json").read_text())
ROUTE = TRUTH["route"]["edges"]


@pytest.fixture(scope="module")
def track_map(served_nets) -> RoadMap:
    return RoadMap.load(served_nets[0])


@pytest.fixture
def client(served_server) -> httpx.Client:
    return served_server.client


def _route_lane(route_s: float) -> tuple[str, float]:
    """Lane and lane position of a route arc length, from the truth's lane table."""
    lane = next(lane for lane in reversed(TRUTH["lanes"]) if lane["start_s"] <= route_s)
    return lane["lane"], route_s - lane["start_s"]


def _lane_query(vehicle_id: str, route_s: float, speed_kmh: float, category: str = "N", **extra) -> dict:
    lane_id, lane_pos_m = _route_lane(route_s)
    return {
        "vehicle_id": vehicle_id,
        "category": category,
        "speed_kmh": speed_kmh,
        "lane_id": lane_id,
        "lane_pos_m": lane_pos_m,
        "route": ROUTE,
        **extra,
    }


def _library_input(query: dict) -> VehicleInput:
    return VehicleInput(
        query["vehicle_id"],
        query["category"],
        query["speed_kmh"],
        query["lane_id"],
        query["lane_pos_m"],
        query.get("route"),
        query.get("timestamp_s"),
        query.get("age_s"),
    )


def _assert_same(served: dict, library) -> None:
    """A served answer says exactly what the library's answer says (floats compared exactly)."""
    assert served["vehicle_id"] == library.vehicle_id
    assert served["state"] == library.state.value
    assert served["fault"] == (library.fault.value if library.fault else None)
    assert served["level"] == int(library.level)
    assert served["path_kind"] == (library.path.kind.value if library.path else None)
    assert served["hmi"] == {"visual": library.warning.hmi.visual, "audible": library.warning.hmi.audible}
    fields = ("curve_id", "part_index", "distance_m", "radius_m", "warning_speed_kmh", "warning_distance_m")
    expected = [{f: getattr(t, f) for f in fields} | {"level": int(t.level)} for t in library.warning.triggers]
    assert [{k: t[k] for k in (*fields, "level")} for t in served["triggers"]] == expected
    if library.warning.target is None:
        assert served["target"] is None
    else:
        assert served["target"]["distance_m"] == library.warning.target.distance_m
        assert served["target"]["curve_id"] == library.warning.target.curve_id


# ------------------------------------------------------------------ warnings
def test_a_drive_through_the_track_gives_the_library_answers(client, track_map) -> None:
    engine = Engine(track_map)
    levels = []
    for step, route_s in enumerate(np.arange(700.0, 1180.0, 10.0)):
        query = _lane_query("drive-1", float(route_s), 75.0, timestamp_s=float(step))
        response = client.post("/v1/warning", json=query)
        assert response.status_code == 200, response.text
        _assert_same(response.json(), engine.evaluate(_library_input(query)))
        levels.append(response.json()["level"])
    assert max(levels) == 2  # 75 km/h is above N's level-2 warning speed of both curves


def test_the_target_lies_where_the_truth_puts_the_curve(client, track_map) -> None:
    curve_1 = TRUTH["curves"][0]
    route_s = curve_1["start_s"] - 20.0
    answer = client.post("/v1/warning", json=_lane_query("target-1", route_s, 90.0)).json()
    target = answer["target"]
    assert target["level"] == 2
    assert target["distance_m"] == pytest.approx(20.0, abs=0.5)
    assert target["radius_m"] == pytest.approx(curve_1["radius_m"], rel=0.01)
    assert target["warning_speed_kmh"] == pytest.approx(
        warning_speed(target["radius_m"], Category.N, Level.LEVEL_2), rel=1e-9
    )
    position = target["position"]
    assert (position["x"], position["y"]) == pytest.approx(tuple(curve_1["start_xy"]), abs=0.5)
    assert (position["lon"], position["lat"]) == pytest.approx(track_map.xy_to_lonlat(position["x"], position["y"]))
    lane_id, lane_pos_m = _route_lane(route_s)
    matched = answer["matched"]
    assert (matched["lane_id"], matched["lane_pos_m"], matched["distance_m"]) == (lane_id, lane_pos_m, 0.0)


def test_a_batch_is_answered_in_order_as_the_library_answers(client, track_map) -> None:
    rng = np.random.default_rng(3)
    queries = [
        _lane_query(f"fleet-{i}", float(s), float(v), str(c))
        for i, (s, v, c) in enumerate(
            zip(
                rng.uniform(0.0, 1450.0, 2000),
                rng.uniform(20.0, 130.0, 2000),
                rng.choice(["M1", "M2", "M3", "N", "O"], 2000),
                strict=False,
            )
        )
    ]
    response = client.post("/v1/warnings", json={"queries": queries})
    assert response.status_code == 200, response.text
    served = response.json()["answers"]
    library = Engine(track_map).evaluate_many([_library_input(q) for q in queries])
    assert [a["vehicle_id"] for a in served] == [q["vehicle_id"] for q in queries]
    for answer, expected in zip(served, library, strict=False):
        _assert_same(answer, expected)
    assert {a["level"] for a in served} == {0, 1, 2}
    assert "csws;dur=" in response.headers["server-timing"]


def test_a_vehicle_twice_in_one_batch_is_evaluated_in_order(client) -> None:
    older = _lane_query("twice", 500.0, 50.0, timestamp_s=10.0)
    newer = _lane_query("twice", 510.0, 50.0, timestamp_s=11.0)
    stale = _lane_query("twice", 520.0, 50.0, timestamp_s=5.0)
    answers = client.post("/v1/warnings", json={"queries": [older, newer, stale]}).json()["answers"]
    assert [a["state"] for a in answers] == ["active", "active", "fault"]
    assert answers[2]["fault"] == "the input is stale"


def test_positions_are_matched_in_metres_and_in_lon_lat(client, track_map) -> None:
    lon, lat = track_map.xy_to_lonlat(850.0, 0.4)
    by_xy = client.post(
        "/v1/warning",
        json={
            "vehicle_id": "xy-1",
            "category": "M1",
            "speed_kmh": 60.0,
            "position": {"x": 850.0, "y": 0.4},
            "heading_deg": 90.0,
        },
    ).json()
    by_lonlat = client.post(
        "/v1/warning",
        json={
            "vehicle_id": "ll-1",
            "category": "M1",
            "speed_kmh": 60.0,
            "position": {"lon": lon, "lat": lat},
            "heading_deg": 90.0,
        },
    ).json()
    for answer in (by_xy, by_lonlat):
        assert answer["matched"]["lane_id"] == "approach_0"
        assert answer["matched"]["lane_pos_m"] == pytest.approx(850.0, abs=0.01)
        assert answer["matched"]["distance_m"] == pytest.approx(0.4, abs=0.01)
        assert answer["path_kind"] == "predicted"
    library = Engine(track_map).evaluate(VehicleInput("xy-1", "M1", 60.0, "approach_0", by_xy["matched"]["lane_pos_m"]))
    _assert_same(by_xy, library)


def test_consecutive_fixes_keep_to_their_road(client) -> None:
    main_lane_y = -LANE_WIDTH_M / 2
    first = {
        "vehicle_id": "parallel-1",
        "category": "N",
        "speed_kmh": 70.0,
        "position": {"x": SIDE_X_M + 250.0, "y": main_lane_y},
        "heading_deg": 90.0,
    }
    between = {"x": SIDE_X_M + 300.0, "y": FRONTAGE_OFFSET_M - 4.0}  # nearer the frontage road
    assert client.post("/v1/warning", json=first).json()["matched"]["lane_id"] == "AB_0"
    kept = client.post("/v1/warning", json={**first, "position": between}).json()
    fresh = client.post("/v1/warning", json={**first, "vehicle_id": "parallel-2", "position": between}).json()
    assert kept["matched"]["lane_id"] == "AB_0"
    assert fresh["matched"]["lane_id"] == "frontage_0"


def test_a_query_naming_its_network_is_answered_on_that_network_only(client) -> None:
    on_track = {"vehicle_id": "named-1", "category": "N", "speed_kmh": 50.0, "position": {"x": 500.0, "y": 0.0}}
    answer = client.post("/v1/warning", json={**on_track, "network": "t7_geo"}).json()
    assert answer["matched"]["lane_id"] == "approach_0" and answer["state"] == "active"
    elsewhere = client.post("/v1/warning", json={**on_track, "vehicle_id": "named-2", "network": "side_roads"}).json()
    assert elsewhere["matched"] is None and elsewhere["state"] == "fault"


def test_a_fix_matching_nothing_is_a_fault_answer(client) -> None:
    response = client.post(
        "/v1/warning",
        json={"vehicle_id": "lost-1", "category": "N", "speed_kmh": 50.0, "position": {"x": 5000.0, "y": 5000.0}},
    )
    assert response.status_code == 200
    answer = response.json()
    assert (answer["state"], answer["level"], answer["matched"]) == ("fault", 0, None)
    assert answer["fault"] == "the position matches no lane of the map: no lane within 10 m"


def test_the_matchers_scales_are_settings(monkeypatch) -> None:
    from service.settings import ServiceSettings

    given = {
        "accuracy_m": 8.0,
        "search_sigmas": 3.0,
        "heading_sigma_deg": 15.0,
        "lane_change_log_p": -2.5,
        "standstill_mps": 0.5,
        "standstill_edge_log_p": -3.0,
        "standstill_junction_log_p": -6.0,
    }
    for name, value in given.items():
        monkeypatch.setenv(f"CSWS_MATCH_{name.upper()}", str(value))
    monkeypatch.setenv("CSWS_MATCH_DEAD_RECKONING_S", "4")
    settings = ServiceSettings().match_settings()
    assert {name: getattr(settings, name) for name in given} == given and settings.dead_reckoning_s == 4.0


@pytest.mark.slow
def test_a_fleet_with_noisier_fixes_sets_the_default_accuracy(served_nets, tmp_path, client) -> None:
    """A fix without ``accuracy_m`` 15 m beside the road: beyond the default search radius (the tolerance,
    and 2.5 standard deviations of 4 m), within 2.5 of CSWS_MATCH_ACCURACY_M = 8 m."""
    off_road_m, sigmas = 15.0, 2.5
    assert max(10.0, sigmas * 4.0) < off_road_m < sigmas * 8.0
    fix = {
        "vehicle_id": "noisy-1",
        "category": "N",
        "speed_kmh": 50.0,
        "position": {"x": 500.0, "y": off_road_m},
        "heading_deg": 90.0,
        "network": "t7_geo",
    }
    assert client.post("/v1/warning", json=fix).json()["state"] == "fault"
    noisier = Server(served_nets[:1], tmp_path / "vehicles.sqlite3", match_accuracy_m="8")
    try:
        answer = noisier.client.post("/v1/warning", json=fix).json()
    finally:
        noisier.stop()
    assert answer["state"] == "active" and answer["matched"]["lane_id"] == "approach_0", answer


# ------------------------------------------------------------------ map
def test_curves_are_geojson_with_the_truth_radii(client) -> None:
    collection = client.get("/v1/curves").json()
    assert collection["type"] == "FeatureCollection"
    assert collection["coordinates"] == "per feature"
    (curve,) = [f for f in collection["features"] if f["properties"]["network"] == "t7_geo"]
    properties = curve["properties"]
    assert properties["coordinates"] == "lon/lat (WGS84)"
    assert [p["radius_m"] for p in properties["parts"]] == pytest.approx(
        [c["radius_m"] for c in TRUTH["curves"]], rel=0.01
    )
    assert properties["radius_m"] == pytest.approx(min(c["radius_m"] for c in TRUTH["curves"]), rel=0.01)
    assert properties["angle_deg"] == pytest.approx(sum(c["angle_deg"] for c in TRUTH["curves"]), abs=1.0)
    assert properties["direction"] == "left"
    assert properties["warning_speed_kmh"]["N"]["1"] == pytest.approx(
        warning_speed(properties["radius_m"], "N", 1), rel=1e-9
    )
    assert not any(part["spiral"] for part in properties["parts"])  # the track's curves are arcs
    assert (properties["street_name"], properties["road_type"]) == ("", "")  # as the generator writes the track
    west, south, east, north = curve["bbox"]
    assert client.get("/v1/curves", params={"bbox": f"{west},{south},{east},{north}"}).json()["features"] == [curve]
    assert client.get("/v1/curves", params={"bbox": f"{east + 1},{south},{east + 2},{north}"}).json()["features"] == []


def test_the_horizon_lists_the_curves_ahead_at_their_truth_distances(client) -> None:
    response = client.get(
        "/v1/horizon",
        params={"lane_id": "approach_0", "lane_pos_m": 700.0, "length_m": 600.0, "route": ",".join(ROUTE)},
    )
    assert response.status_code == 200, response.text
    ahead = response.json()
    assert ahead["path_kind"] == "route"
    assert [c["distance_m"] for c in ahead["cpois"]] == pytest.approx(
        [c["start_s"] - 700.0 for c in TRUTH["curves"]], abs=0.5
    )
    assert [c["radius_m"] for c in ahead["cpois"]] == pytest.approx([c["radius_m"] for c in TRUTH["curves"]], rel=0.01)
    profile = ahead["profile"]
    assert profile[0]["start_m"] == 0.0 and profile[-1]["end_m"] == pytest.approx(600.0)
    assert all(a["end_m"] == b["start_m"] for a, b in pairwise(profile))


# ------------------------------------------------------------------ vehicles
def test_switching_a_vehicle_off_and_on(client) -> None:
    warning_at = _lane_query("switch-1", TRUTH["curves"][0]["start_s"] - 10.0, 90.0)
    assert client.put("/v1/vehicles/switch-1", json={"switched_on": False, "category": "N"}).json()["state"] == "off"
    off = client.post("/v1/warning", json={k: v for k, v in warning_at.items() if k != "category"}).json()
    assert (off["state"], off["level"], off["target"]) == ("off", 0, None)
    state = client.get("/v1/vehicles/switch-1").json()
    assert (state["switched_on"], state["category"]) == (False, "N")
    assert client.put("/v1/vehicles/switch-1", json={"switched_on": True}).json()["state"] == "standby"
    on = client.post("/v1/warning", json=warning_at).json()
    assert (on["state"], on["level"]) == ("active", 2)
    assert client.get("/v1/vehicles/never-seen").status_code == 404


@pytest.mark.slow
def test_switches_survive_a_restart(served_nets, tmp_path) -> None:
    state_db = tmp_path / "vehicles.sqlite3"
    first = Server(served_nets[1:], state_db)
    try:
        assert (
            first.client.put("/v1/vehicles/kept-off", json={"switched_on": False, "category": "M3"}).status_code == 200
        )
    finally:
        first.stop()
    second = Server(served_nets[1:], state_db)
    try:
        state = second.client.get("/v1/vehicles/kept-off").json()
        assert (state["switched_on"], state["category"]) == (False, "M3")
        answer = second.client.post(
            "/v1/warning",
            json={"vehicle_id": "kept-off", "speed_kmh": 50.0, "position": {"x": SIDE_X_M + 100.0, "y": -1.6}},
        ).json()
        assert answer["state"] == "off"
    finally:
        second.stop()


# ------------------------------------------------------------------ operations
def test_health_metrics_and_docs(client) -> None:
    assert client.get("/healthz").json() == {"status": "ok"}
    ready = client.get("/readyz").json()
    assert [n["name"] for n in ready["networks"]] == ["t7_geo", "side_roads"]
    client.post("/v1/warning", json=_lane_query("metrics-1", 100.0, 50.0))
    metrics = client.get("/metrics").text
    assert 'csws_http_requests_total{method="POST",route="/v1/warning",status="200"}' in metrics
    assert 'csws_http_request_duration_seconds_count{route="/v1/warning"}' in metrics
    assert 'csws_answers_total{state="active",level="0"}' in metrics
    schema = client.get("/openapi.json").json()
    assert {"/v1/warning", "/v1/warnings", "/v1/curves", "/v1/horizon", "/v1/vehicles/{vehicle_id}"} <= set(
        schema["paths"]
    )
    bodies = {
        path: schema["paths"][path]["post"]["requestBody"]["content"]["application/json"]["schema"]
        for path in ("/v1/warning", "/v1/warnings")
    }
    assert bodies["/v1/warnings"]["properties"]["queries"]["maxItems"] == 10_000
    assert (
        "examples" in bodies["/v1/warning"] and "examples" in bodies["/v1/warnings"]["properties"]["queries"]["items"]
    )
    assert client.get("/docs").status_code == 200


@pytest.mark.slow
def test_a_network_that_cannot_be_read_stops_start_up_in_one_line(tmp_path) -> None:
    broken = tmp_path / "broken.net.xml"
    broken.write_text("<net>")
    result = subprocess.run(
        [sys.executable, "-m", "csws", "serve", "--net", str(broken), "--state-db", ":memory:"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2
    assert result.stderr.strip().count("\n") == 0
    assert result.stderr.startswith("csws: error: ") and "broken.net.xml" in result.stderr
