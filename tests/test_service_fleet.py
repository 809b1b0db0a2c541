"""``GET /v1/fleet``: the vehicles with a live session, where they were last matched and what their latest
answer said, each fleet its own, a page at a time; on each state store, against a real service on loopback.
The map page that draws them is tested in a real browser (tests/test_map.py)."""

from __future__ import annotations

import base64
import time
from pathlib import Path

import numpy as np
import pytest
from builders import write_geo_track
from hypothesis import given, settings
from hypothesis import strategies as st
from servers import Server

from csws.networks import networks_dir
from csws.road.matching import lane_point, lane_points
from csws.road.roadmap import RoadMap
from service.fleet import DEFAULT_PAGE_SIZE, MAX_PAGE_SIZE
from service.keys import Role, add_key
from service.places import lane_points_many
from service.store.sqlite import BOX_PROBE_FACTOR

TRACK_NET = networks_dir() / "t7_left.net.xml"
TRACK = RoadMap.load(TRACK_NET)
#: The lanes of the track the vehicles are put on, with their lengths, m.
LANES = {lane_id: TRACK.lane(lane_id).length_m for lane_id in ("approach_0", "curve_0", "runout_0")}


def _query(vehicle_id: str, lane_pos_m: float, speed_kmh: float, lane_id: str = "approach_0") -> dict:
    return {
        "vehicle_id": vehicle_id,
        "category": "N",
        "speed_kmh": speed_kmh,
        "lane_id": lane_id,
        "lane_pos_m": lane_pos_m,
        "route": ["approach", "curve", "runout"],
    }


def _server(folder: Path, nets: list[Path], state: dict[str, str], **settings: str) -> Server:
    """The service on loopback with the state store of ``state`` (a SQLite file or a Redis database)."""
    others = {name: value for name, value in state.items() if name != "state_db"}
    return Server(nets, Path(state.get("state_db", folder / "unused.sqlite3")), **others, **settings)


def _walk(server: Server, limit: int, headers: dict[str, str] | None = None, **params: str) -> list[list[dict]]:
    """Every page of ``GET /v1/fleet`` from the first, following ``next_cursor`` until it is null."""
    pages, cursor = [], None
    while True:
        asked = {**params, "limit": str(limit), **({"cursor": cursor} if cursor is not None else {})}
        answer = server.client.get("/v1/fleet", params=asked, headers=headers)
        assert answer.status_code == 200, answer.text
        body = answer.json()
        pages.append(body["features"])
        cursor = body["next_cursor"]
        if cursor is None:
            return pages
        assert len(pages) <= 1000, "the cursor never ended"


def _shown_lonlat(track: RoadMap, lanes: dict[str, tuple[str, float]]) -> dict[str, tuple[float, float]]:
    """Where each vehicle of ``lanes`` (lane id and lane position by vehicle) is shown: its lane point in lon/lat."""
    return {
        vehicle_id: tuple(track.xy_to_lonlat_many(lane_points(track, lane_id, np.array([lane_pos_m])))[0])
        for vehicle_id, (lane_id, lane_pos_m) in lanes.items()
    }


def test_each_vehicle_is_where_it_was_matched_with_its_latest_answer(state, tmp_path) -> None:
    server = _server(tmp_path, [TRACK_NET], state)
    try:
        batch = [_query("far", 100.0, 60.0), _query("near", 885.0, 80.0), _query("near", 85.0, 80.0, "curve_0")]
        answers = server.client.post("/v1/warnings", json={"queries": batch}).json()["answers"]
        server.client.post(
            "/v1/warning",
            json={"vehicle_id": "lost", "category": "N", "speed_kmh": 50.0, "position": {"x": 500.0, "y": 400.0}},
        )
        fleet = server.client.get("/v1/fleet").json()
        assert fleet["next_cursor"] is None
        shown = {f["id"]: f for f in fleet["features"]}
        assert list(shown) == ["far", "near"]  # "lost" never matched: it has no place
        for answer, query in ((answers[0], batch[0]), (answers[2], batch[2])):
            feature = shown[answer["vehicle_id"]]
            assert feature["geometry"]["coordinates"] == pytest.approx(
                lane_point(TRACK, query["lane_id"], query["lane_pos_m"])
            )
            assert {k: feature["properties"][k] for k in ("state", "level", "speed_kmh", "category", "lane_id")} == {
                "state": answer["state"],
                "level": answer["level"],
                "speed_kmh": query["speed_kmh"],
                "category": "N",
                "lane_id": query["lane_id"],
            }
        assert shown["near"]["properties"]["level"] > 0
        x, y = shown["far"]["geometry"]["coordinates"]
        inside = server.client.get("/v1/fleet", params={"bbox": f"{x - 1},{y - 1},{x + 1},{y + 1}"}).json()
        assert [f["id"] for f in inside["features"]] == ["far"]
        for params in ({"network": "nowhere"}, {"bbox": "1,2,3"}):
            assert server.client.get("/v1/fleet", params=params).status_code == 422
    finally:
        server.stop()


def test_pages_hold_every_vehicle_once_and_a_box_exactly_those_inside(state, tmp_path) -> None:
    geo_net = write_geo_track(tmp_path)
    geo_track = RoadMap.load(geo_net)
    rng = np.random.default_rng(91)
    lane_ids = rng.choice(list(LANES), 403)
    lanes = {
        f"v{n:03d}-{rng.integers(1000)}": (str(lane), float(rng.uniform(0.0, LANES[lane])))
        for n, lane in enumerate(lane_ids)
    }
    server = _server(tmp_path, [geo_net], state)
    try:
        queries = [_query(v, pos, 50.0, lane) for v, (lane, pos) in lanes.items()]
        assert server.client.post("/v1/warnings", json={"queries": queries}).status_code == 200
        truth = _shown_lonlat(geo_track, lanes)

        pages = _walk(server, 10)
        assert [len(page) for page in pages] == [10] * 40 + [3]
        ids = [f["id"] for page in pages for f in page]
        assert ids == sorted(lanes)  # every vehicle once, in the order of the ids
        for feature in (f for page in pages for f in page):
            assert feature["geometry"]["coordinates"] == pytest.approx(truth[feature["id"]], abs=1e-9)

        lon, lat = np.array(list(truth.values())).T
        box = tuple(float(v) for v in (np.quantile(lon, 0.3), np.quantile(lat, 0.2), np.quantile(lon, 0.8), lat.max()))
        inside = {v for v, (x, y) in truth.items() if box[0] <= x <= box[2] and box[1] <= y <= box[3]}
        assert BOX_PROBE_FACTOR * 2 < len(inside) < len(lanes)
        bbox = ",".join(map(repr, box))
        # Pages of one (read in pieces of two) read this box in key order, pages of 100 the R*Tree's hits.
        assert BOX_PROBE_FACTOR * 101 > len(lanes)
        for limit in (1, 100):
            boxed = [f["id"] for page in _walk(server, limit, bbox=bbox) for f in page]
            assert boxed == sorted(inside)

        # A vehicle inside stands still (its place is kept), then moves out of the box: it leaves the box's
        # pages and shows where it went.
        mover = sorted(inside)[0]
        assert server.client.post("/v1/warning", json=_query(mover, lanes[mover][1], 0.0, lanes[mover][0])).is_success
        assert [f["id"] for page in _walk(server, 7, bbox=bbox) for f in page] == sorted(inside)
        outside = next(
            (lane, pos)
            for lane, pos in ((lane, float(p)) for lane in LANES for p in np.linspace(0.0, LANES[lane], 40))
            if not box[0] <= _shown_lonlat(geo_track, {"x": (lane, pos)})["x"][0] <= box[2]
        )
        assert server.client.post("/v1/warning", json=_query(mover, outside[1], 50.0, outside[0])).status_code == 200
        boxed = [f["id"] for page in _walk(server, 7, bbox=bbox) for f in page]
        assert boxed == sorted(inside - {mover})
        everywhere = {f["id"]: f for page in _walk(server, MAX_PAGE_SIZE) for f in page}
        assert everywhere[mover]["geometry"]["coordinates"] == pytest.approx(
            _shown_lonlat(geo_track, {mover: outside})[mover], abs=1e-9
        )
    finally:
        server.stop()


def test_bad_limits_and_cursors_are_a_422_naming_the_rule(tmp_path) -> None:
    server = Server([TRACK_NET], tmp_path / "vehicles.sqlite3")
    try:
        for params, field in (
            ({"limit": "0"}, "limit"),
            ({"limit": str(MAX_PAGE_SIZE + 1)}, "limit"),
            ({"cursor": "%%%"}, "cursor"),
            ({"cursor": base64.urlsafe_b64encode(b"not a cursor").decode()}, "cursor"),
        ):
            answer = server.client.get("/v1/fleet", params=params)
            assert answer.status_code == 422, params
            (detail,) = answer.json()["detail"]
            assert detail["loc"] == ["query", field]
        limit = server.client.get("/openapi.json").json()["paths"]["/v1/fleet"]["get"]["parameters"]
        documented = {p["name"]: p["schema"] for p in limit}
        assert documented["limit"]["default"] == DEFAULT_PAGE_SIZE
        assert documented["limit"]["maximum"] == MAX_PAGE_SIZE
        assert "cursor" in documented
    finally:
        server.stop()


def test_a_fleet_sees_only_its_own_vehicles(state, tmp_path) -> None:
    path = tmp_path / "api-keys.json"
    acme, other = add_key(path, "acme", Role.QUERY), add_key(path, "other", Role.QUERY)
    server = _server(tmp_path, [TRACK_NET], state, api_keys_file=str(path))
    try:
        sent = {acme: ["truck-1", "truck-3"], other: ["truck-1", "truck-2", "truck-4"]}
        for key, vehicle_ids in sent.items():
            for number, vehicle_id in enumerate(vehicle_ids):
                answer = server.client.post(
                    "/v1/warning",
                    json=_query(vehicle_id, 100.0 * number + 50.0, 70.0),
                    headers={"Authorization": f"Bearer {key}"},
                )
                assert answer.status_code == 200
        for key, vehicle_ids in sent.items():
            headers = {"Authorization": f"Bearer {key}"}
            pages = _walk(server, 1, headers)
            assert [f["id"] for page in pages for f in page] == vehicle_ids
        # A cursor is a place in the order of ids, not a way into another fleet.
        first = server.client.get("/v1/fleet", params={"limit": "1"}, headers={"Authorization": f"Bearer {other}"})
        cursor = first.json()["next_cursor"]
        after = server.client.get(
            "/v1/fleet", params={"cursor": cursor}, headers={"Authorization": f"Bearer {acme}"}
        ).json()
        assert [f["id"] for f in after["features"]] == ["truck-3"]
        assert server.client.get("/v1/fleet").status_code == 401
        assert server.client.get("/map").status_code == 200  # the page holds no data; it sends the key for it
        assert "next_cursor" in server.client.get("/static/map.js").text  # it follows the pages
    finally:
        server.stop()


@settings(max_examples=200, deadline=None)
@given(
    st.lists(
        st.tuples(st.sampled_from(sorted(TRACK.lane_ids)), st.floats(-50.0, 1_500.0, allow_nan=False)),
        min_size=1,
        max_size=20,
    )
)
def test_lane_points_of_many_lanes_at_once_are_those_of_each_lane(lanes) -> None:
    lane_ids, positions = [lane for lane, _ in lanes], [pos for _, pos in lanes]
    expected = [lane_points(TRACK, lane, np.array([pos]))[0] for lane, pos in lanes]
    assert lane_points_many(TRACK, lane_ids, positions) == pytest.approx(np.array(expected), abs=1e-9)


def test_a_vehicle_whose_session_expired_leaves_the_fleet(state, tmp_path) -> None:
    idle_s = 2.0
    server = _server(tmp_path, [TRACK_NET], state, session_idle_s=str(idle_s))
    try:
        assert server.client.post("/v1/warning", json=_query("parked", 100.0, 50.0)).status_code == 200
        assert [f["id"] for page in _walk(server, 10) for f in page] == ["parked"]
        time.sleep(idle_s + 0.5)
        assert server.client.post("/v1/warning", json=_query("driving", 200.0, 50.0)).status_code == 200
        for _ in range(2):  # the walk that finds it gone takes it out of the index (Redis); it stays out
            assert [f["id"] for page in _walk(server, 10) for f in page] == ["driving"]
    finally:
        server.stop()
