"""Inputs and faults that must never crash anything, where the other test files do not already cover them.

docs/robustness.md maps every robustness point to the test that covers it. Here:

* a network without curves, through the engine and the service (nothing warns, nothing
  breaks, the end of its dead-end lane included);
* zero-length lanes: netconvert's lanes of a 2 cm edge (0.1 m long, shapes of 2-6 cm,
  some running backwards), the tracks' junction lanes whose shapes are two identical
  points, and lanes whose shape has one point or none (a broken network);
* NaN coordinates through the service (every numeric field, single and batch, and the
  map endpoints) and through the library;
* a missing and a corrupt network for every command that takes one, and a corrupt
  settings database for ``csws serve``: one line, exit status 2.

Truth is constructed: the roads are straight (no curve, no CPOI) and their lengths are
authored here; the Table 7 track's curve positions come from its generator-written truth.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from markers import marks_its_tests
from servers import Server

from csws.engine import Engine, VehicleInput
from csws.geometry import sample_pieces, straight
from csws.networks import networks_dir
from csws.road.roadmap import NetworkError, RoadMap
from csws.state import Fault, SystemState
from csws.sumo.netbuild import netconvert, shape_text

#: The straight network: a one-way road A -> J -> B along y = 0, J at this x, B at twice it, m.
STRAIGHT_HALF_M = 500.0
#: The tiny-edge network lies this far north of the straight one, so that no fix matches both.
TINY_Y_M = 5000.0
#: Its edge bc is this long between two 600 m edges, m.
TINY_EDGE_M = 0.02
TINY_ROUTE = ["ab", "bc", "cd"]
CATEGORIES = ("M1", "M2", "M3", "N", "O")
T7_TRUTH = json.loads((networks_dir() / "t7_left.truth.json").read_text())


def _node(node_id: str, x: float, y: float) -> str:
    return f'<node id="{node_id}" x="{x:.6f}" y="{y:.6f}" type="priority"/>'


def _edge(edge_id: str, from_id: str, to_id: str, xy: np.ndarray) -> str:
    return (
        f'<edge id="{edge_id}" from="{from_id}" to="{to_id}" numLanes="1" speed="27.8" spreadType="center" '
        f'shape="{shape_text(xy)}"/>'
    )


def build_straight(folder: Path) -> Path:
    """A one-way straight road A -> J -> B, dead-ending at B: no curve anywhere."""
    first, _ = sample_pieces((straight(STRAIGHT_HALF_M),), 5.0, (0.0, 0.0), 0.0)
    second, _ = sample_pieces((straight(STRAIGHT_HALF_M),), 5.0, (STRAIGHT_HALF_M, 0.0), 0.0)
    nodes = [_node("A", 0.0, 0.0), _node("J", STRAIGHT_HALF_M, 0.0), _node("B", 2 * STRAIGHT_HALF_M, 0.0)]
    edges = [_edge("aj", "A", "J", first), _edge("jb", "J", "B", second)]
    return netconvert(
        f"<nodes>{''.join(nodes)}</nodes>", f"<edges>{''.join(edges)}</edges>", folder / "straight.net.xml"
    )


def build_tiny_edge(folder: Path) -> Path:
    """A straight road a -> b -> c -> d whose middle edge is 2 cm long: netconvert makes its lanes
    and the junction lanes around it 0.1 m long with shapes of a few centimetres."""
    points = {"a": 0.0, "b": 600.0, "c": 600.0 + TINY_EDGE_M, "d": 1200.0}
    nodes = [_node(name, x, TINY_Y_M) for name, x in points.items()]
    edges = [
        _edge(f"{start}{end}", start, end, np.array([[points[start], TINY_Y_M], [points[end], TINY_Y_M]]))
        for start, end in ("ab", "bc", "cd")
    ]
    return netconvert(
        f"<nodes>{''.join(nodes)}</nodes>", f"<edges>{''.join(edges)}</edges>", folder / "tiny_edge.net.xml"
    )


@pytest.fixture(scope="module")
@marks_its_tests("sumo")
def nets(tmp_path_factory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("robust")
    return {"straight": build_straight(folder), "tiny_edge": build_tiny_edge(folder)}


@pytest.fixture(scope="module")
def straight_map(nets) -> RoadMap:
    return RoadMap.load(nets["straight"])


@pytest.fixture(scope="module")
def tiny_map(nets) -> RoadMap:
    return RoadMap.load(nets["tiny_edge"])


@pytest.fixture(scope="module")
@marks_its_tests("slow")
def server(nets, tmp_path_factory):
    running = Server([nets["straight"], nets["tiny_edge"]], tmp_path_factory.mktemp("state") / "vehicles.sqlite3")
    yield running
    running.stop()


@pytest.fixture
def client(server):
    return server.client


def _everywhere(road_map: RoadMap, route: list[str] | None) -> list[VehicleInput]:
    """Every category at 0-250 km/h at the start, middle and very end of every lane (and past it)."""
    vehicles = []
    for lane_id in road_map.lane_ids:
        length_m = road_map.lane(lane_id).length_m
        for pos_m in (0.0, length_m / 2, length_m, length_m + 10.0):
            for speed_kmh in (0.0, 60.0, 250.0):
                for category in CATEGORIES:
                    vehicles.append(
                        VehicleInput(
                            f"{lane_id}@{pos_m}/{speed_kmh}/{category}", category, speed_kmh, lane_id, pos_m, route
                        )
                    )
    return vehicles


# ------------------------------------------------------------------ a network without curves
def test_a_network_without_curves_has_none(straight_map: RoadMap) -> None:
    assert straight_map.curves(include_junctions=True) == []
    path = straight_map.path_profile(["aj_0", "jb_0"])
    assert path.curves() == []
    assert path.profile.s[-1] == pytest.approx(2 * STRAIGHT_HALF_M, abs=0.5)


@pytest.mark.parametrize("route", [None, ["aj", "jb"]], ids=["predicted", "route"])
def test_nothing_warns_on_a_network_without_curves(straight_map: RoadMap, route) -> None:
    vehicles = _everywhere(straight_map, route)
    for answer in Engine(straight_map).evaluate_many(vehicles):
        assert answer.state in (SystemState.ACTIVE, SystemState.STANDBY) and answer.fault is None
        assert int(answer.level) == 0 and answer.warning.target is None
        assert answer.path is None or answer.path.cpoi_distance_m.size == 0


def test_the_service_on_a_network_without_curves(client, straight_map: RoadMap) -> None:
    assert client.get("/v1/curves", params={"network": "straight"}).json()["features"] == []
    ahead = client.get("/v1/horizon", params={"lane_id": "aj_0", "lane_pos_m": 0.0, "length_m": 2000.0}).json()
    assert ahead["cpois"] == [] and ahead["lanes"][-1] == "jb_0"
    assert all(part["direction"] == "straight" for part in ahead["profile"])
    assert ahead["profile"][-1]["end_m"] == pytest.approx(2 * STRAIGHT_HALF_M, abs=0.5)


def test_the_very_end_of_a_dead_end_lane_through_the_service(client, straight_map: RoadMap) -> None:
    end_x, end_y = straight_map.lane_shape("jb_0")[-1]
    length_m = straight_map.lane("jb_0").length_m
    by_fix = {
        "vehicle_id": "dead-end-fix",
        "category": "N",
        "speed_kmh": 90.0,
        "position": {"x": float(end_x), "y": float(end_y)},
        "heading_deg": 90.0,
    }
    by_lane = {
        "vehicle_id": "dead-end-lane",
        "category": "N",
        "speed_kmh": 90.0,
        "lane_id": "jb_0",
        "lane_pos_m": length_m,
        "route": ["aj", "jb"],
    }
    for query in (by_fix, by_lane):
        response = client.post("/v1/warning", json=query)
        assert response.status_code == 200, response.text
        answer = response.json()
        assert (answer["state"], answer["level"], answer["target"]) == ("active", 0, None)
        assert answer["matched"]["lane_id"] == "jb_0"
        assert answer["matched"]["lane_pos_m"] == pytest.approx(length_m, abs=0.01)
    ahead = client.get("/v1/horizon", params={"lane_id": "jb_0", "lane_pos_m": length_m}).json()
    assert ahead["cpois"] == [] and ahead["length_m"] == pytest.approx(0.0, abs=0.01)


# ------------------------------------------------------------------ zero-length lanes
def test_netconvert_makes_tiny_lanes_of_a_tiny_edge(tiny_map: RoadMap) -> None:
    tiny = [lane_id for lane_id in tiny_map.lane_ids if tiny_map.lane(lane_id).shape_length_m < 0.1]
    assert "bc_0" in tiny and len(tiny) >= 3  # the edge and the junction lanes either side of it


def test_a_path_through_zero_length_lanes_is_straight_and_as_long_as_authored(tiny_map: RoadMap) -> None:
    path = tiny_map.path_profile(["ab_0", "bc_0", "cd_0"])
    assert set(path.lane_ids) > {"ab_0", "bc_0", "cd_0"}  # the junction lanes filled in
    assert path.curves() == []
    assert path.profile.s[-1] == pytest.approx(1200.0, abs=0.5)
    assert np.all(np.isinf(path.profile.radius))


@pytest.mark.parametrize("route", [None, TINY_ROUTE], ids=["predicted", "route"])
def test_vehicles_on_zero_length_lanes_are_answered(tiny_map: RoadMap, route) -> None:
    engine = Engine(tiny_map)
    for answer in engine.evaluate_many(_everywhere(tiny_map, route)):
        assert answer.fault is None
        assert answer.path is None or answer.path.path.lane_ids[-1] == "cd_0"
    before = engine.evaluate(VehicleInput("through", "N", 80.0, "ab_0", 590.0, route))
    assert before.path.path.lane_ids[-1] == "cd_0"


@pytest.mark.parametrize("route", [None, TINY_ROUTE], ids=["predicted", "route"])
def test_nothing_warns_on_a_straight_road_with_zero_length_lanes(tiny_map: RoadMap, route) -> None:
    for answer in Engine(tiny_map).evaluate_many(_everywhere(tiny_map, route)):
        assert int(answer.level) == 0, answer.vehicle_id
        assert answer.path is None or answer.path.cpoi_distance_m.size == 0, answer.vehicle_id


def test_matching_on_a_zero_length_edge(tiny_map: RoadMap) -> None:
    (nearest, *_) = tiny_map.nearest_lanes(600.0 + TINY_EDGE_M / 2, TINY_Y_M, radius_m=5.0)
    assert nearest.distance_m < 2.0


def test_the_service_answers_on_zero_length_lanes(client, tiny_map: RoadMap) -> None:
    tiny = [lane_id for lane_id in tiny_map.lane_ids if tiny_map.lane(lane_id).shape_length_m < 0.1]
    queries = [
        {
            "vehicle_id": f"tiny-{i}",
            "category": "M3",
            "speed_kmh": 70.0,
            "lane_id": lane_id,
            "lane_pos_m": pos_m,
            "route": TINY_ROUTE,
        }
        for i, (lane_id, pos_m) in enumerate(
            (lane_id, pos_m) for lane_id in tiny for pos_m in (0.0, tiny_map.lane(lane_id).length_m)
        )
    ]
    queries.append(
        {
            "vehicle_id": "tiny-fix",
            "category": "M3",
            "speed_kmh": 70.0,
            "position": {"x": 600.0 + TINY_EDGE_M / 2, "y": TINY_Y_M - 1.0},
            "heading_deg": 90.0,
        }
    )
    response = client.post("/v1/warnings", json={"queries": queries})
    assert response.status_code == 200, response.text
    assert [a["state"] for a in response.json()["answers"]] == ["active"] * len(queries)
    for lane_id in tiny:
        ahead = client.get("/v1/horizon", params={"lane_id": lane_id, "lane_pos_m": 0.0})
        assert ahead.status_code == 200 and ahead.json()["lanes"][-1] == "cd_0"


T7_ENTRY_SHAPE = 'id=":entry_0_0" index="0" speed="50.000" length="0.100" shape="900.000,0.000 900.000,0.000"'


def _t7_with_entry_shape(folder: Path, shape: str) -> Path:
    """The Table 7 track with its junction lane's shape (two identical points) replaced by ``shape``."""
    text = (networks_dir() / "t7_left.net.xml").read_text()
    assert T7_ENTRY_SHAPE in text
    net = folder / "t7_entry.net.xml"
    net.write_text(text.replace(T7_ENTRY_SHAPE, T7_ENTRY_SHAPE.replace("900.000,0.000 900.000,0.000", shape)))
    return net


def test_a_zero_length_junction_lane_keeps_the_distances_to_the_curves() -> None:
    engine = Engine(RoadMap.load(networks_dir() / "t7_left.net.xml"))
    route = T7_TRUTH["route"]["edges"]
    curve_starts_s = np.array([c["start_s"] for c in T7_TRUTH["curves"]])
    entry_s = T7_TRUTH["lanes"][1]["start_s"]  # the junction lane (two identical points) lies here
    for lane_id, pos_m, route_s in (
        ("approach_0", 850.0, 850.0),
        (":entry_0_0", 0.0, entry_s),
        (":entry_0_0", 0.1, entry_s),
    ):
        path = engine.evaluate(VehicleInput(f"on-{lane_id}", "N", 90.0, lane_id, pos_m, route)).path
        ahead_m = curve_starts_s - route_s
        assert path.cpoi_distance_m == pytest.approx(ahead_m[ahead_m <= path.lookahead_m], abs=0.5)


@pytest.mark.parametrize("shape", ["900.000,0.000", ""], ids=["one-point", "no-point"])
def test_a_lane_with_a_broken_shape_is_refused_naming_it(tmp_path: Path, shape: str) -> None:
    with pytest.raises(NetworkError, match=":entry_0_0"):
        RoadMap.load(_t7_with_entry_shape(tmp_path, shape))


# ------------------------------------------------------------------ NaN coordinates
GOOD = {"vehicle_id": "nan-probe", "category": "N", "speed_kmh": 50.0, "position": {"x": 100.0, "y": 0.0}}
NON_FINITE = {
    "x-nan": ({"position": {"x": "NaN", "y": 0.0}}, ["position", "x"]),
    "y-nan": ({"position": {"x": 100.0, "y": "NaN"}}, ["position", "y"]),
    "y-minus-infinity": ({"position": {"x": 100.0, "y": "-Infinity"}}, ["position", "y"]),
    "lon-nan": ({"position": {"lon": "NaN", "lat": 50.0}}, ["position", "lon"]),
    "lat-nan": ({"position": {"lon": 9.7, "lat": "NaN"}}, ["position", "lat"]),
    "heading-nan": ({"heading_deg": "NaN"}, ["heading_deg"]),
    "lane-pos-nan": ({"position": None, "lane_id": "aj_0", "lane_pos_m": "NaN"}, ["lane_pos_m"]),
    "lane-pos-infinity": ({"position": None, "lane_id": "aj_0", "lane_pos_m": "Infinity"}, ["lane_pos_m"]),
    "timestamp-nan": ({"timestamp_s": "NaN"}, ["timestamp_s"]),
    "age-infinity": ({"age_s": "Infinity"}, ["age_s"]),
}


def _raw_json(query: dict) -> str:
    """JSON with the non-standard NaN and Infinity tokens that Python's and JavaScript's encoders can emit."""
    text = json.dumps(query)
    for token in ("NaN", "-Infinity", "Infinity"):
        text = text.replace(f'"{token}"', token)
    return text


@pytest.mark.parametrize("changes, loc", NON_FINITE.values(), ids=NON_FINITE.keys())
def test_non_finite_numbers_get_a_422_naming_the_field(client, changes: dict, loc: list[str]) -> None:
    query = _raw_json({k: v for k, v in {**GOOD, **changes}.items() if v is not None})
    headers = {"content-type": "application/json"}
    single = client.post("/v1/warning", content=query, headers=headers)
    body = f'{{"queries": [{json.dumps(GOOD)}, {query}]}}'
    atomic = client.post("/v1/warnings?atomic=true", content=body, headers=headers)
    for response, prefix in ((single, ["body"]), (atomic, ["body", "queries", 1])):
        assert response.status_code == 422, response.text
        (error,) = response.json()["detail"]
        assert error["loc"] == prefix + loc and "finite number" in error["msg"]
    per_query = client.post("/v1/warnings", content=body, headers=headers)  # the other query is answered
    assert per_query.status_code == 200, per_query.text
    good, bad = per_query.json()["answers"]
    assert "error" not in good and bad["error"]["detail"] == atomic.json()["detail"]
    assert client.get("/healthz").json() == {"status": "ok"}


@pytest.mark.parametrize(
    "params",
    [
        {"lon": "nan", "lat": 50.0},
        {"x": 1.0, "y": "-inf"},
        {"x": 1.0, "y": 0.0, "heading_deg": "nan"},
        {"lane_id": "aj_0", "lane_pos_m": "nan"},
        {"lane_id": "aj_0", "lane_pos_m": 1.0, "length_m": "nan"},
    ],
    ids=["lon", "y", "heading", "lane-pos", "length"],
)
def test_non_finite_horizon_parameters_get_a_422(client, params: dict) -> None:
    response = client.get("/v1/horizon", params=params)
    assert response.status_code == 422 and "finite number" in response.text


def test_a_non_finite_bbox_gets_a_422(client) -> None:
    response = client.get("/v1/curves", params={"bbox": "nan,0,1,1"})
    assert response.status_code == 422 and "four finite numbers" in response.text


def test_matching_nan_coordinates_is_a_clear_value_error(straight_map: RoadMap) -> None:
    try:
        straight_map.match_points(np.array([[100.0, 0.0], [math.nan, 0.0]]), radius_m=10.0)
    except ValueError as error:
        assert "finite" in str(error)
    except Exception as error:  # noqa: BLE001 - which exception comes is the point of the test
        raise AssertionError(f"{type(error).__name__} instead of a ValueError") from error
    else:
        raise AssertionError("no error for a NaN coordinate")


def test_a_nan_lane_position_is_invalid_input() -> None:
    engine = Engine(RoadMap.load(networks_dir() / "t7_left.net.xml"))
    route = T7_TRUTH["route"]["edges"]
    lane = T7_TRUTH["lanes"][1]  # curve_0: the first curve starts 100 m into it
    before_curve_m = T7_TRUTH["curves"][0]["start_s"] - 10.0 - lane["start_s"]
    warned = engine.evaluate(VehicleInput("finite", "N", 90.0, lane["lane"], before_curve_m, route))
    assert int(warned.level) == 2  # the same query with a finite position warns
    answer = engine.evaluate(VehicleInput("nan", "N", 90.0, lane["lane"], math.nan, route))
    assert (answer.state, answer.fault) == (SystemState.FAULT, Fault.INVALID_INPUT)


# ------------------------------------------------------------------ missing and corrupt networks, every command
def _csws(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "csws", *map(str, args)], capture_output=True, text=True, timeout=120, cwd=cwd
    )


def _sumocfg(folder: Path, net: Path) -> Path:
    routes = folder / "empty.rou.xml"
    routes.write_text("<routes/>\n")
    config = folder / "scenario.sumocfg"
    config.write_text(
        f'<configuration><input><net-file value="{net}"/><route-files value="{routes}"/></input></configuration>\n'
    )
    return config


def _tracks_folder(folder: Path, net: Path) -> Path:
    """A folder of test tracks whose one track's network is ``net``."""
    index = json.loads((networks_dir() / "index.json").read_text())
    entry = next(e for e in index["networks"] if e["name"] == "t7_left")
    tracks = folder / "tracks"
    tracks.mkdir()
    (tracks / entry["truth_file"]).write_text((networks_dir() / entry["truth_file"]).read_text())
    (tracks / "index.json").write_text(json.dumps({**index, "networks": [{**entry, "net_file": str(net)}]}))
    return tracks


COMMANDS = {
    "curves": lambda net, folder: ["curves", net],
    "serve": lambda net, folder: ["serve", "--net", net, "--state-db", ":memory:", "--port", "0"],
    "cosim --net": lambda net, folder: [
        "cosim",
        "--net",
        net,
        "--routes",
        _sumocfg(folder, net).with_name("empty.rou.xml"),
        "--out",
        folder / "out",
    ],
    "cosim --sumocfg": lambda net, folder: ["cosim", "--sumocfg", _sumocfg(folder, net), "--out", folder / "out"],
    "fleet-scenario": lambda net, folder: ["fleet-scenario", net, "-o", folder / "fleet"],
    "networks verify": lambda net, folder: ["networks", "verify", "--dir", _tracks_folder(folder, net)],
}


def _truncated(folder: Path) -> Path:
    net = folder / "truncated.net.xml"
    net.write_bytes((networks_dir() / "t7_left.net.xml").read_bytes()[:3000])
    return net


@pytest.mark.slow
@pytest.mark.parametrize("damage", ["missing", "truncated"])
@pytest.mark.parametrize("command", COMMANDS.values(), ids=COMMANDS.keys())
def test_a_missing_or_corrupt_network_is_one_line_for_every_command(tmp_path: Path, command, damage: str) -> None:
    net = tmp_path / "missing.net.xml" if damage == "missing" else _truncated(tmp_path)
    result = _csws(*command(net, tmp_path), cwd=tmp_path)
    assert result.returncode == 2, result.stdout + result.stderr
    assert result.stderr.count("\n") == 1 and result.stderr.startswith("csws: error: "), result.stderr
    assert net.name in result.stderr


def test_a_network_with_a_nan_shape_is_one_line_naming_the_file(tmp_path: Path) -> None:
    net = _t7_with_entry_shape(tmp_path, "nan,0.000 900.000,0.000")
    result = _csws("curves", net, cwd=tmp_path)
    assert result.returncode == 2 and result.stderr.count("\n") == 1
    assert result.stderr.startswith("csws: error: ") and net.name in result.stderr


@pytest.mark.slow
def test_a_corrupt_settings_database_is_one_line(tmp_path: Path) -> None:
    state_db = tmp_path / "vehicles.sqlite3"
    state_db.write_bytes(b"not a database " * 100)
    result = _csws(
        "serve", "--net", networks_dir() / "t7_left.net.xml", "--state-db", state_db, "--port", "0", cwd=tmp_path
    )
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1 and result.stderr.startswith("csws: error: ")
    assert state_db.name in result.stderr
