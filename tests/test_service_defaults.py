"""What a new user gets: ``csws serve`` with no options serves the bundled city, and every warning
answer says where its fix was placed: the network, the lane, the street's name and road type, and
the point on the lane (x, y, and lon, lat on a geo-referenced network).

The truth is the SUMO network read by sumolib (the edge a fix was laid on, its name and type, the
projection) and the lane's shape (the placed point lies on it, as far from the fix as the answer says).
"""

from __future__ import annotations

import math

import httpx
import numpy as np
import pytest
import sumolib
from builders import TRACK_NET, write_geo_track
from fastapi.testclient import TestClient
from hypothesis import given, settings
from hypothesis import strategies as st
from servers import Workers
from shapely import STRtree
from shapely.geometry import LineString, Point

from csws.networks import networks_dir
from csws.road.matching import lane_point
from csws.road.roadmap import RoadMap
from service.app import create_app
from service.networks import CITY_NETWORK, track_network_paths
from service.placement import LanePoints
from service.settings import ServiceSettings

CITY_NET = networks_dir() / CITY_NETWORK
#: How far beside its lane's axis the city fix is laid, m.
BESIDE_M = 1.5
#: No other road (or junction) lies this near the city fix, m.
NO_OTHER_ROAD_M = 25.0
#: The city takes longer to load than a test track, all the more on a busy machine, s.
CITY_STARTUP_S = 240.0


def test_by_default_the_city_alone_is_served(monkeypatch) -> None:
    for name in ("CSWS_NETS", "CSWS_TEST_TRACKS"):
        monkeypatch.delenv(name, raising=False)
    assert ServiceSettings(state_db=":memory:").nets == [CITY_NET]
    tracks = ServiceSettings(state_db=":memory:", test_tracks=True).nets
    assert CITY_NET not in tracks and TRACK_NET in tracks and len(tracks) == len(set(tracks)) > 30
    both = ServiceSettings(state_db=":memory:", nets=[CITY_NET], test_tracks=True).nets
    assert both == [CITY_NET, *track_network_paths()]
    monkeypatch.setenv("CSWS_TEST_TRACKS", "true")
    assert ServiceSettings(state_db=":memory:").nets == track_network_paths()


@settings(max_examples=60, deadline=None)
@given(st.data())
def test_lane_points_are_the_lanes_points_at_their_positions(data) -> None:
    road_map = _track_map()
    lane_ids = data.draw(st.lists(st.sampled_from(road_map.lane_ids), min_size=1, max_size=8))
    fractions = data.draw(st.lists(st.floats(-0.1, 1.1), min_size=len(lane_ids), max_size=len(lane_ids)))
    lane_pos_m = [f * road_map.lane(lane_id).length_m for lane_id, f in zip(lane_ids, fractions, strict=True)]
    lane_points = LanePoints(road_map)
    points = lane_points.points(lane_ids, lane_pos_m)
    for (x, y), lane_id, position_m in zip(points.tolist(), lane_ids, lane_pos_m, strict=True):
        clamped_m = min(max(position_m, 0.0), road_map.lane(lane_id).length_m)
        truth = lane_point(road_map, lane_id, clamped_m)
        assert math.dist((x, y), truth) < 1e-6
        assert math.dist(lane_points.point(lane_id, position_m), truth) < 1e-6


_MAPS: dict[str, RoadMap] = {}


def _track_map() -> RoadMap:
    if "track" not in _MAPS:
        _MAPS["track"] = RoadMap.load(TRACK_NET)
    return _MAPS["track"]


def _assert_placed(matched: dict, fix_xy: tuple[float, float], net: sumolib.net.Net) -> None:
    """The answer's point lies on its lane, as far from the fix as it says, and on a geo-referenced network
    at the lon/lat the network's projection gives it."""
    lane = net.getLane(matched["lane_id"])
    point = matched["position"]
    assert LineString(lane.getShape()).distance(Point(point["x"], point["y"])) < 1e-6
    assert math.dist(fix_xy, (point["x"], point["y"])) == pytest.approx(matched["distance_m"], abs=1e-4)
    if net.hasGeoProj():
        lon, lat = net.convertXY2LonLat(point["x"], point["y"])
        assert (point["lon"], point["lat"]) == (pytest.approx(lon, abs=1e-9), pytest.approx(lat, abs=1e-9))
    else:
        assert "lon" not in point


def test_single_and_batch_answers_name_the_network_lane_and_placed_point(tmp_path) -> None:
    geo_net = write_geo_track(tmp_path)
    settings = ServiceSettings(nets=[geo_net], state_db=":memory:")
    fixes = [(985.0, 0.4), (600.0, -0.8)]
    queries = [
        {"vehicle_id": f"truck-{k}", "category": "N", "speed_kmh": 80, "position": {"x": x, "y": y}, "heading_deg": 90}
        for k, (x, y) in enumerate(fixes)
    ]
    with TestClient(create_app(settings)) as client:
        single = client.post("/v1/warning", json=queries[0]).json()
        batch = client.post("/v1/warnings", json={"queries": queries[1:] + [queries[0] | {"vehicle_id": "van"}]}).json()
    net = sumolib.net.readNet(str(geo_net))
    answers = [single, *batch["answers"]]
    for answer, fix in zip(answers, [fixes[0], fixes[1], fixes[0]], strict=True):
        matched = answer["matched"]
        assert matched["network"] == "t7_geo" and matched["street_name"] is None and matched["road_type"] is None
        _assert_placed(matched, fix, net)
    assert single["matched"] == answers[2]["matched"]  # one vehicle or many: the same placement


def _lonely_city_segment(net: sumolib.net.Net) -> tuple[sumolib.net.edge.Edge, tuple[float, float], float]:
    """A named one-lane street of the city with a straight stretch far from every other road: its edge, a
    fix :data:`BESIDE_M` to the right of its lane's axis in the stretch's middle, and the lane's heading there."""
    edges = sorted(net.getEdges(withInternal=True), key=lambda e: e.getID())
    roads = STRtree([LineString(edge.getLane(0).getShape()) for edge in edges])
    for edge in edges:
        if edge.isSpecial() or not edge.getName() or edge.getLaneNumber() != 1 or edge.getLength() < 150:
            continue
        shape = np.array(edge.getLane(0).getShape())
        for start, end in zip(shape[:-1], shape[1:], strict=True):
            along = end - start
            if np.hypot(*along) < 60:
                continue
            unit = along / np.hypot(*along)
            middle = (start + end) / 2 + BESIDE_M * np.array([unit[1], -unit[0]])
            near = roads.query(Point(*middle).buffer(NO_OTHER_ROAD_M))
            if {edges[k].getID() for k in near} == {edge.getID()}:
                heading_deg = math.degrees(math.atan2(unit[0], unit[1])) % 360.0
                return edge, (float(middle[0]), float(middle[1])), heading_deg
    raise AssertionError("the city has no lonely named street")


@pytest.mark.slow
def test_the_default_service_answers_a_city_fix_with_its_street(tmp_path) -> None:
    net = sumolib.net.readNet(str(CITY_NET))
    edge, (x, y), heading_deg = _lonely_city_segment(net)
    lon, lat = net.convertXY2LonLat(x, y)
    service = Workers([], "--state-db", str(tmp_path / "state.sqlite3"), workers=1, startup_timeout_s=CITY_STARTUP_S)
    try:
        query = {"vehicle_id": "truck-1", "category": "N", "speed_kmh": 40, "heading_deg": heading_deg}
        with httpx.Client(base_url=service.url, timeout=30.0) as client:
            by_lonlat = client.post("/v1/warning", json=query | {"position": {"lon": lon, "lat": lat}}).json()
            by_xy = client.post(
                "/v1/warnings", json={"queries": [query | {"vehicle_id": "truck-2", "position": {"x": x, "y": y}}]}
            ).json()["answers"][0]
    finally:
        service.stop()
    for answer in (by_lonlat, by_xy):
        matched = answer["matched"]
        assert answer["state"] == "active", answer
        assert (matched["network"], matched["lane_id"]) == ("badhersfeld", edge.getLane(0).getID())
        assert (matched["street_name"], matched["road_type"]) == (edge.getName(), edge.getType())
        assert matched["distance_m"] == pytest.approx(BESIDE_M, abs=0.05)
        _assert_placed(matched, (x, y), net)
