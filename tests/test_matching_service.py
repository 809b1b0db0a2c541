"""Map matching over the fix sequence in the service: ``POST /v1/match`` for a whole trace, and the
``POST /v1/warnings`` batches of a fleet whose matching state lives in each vehicle's session, on both
state stores and through two workers. The network is the junction town of tests/junction_town.py; the
truth is the path each constructed drive takes (σ 3 m fixes at 1 Hz, fixed seeds)."""

from __future__ import annotations

import threading
from pathlib import Path

import httpx
import numpy as np
import pytest
from fastapi.testclient import TestClient
from junction_town import drive, write_junction_town
from markers import marks_its_tests
from servers import Workers, state_options

from csws.road.roadmap import RoadMap
from service.app import create_app
from service.settings import ServiceSettings

SPEED_MPS = 19.4  # 70 km/h: the side streets' R 20 m curves warn at level 2 from their connections
SIDE_STREETS = ("JS_0", "JN_0")


@pytest.fixture(scope="module")
@marks_its_tests("sumo")
def town_net(tmp_path_factory) -> Path:
    return write_junction_town(tmp_path_factory.mktemp("town"))


@pytest.fixture(scope="module")
def town(town_net: Path) -> RoadMap:
    return RoadMap.load(town_net)


@pytest.fixture(scope="module")
def client(town_net: Path, tmp_path_factory):
    settings = ServiceSettings(nets=[town_net], state_db=str(tmp_path_factory.mktemp("state") / "v.sqlite3"))
    with TestClient(create_app(settings)) as test_client:
        yield test_client


def _trace_fixes(route, with_speed: bool = True) -> list[dict]:
    return [
        {
            "position": {"x": float(x), "y": float(y)},
            "timestamp_s": float(t),
            "heading_deg": float(h),
            **({"speed_kmh": SPEED_MPS * 3.6} if with_speed else {}),
            "accuracy_m": 3.0,
        }
        for (x, y), t, h in zip(route.xy, route.time_s, route.heading_deg, strict=True)
    ]


def _query(vehicle_id: str, route, k: int) -> dict:
    x, y = route.xy[k]
    return {
        "vehicle_id": vehicle_id,
        "category": "M1",
        "speed_kmh": SPEED_MPS * 3.6,
        "position": {"x": float(x), "y": float(y)},
        "heading_deg": float(route.heading_deg[k]),
        "timestamp_s": 1000.0 + float(route.time_s[k]),
        "accuracy_m": 3.0,
    }


# ------------------------------------------------------------------ POST /v1/match
@pytest.mark.parametrize("to_lane", ["JE_0", "JS_0"])
def test_a_trace_is_matched_on_the_path_driven(client, town: RoadMap, to_lane: str) -> None:
    path = town.expand_path(["WJ_0", to_lane])
    for seed in range(5):
        route = drive(town, ["WJ_0", to_lane], SPEED_MPS, seed)
        response = client.post("/v1/match", json={"fixes": _trace_fixes(route, with_speed=seed % 2 == 0)})
        assert response.status_code == 200, response.text
        matched = response.json()["matched"]
        assert len(matched) == len(route.time_s)
        assert {fix["lane_id"] for fix in matched} <= set(path)
        for fix in matched:
            assert fix["network"] == "town" and fix["placed"] == "matched" and fix["reason"] is None
            assert fix["edge_id"] == town.lane(fix["lane_id"]).edge_id
            point = np.array([fix["point"]["x"], fix["point"]["y"]])
        # The matched point of the last fix lies on its lane within the noise of the fix.
        assert np.hypot(*(point - route.xy[-1])) == pytest.approx(matched[-1]["distance_m"], abs=1e-6)
        assert matched[-1]["distance_m"] < 4 * 3.0


def test_a_long_trace_never_holds_up_the_warnings(client, town: RoadMap, monkeypatch) -> None:
    """A trace is matched on a thread of its own: a warning asked while a trace is being matched is answered
    before the trace is (here the trace waits until the warning has been answered)."""
    import service.routes.match as match_route

    started, release = threading.Event(), threading.Event()
    original = match_route.match_trace

    def held(placer, trace):
        started.set()
        assert release.wait(30.0), "the warning was not answered while the trace was matched"
        return original(placer, trace)

    monkeypatch.setattr(match_route, "match_trace", held)
    route = drive(town, ["WJ_0", "JE_0"], SPEED_MPS, 0)
    traced: dict[str, httpx.Response] = {}
    thread = threading.Thread(
        target=lambda: traced.update(answer=client.post("/v1/match", json={"fixes": _trace_fixes(route)}))
    )
    thread.start()
    assert started.wait(30.0)
    warned = client.post("/v1/warning", json=_query("while-tracing", route, 0))
    assert warned.status_code == 200 and thread.is_alive()
    release.set()
    thread.join(30.0)
    assert traced["answer"].status_code == 200 and len(traced["answer"].json()["matched"]) == len(route.time_s)


def test_a_late_fix_is_stale_and_leaves_the_vehicle_where_its_newest_fix_put_it(client, town: RoadMap) -> None:
    """Fixes along the main road at 1 s, then one taken 5 s before the newest (sent late): it is answered stale,
    the live map keeps the vehicle at its newest fix, and the next fix confirms the newest, not the late one."""
    route = drive(town, ["WJ_0", "JE_0"], SPEED_MPS, 11)
    answers = [client.post("/v1/warning", json=_query("late", route, k)).json() for k in range(6)]
    newest = answers[-1]["matched"]
    late = client.post("/v1/warning", json=_query("late", route, 0)).json()
    assert late["state"] == "fault" and late["fault_code"] is not None and "stale" in late["fault"]
    [shown] = [f for f in client.get("/v1/fleet", params={"network": "town"}).json()["features"] if f["id"] == "late"]
    assert shown["properties"]["lane_id"] == newest["lane_id"]
    assert shown["properties"]["timestamp_s"] == 1000.0 + float(route.time_s[5])  # its latest answer too
    assert shown["geometry"]["coordinates"] == pytest.approx([newest["position"]["x"], newest["position"]["y"]])
    following = client.post("/v1/warning", json=_query("late", route, 6)).json()
    assert following["confirmed"]["timestamp_s"] == 1000.0 + float(route.time_s[5])


def test_fixes_that_come_too_old_are_stale_but_still_move_the_vehicle_on_the_live_map(client, town: RoadMap) -> None:
    """Fixes in time order whose age is over 2 s are stale (no warning from them), yet each is the vehicle's newest
    position: the live map shows it there."""
    route = drive(town, ["WJ_0", "JE_0"], SPEED_MPS, 12)
    for k in range(6):
        answer = client.post("/v1/warning", json={**_query("old", route, k), "age_s": 5.0}).json()
        assert answer["state"] == "fault" and "stale" in answer["fault"]
    fleet = client.get("/v1/fleet", params={"network": "town"}).json()["features"]
    [shown] = [f for f in fleet if f["id"] == "old"]
    assert shown["properties"]["timestamp_s"] == 1000.0 + float(route.time_s[5])
    matched = answer["matched"]
    assert shown["geometry"]["coordinates"] == pytest.approx([matched["position"]["x"], matched["position"]["y"]])


def test_a_trace_matching_nothing_says_why(client) -> None:
    far = [{"position": {"x": 5000.0, "y": 5000.0}, "timestamp_s": 0.0}]
    (fix,) = client.post("/v1/match", json={"fixes": far}).json()["matched"]
    assert fix["lane_id"] is None and fix["placed"] is None and fix["reason"] == "no lane within 10 m"


@pytest.mark.parametrize(
    ("fixes", "network", "loc"),
    [
        ([{"position": {"x": 1.0}, "timestamp_s": 0.0}], None, ["body", "fixes", 0, "position"]),
        ([{"position": {"x": 1.0, "y": 2.0}}], None, ["body", "fixes", 0, "timestamp_s"]),
        (
            [{"position": {"x": 1.0, "y": 2.0}, "timestamp_s": 0.0, "accuracy_m": 0.0}],
            None,
            ["body", "fixes", 0, "accuracy_m"],
        ),
        (
            [{"position": {"x": 1.0, "y": 2.0}, "timestamp_s": 0.0, "heading_deg": 360.0}],
            None,
            ["body", "fixes", 0, "heading_deg"],
        ),
        ([{"position": {"x": 1.0, "y": 2.0}, "timestamp_s": "0"}], None, ["body", "fixes", 0, "timestamp_s"]),
        (
            [
                {"position": {"x": 1.0, "y": 2.0}, "timestamp_s": 1.0},
                {"position": {"x": 1.0, "y": 2.0}, "timestamp_s": 0.5},
            ],
            None,
            ["body", "fixes"],
        ),
        ([], None, ["body", "fixes"]),
        ([{"position": {"lon": 9.0, "lat": 50.0}, "timestamp_s": 0.0}], None, ["body", "fixes", 0, "position"]),
        ([{"position": {"x": 1.0, "y": 2.0}, "timestamp_s": 0.0}], "elsewhere", ["body", "network"]),
    ],
)
def test_bad_fixes_get_a_422_naming_them(client, fixes, network, loc) -> None:
    body = {"fixes": fixes, **({"network": network} if network else {})}
    response = client.post("/v1/match", json=body)
    assert response.status_code == 422
    assert any(error["loc"][: len(loc)] == loc for error in response.json()["detail"]), response.json()


def test_a_body_that_is_not_json_gets_a_422(client) -> None:
    response = client.post("/v1/match", content=b"\x03fixes", headers={"Content-Type": "application/json"})
    assert response.status_code == 422 and response.json()["detail"][0]["loc"][0] == "body"


# ------------------------------------------------------------------ POST /v1/warnings with sessions
def _batches(town: RoadMap) -> tuple[list[list[dict]], dict[str, list[str]]]:
    """One batch a second of vehicles driving straight on and turning into each side street, and the true lane of
    each vehicle at each fix."""
    routes = {
        f"{kind}-{seed}": drive(town, ["WJ_0", to_lane], SPEED_MPS, seed)
        for seed in range(4)
        for kind, to_lane in (("straight", "JE_0"), ("south", "JS_0"), ("north", "JN_0"))
    }
    steps = min(len(route.time_s) for route in routes.values())
    batches = [[_query(vehicle_id, route, k) for vehicle_id, route in routes.items()] for k in range(steps)]
    return batches, {vehicle_id: route.lane_id[:steps] for vehicle_id, route in routes.items()}


def _check_answers(town: RoadMap, answers_by_step: list[list[dict]], truth: dict[str, list[str]]) -> None:
    """Straight-on vehicles never matched onto a side street or its connection nor warned of its curve; turning
    ones on their side street (or the connection into it) from their first fix there; from the second fix on,
    each answer confirms the vehicle's previous fix on the path it drives."""
    side_lanes = {lane for side in SIDE_STREETS for lane in town.expand_path(["WJ_0", side])[1:]}
    side_roads = {town.lane(side).edge_id for side in SIDE_STREETS}
    answered: dict[tuple[str, float], str] = {}
    for k, answers in enumerate(answers_by_step):
        for answer in answers:
            vehicle_id = answer["vehicle_id"]
            assert answer["state"] == "active" and answer["matched"] is not None, answer
            lane_id = answer["matched"]["lane_id"]
            triggered = {trigger["curve_id"].split("@")[0] for trigger in answer["triggers"]}
            if vehicle_id.startswith("straight"):
                assert lane_id not in side_lanes and not triggered & side_roads, answer
            true_lane = truth[vehicle_id][k]
            if true_lane in SIDE_STREETS:
                assert lane_id in town.expand_path(["WJ_0", true_lane])[1:], (vehicle_id, k, answer)
            _check_confirmed(town, answer, answered, k)
            answered[(vehicle_id, 1000.0 + k)] = lane_id


def _check_confirmed(town: RoadMap, answer: dict, answered: dict[tuple[str, float], str], k: int) -> None:
    """An answer's confirmed fix: none for a vehicle's first fix; else an earlier fix of the vehicle, placed on
    the path it drives, revised exactly where that fix was answered on another lane."""
    confirmed = answer.get("confirmed")
    if k == 0:
        assert confirmed is None, answer
        return
    assert confirmed is not None, answer
    vehicle_id = answer["vehicle_id"]
    to_lane = {"straight": "JE_0", "south": "JS_0", "north": "JN_0"}[vehicle_id.split("-")[0]]
    assert confirmed["lane_id"] in town.expand_path(["WJ_0", to_lane]), answer
    assert confirmed["revised"] == (confirmed["lane_id"] != answered[(vehicle_id, confirmed["timestamp_s"])])


def _lost_batch(batch: list[dict]) -> list[dict]:
    """The batch one second later with every fix 40 m or more off any road (multipath)."""
    return [
        {
            **query,
            "timestamp_s": query["timestamp_s"] + 1.0,
            "position": {"x": query["position"]["x"], "y": query["position"]["y"] + 100.0},
        }
        for query in batch
    ]


def _check_dead_reckoned(town: RoadMap, answers: list[dict], before: list[dict]) -> None:
    """Each vehicle whose fix matched no lane is placed by dead reckoning from its last match, as far on along
    the road as one second at its speed, not in fault."""
    for answer, previous in zip(answers, before, strict=True):
        assert answer["state"] == "active" and answer["fault"] is None, answer
        lane_id, pos_m = answer["matched"]["lane_id"], answer["matched"]["lane_pos_m"]
        last_lane, last_pos_m = previous["matched"]["lane_id"], previous["matched"]["lane_pos_m"]
        assert lane_id == last_lane and pos_m == pytest.approx(last_pos_m + SPEED_MPS, abs=0.01), answer


def test_warning_batches_match_over_each_vehicles_sequence(client, town: RoadMap) -> None:
    batches, truth = _batches(town)
    answers = []
    for batch in batches:
        response = client.post("/v1/warnings", json={"queries": batch})
        assert response.status_code == 200, response.text
        answers.append(response.json()["answers"])
    _check_answers(town, answers, truth)
    warned = {a["vehicle_id"] for step in answers for a in step if a["level"] == 2}
    assert {v for v in truth if not v.startswith("straight")} <= warned  # the turning ones are warned of their curve
    lost = client.post("/v1/warnings", json={"queries": _lost_batch(batches[-1])}).json()["answers"]
    _check_dead_reckoned(town, lost, answers[-1])
    # A vehicle without a sequence has nothing to dead-reckon from: the same fix is a fault.
    (fresh,) = client.post(
        "/v1/warnings", json={"queries": [{**_lost_batch(batches[-1])[0], "vehicle_id": "new"}]}
    ).json()["answers"]
    assert fresh["state"] == "fault" and fresh["fault"].endswith("no lane within 10 m")


@pytest.fixture
@marks_its_tests("slow")
def workers(state, town_net):
    running = Workers([town_net], *state_options(state))
    yield running
    running.stop()


def test_the_matching_state_survives_two_workers(workers, town: RoadMap) -> None:
    # Each batch goes to the other worker: the sequence of every vehicle is carried by its session in the store.
    clients = workers.clients()
    batches, truth = _batches(town)
    answers = []
    for k, batch in enumerate(batches):
        response = clients[k % 2].post("/v1/warnings", json={"queries": batch})
        assert response.status_code == 200, response.text
        answers.append(response.json()["answers"])
    _check_answers(town, answers, truth)
    # Dead reckoning needs the last match, which the other worker made.
    lost = clients[len(batches) % 2].post("/v1/warnings", json={"queries": _lost_batch(batches[-1])}).json()["answers"]
    _check_dead_reckoned(town, lost, answers[-1])
