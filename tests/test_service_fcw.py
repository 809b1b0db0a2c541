"""The service's forward_target: the answer's fcw is the library's, from the seed's formulas; the
curve warning's answers are unchanged without one; bad targets are a 422 that names the field."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from fastapi.testclient import TestClient
from fcw_queries import N_SETTINGS, TRACK_NET, fcw_query, stopped_car, stopped_car_level
from hypothesis import given
from hypothesis import strategies as st
from servers import Workers, state_options

from csws.engine import VehicleInput
from csws.fcw.objects import EgoMotion, SensorObject
from csws.fcw.path import (
    PathCurvature,
    equivalent_curvature_1pm,
    offset_from_circle_m,
    path_curvature_ahead,
    path_table,
)
from csws.fcw.physics import evaluate_fcw
from csws.fcw.tracker import ForwardCollisionWarning
from csws.networks import networks_dir
from csws.standard import Level
from csws.warning.rules import HmiHint
from service.answer_schemas import FcwAnswer
from service.app import create_app
from service.fcw import FCW_HMI_HINTS, combined_hmi
from service.fcw_objects import _ids_by_row, _json_values, _keys, _paths
from service.networks import load_networks
from service.schemas import MAX_OBJECT_ID, MAX_OBJECTS, ForwardTarget
from service.settings import ServiceSettings

T7_NET = networks_dir() / "t7_left.net.xml"


@pytest.fixture
def client(tmp_path):
    settings = ServiceSettings(nets=[TRACK_NET], state_db=str(tmp_path / "vehicles.sqlite3"))
    with TestClient(create_app(settings)) as client:
        yield client


def test_a_forward_target_gets_the_fcw_of_the_seeds_formulas(client):
    target = {"range_m": 40.0, "range_rate_mps": -15.0, "target_accel_mps2": -1.0}
    answer = client.post("/v1/warning", json=fcw_query("truck-1", forward_target=target)).json()
    fcw = answer["fcw"]
    assert fcw["ttc_s"] == pytest.approx(40.0 / 15.0)  # formula (2)
    assert fcw["ettc_s"] == pytest.approx((15.0 - math.sqrt(15.0**2 + 2.0 * 1.0 * 40.0)) / -1.0)  # formula (3)
    # formula (4) at the end of T_resp 1.2 s, the lead braking at 1 m/s^2 through it: closing 15 + 1.2 m/s,
    # clearance 40 - 15 * 1.2 - 1.2**2 / 2 m
    assert fcw["a_req_mps2"] == pytest.approx(1.0 + (15.0 + 1.2) ** 2 / (2.0 * (40.0 - 15.0 * 1.2 - 1.2**2 / 2.0)))
    library = evaluate_fcw([0.0], [40.0], [-15.0], [-1.0], [False])
    assert (fcw["state"], fcw["level"]) == ("active", int(library.level[0])) == ("active", 2)
    assert "level" in answer and answer["vehicle_id"] == "truck-1"


def test_the_batch_answers_fcw_only_where_asked_and_the_state_follows_the_speed(client):
    queries = [
        fcw_query("a"),
        fcw_query("b", speed_kmh=20.0, forward_target={"range_m": 10.0, "range_rate_mps": -5.0}),
        fcw_query("c", forward_target={"range_m": 10.0, "range_rate_mps": -5.0, "measured": False}),
        fcw_query("d", forward_target={"range_m": 80.0, "range_rate_mps": 2.0}),
    ]
    answers = client.post("/v1/warnings", json={"queries": queries}).json()["answers"]
    assert "fcw" not in answers[0]
    assert [(a["fcw"]["state"], a["fcw"]["level"]) for a in answers[1:]] == [
        ("standby", 0),
        ("fault", 0),
        ("active", 0),
    ]
    assert answers[3]["fcw"]["ttc_s"] is None  # opening: no collision


def test_without_a_forward_target_the_answer_is_as_before(client):
    plain = client.post("/v1/warning", json=fcw_query("e")).content
    assert b"fcw" not in plain


@pytest.mark.parametrize(
    ("target", "field"),
    [
        ({"range_rate_mps": -5.0}, "range_m"),
        ({"range_m": -1.0, "range_rate_mps": -5.0}, "range_m"),
        ({"range_m": 10.0, "range_rate_mps": "fast"}, "range_rate_mps"),
        ({"range_m": 10.0, "range_rate_mps": -5.0, "measured": 1}, "measured"),
    ],
)
def test_a_bad_forward_target_is_a_422_naming_the_field(client, target, field):
    body = json.dumps({"queries": [fcw_query("f", forward_target=target)]}).encode()
    locs = [error["loc"] for error in _refused(client, body)]
    assert ["body", "queries", 0, "forward_target", field] in locs


def _refused(client, body: bytes) -> list[dict]:
    """The problems of a batch of one bad query: the 422 of an all-or-nothing batch (``?atomic=true``), which the
    error entry of the batch answered per query lists alike."""
    headers = {"content-type": "application/json"}
    atomic = client.post("/v1/warnings?atomic=true", content=body, headers=headers)
    assert atomic.status_code == 422
    per_query = client.post("/v1/warnings", content=body, headers=headers)
    assert per_query.status_code == 200
    [entry] = per_query.json()["answers"]
    assert entry["index"] == 0 and entry["error"]["detail"] == atomic.json()["detail"]
    return atomic.json()["detail"]


def test_the_schema_examples_of_a_target_and_its_answer_agree(client):
    """The OpenAPI example of an fcw answer is what the service answers to the example target."""
    target = ForwardTarget.model_config["json_schema_extra"]["examples"][0]
    answer = client.post("/v1/warning", json=fcw_query("truck-ex", speed_kmh=60.0, forward_target=target)).json()["fcw"]
    example = FcwAnswer.model_config["json_schema_extra"]["examples"][0]
    assert {name: answer[name] for name in ("state", "level")} == {name: example[name] for name in ("state", "level")}
    for name in ("ttc_s", "ettc_s", "a_req_mps2"):
        assert answer[name] == pytest.approx(example[name], abs=0.005)


# ------------------------------------------------------------------ objects: the service selects the target


def _library_frame(time_s: float, speed_mps: float, objects: list[dict], tracker: ForwardCollisionWarning):
    return tracker.update(
        time_s,
        EgoMotion(speed_mps),
        [SensorObject(o["id"], o["x_m"], o["y_m"], o["relative_speed_mps"], o.get("accel_mps2", 0.0)) for o in objects],
    )


@pytest.mark.parametrize("x_m", [25.0, 40.0, 55.0, 70.0, 120.0])
def test_a_stopped_car_ahead_warns_at_the_level_of_formula_4_and_of_the_library(client, x_m):
    speed_mps = 20.0
    car = stopped_car(x_m, speed_mps)
    answer = client.post("/v1/warning", json=fcw_query(f"car-{x_m}", speed_kmh=72.0, objects=[car])).json()
    fcw = answer["fcw"]
    library = _library_frame(1.0, speed_mps, [car], ForwardCollisionWarning(N_SETTINGS))
    assert fcw["level"] == library.level == stopped_car_level(x_m, speed_mps)
    assert (fcw["state"], fcw["target_id"], fcw["clearance_m"]) == ("active", 7, x_m)
    assert fcw["ttc_s"] == pytest.approx(x_m / speed_mps)  # formula (2)
    assert fcw["a_req_mps2"] == pytest.approx(speed_mps**2 / (2.0 * (x_m - 1.2 * speed_mps)))  # formula (4)


def test_the_target_is_the_most_demanding_object_in_the_path(client):
    speed_mps = 20.0
    beside = {**stopped_car(20.0, speed_mps, object_id=1), "y_m": 3.5}  # the next lane: not in the path
    ahead_far = stopped_car(90.0, speed_mps, object_id=2)
    braking_lead = {"id": 3, "x_m": 45.0, "y_m": 0.3, "relative_speed_mps": -2.0, "accel_mps2": -6.0}
    objects = [beside, ahead_far, braking_lead]
    fcw = client.post("/v1/warning", json=fcw_query("pick", objects=objects)).json()["fcw"]
    # 3.22: the braking lead (18 m/s at 6 m/s^2) stops 27 m on, 72 m ahead, before the speeds could meet; the
    # subject, 24 m on after the 1.2 s reaction, must stop in the 48 m left (formula (4), d_TV held for ever,
    # would ask 6 + 9.2^2 / (2 (45 - 6.72)) = 7.1 m/s^2).
    lead_stop_m = 45.0 + 18.0**2 / (2.0 * 6.0)
    a_req = {2: speed_mps**2 / (2.0 * (90.0 - 1.2 * speed_mps)), 3: speed_mps**2 / (2.0 * (lead_stop_m - 24.0))}
    assert fcw["target_id"] == max(a_req, key=a_req.__getitem__) == 3
    assert fcw["a_req_mps2"] == pytest.approx(a_req[3])


def test_the_map_path_on_a_curve_keeps_the_own_lane_and_drops_the_next_one(client):
    """On R 120 m, 40 m ahead, the own lane is 7 m left of a straight beam: the map's curvature finds it."""
    radius_m, speed_mps = 120.0, 20.0

    def on_arc(arc_m: float, lateral_m: float) -> tuple[float, float]:
        """The rear's range and the centre's lateral position of a car on a circle ``lateral_m`` outside the path."""
        centre_arc = arc_m + N_SETTINGS.object_half_length_m
        r = radius_m - lateral_m
        return r * math.sin(centre_arc / radius_m) - N_SETTINGS.object_half_length_m, radius_m - r * math.cos(
            centre_arc / radius_m
        )

    x_own, y_own = on_arc(40.0, 0.0)
    x_next, y_next = on_arc(40.0, -3.5)
    objects = [
        {"id": 1, "x_m": x_own, "y_m": y_own, "relative_speed_mps": -speed_mps},
        {"id": 2, "x_m": x_next, "y_m": y_next, "relative_speed_mps": -speed_mps},
    ]
    on_curve = {"lane_id": "curve_0", "lane_pos_m": 110.0}  # the lane's R 120 m arc runs from 100 m to 196 m
    own = client.post("/v1/warning", json={**fcw_query("bend", **on_curve), "objects": objects}).json()["fcw"]
    assert (own["target_id"], own["level"]) == (1, stopped_car_level(x_own, speed_mps))
    alone = [objects[1]]
    next_lane = client.post("/v1/warning", json={**fcw_query("bend-2", **on_curve), "objects": alone}).json()["fcw"]
    assert (next_lane["target_id"], next_lane["level"]) == (None, 0)


def test_the_level_is_held_across_queries_as_the_library_holds_it(client):
    """A collision warning stays on for the hold after the object leaves, then goes: as the library's tracker."""
    speed_mps, hold_s = 20.0, N_SETTINGS.level_hold_s
    tracker = ForwardCollisionWarning(N_SETTINGS)
    frames = [(10.0, [stopped_car(30.0, speed_mps)]), (10.1, []), (10.0 + hold_s - 0.05, []), (10.0 + hold_s, [])]
    levels = []
    for time_s, objects in frames:
        answer = client.post("/v1/warning", json=fcw_query("held", timestamp_s=time_s, objects=objects)).json()
        levels.append((answer["fcw"]["level"], _library_frame(time_s, speed_mps, objects, tracker).level))
    assert levels == [(2, 2), (2, 2), (2, 2), (0, 0)]


def test_a_query_not_after_the_last_frame_changes_nothing_kept(client):
    speed_mps = 20.0
    client.post("/v1/warning", json=fcw_query("late", timestamp_s=5.0, objects=[stopped_car(30.0, speed_mps)]))
    # An older frame without objects is answered from the kept hold, and does not end it.
    assert client.post("/v1/warning", json=fcw_query("late", timestamp_s=4.0, objects=[])).json()["fcw"]["level"] == 2
    assert client.post("/v1/warning", json=fcw_query("late", timestamp_s=5.3, objects=[])).json()["fcw"]["level"] == 2


def test_a_batch_with_objects_answers_each_vehicle_as_the_library(client):
    speed_mps = 20.0
    distances = {"b1": 25.0, "b2": 45.0, "b3": 60.0, "b4": 150.0}
    queries = [
        fcw_query(
            vehicle_id,
            category=category,
            objects=[stopped_car(x_m, speed_mps), {**stopped_car(10.0, 0.0), "id": 9, "y_m": -4.0}],
        )
        for (vehicle_id, x_m), category in zip(distances.items(), ["N", "M1", "M3", "O"], strict=True)
    ]
    queries.append(fcw_query("plain"))
    answers = client.post("/v1/warnings", json={"queries": queries}).json()["answers"]
    for answer, (vehicle_id, x_m) in zip(answers, distances.items(), strict=False):
        assert answer["vehicle_id"] == vehicle_id
        assert (answer["fcw"]["level"], answer["fcw"]["target_id"]) == (
            stopped_car_level(x_m, speed_mps),
            7 if x_m < N_SETTINGS.range_m else None,
        )
    assert "fcw" not in answers[-1]


def test_v_max_comes_from_the_category(client):
    """4.3.3: at 120 km/h a car (V_max 250 km/h) is active, a truck (V_max 27.8 m/s + delta) on standby."""
    car = [stopped_car(150.0, 120.0 / 3.6)]
    states = {
        category: client.post(
            "/v1/warning", json=fcw_query(f"vmax-{category}", speed_kmh=120.0, category=category, objects=car)
        ).json()["fcw"]["state"]
        for category in ("M1", "N")
    }
    assert states == {"M1": "active", "N": "standby"}


@pytest.fixture
def workers(state):
    running = Workers([Path(TRACK_NET)], *state_options(state))
    yield running
    running.stop()


def test_the_hold_is_kept_across_two_workers(workers):
    """Frames alternate between two workers (SQLite and Redis): each takes up the hold the other left, as the
    library's one tracker does; the cut-in memory (4.5.5 c) too."""
    first, second = workers.clients()
    speed_mps, hold_s = 20.0, N_SETTINGS.level_hold_s
    tracker = ForwardCollisionWarning(N_SETTINGS)
    frames = [
        (10.0, [stopped_car(30.0, speed_mps)]),
        (10.1, []),
        (10.0 + hold_s - 0.05, []),
        (10.0 + hold_s, []),
        # a lead already in the path that brakes hard while still faster is warned of: it is no cut-in
        # (4.5.5 c), which the worker answering the second frame knows only from the session
        (11.0, [{"id": 5, "x_m": 30.0, "y_m": 0.0, "relative_speed_mps": -1.0}]),
        (11.1, [{"id": 5, "x_m": 6.0, "y_m": 0.0, "relative_speed_mps": 1.0, "accel_mps2": -6.0}]),
        # a car coming into the path faster and braking is a cut-in, and stays one in the next frame
        (12.0, [{"id": 6, "x_m": 8.0, "y_m": 4.0, "relative_speed_mps": 1.0, "accel_mps2": -6.0}]),
        (12.1, [{"id": 6, "x_m": 8.0, "y_m": 0.0, "relative_speed_mps": 1.0, "accel_mps2": -6.0}]),
        (12.2, [{"id": 6, "x_m": 8.1, "y_m": 0.0, "relative_speed_mps": 1.0, "accel_mps2": -6.0}]),
    ]
    levels, targets = [], []
    for step, (time_s, objects) in enumerate(frames):
        client = (first, second)[step % 2]
        fcw = client.post("/v1/warning", json=fcw_query("shared", timestamp_s=time_s, objects=objects)).json()["fcw"]
        library = _library_frame(time_s, speed_mps, objects, tracker)
        levels.append((fcw["level"], library.level))
        targets.append((fcw["target_id"], library.target_id))
    assert levels == [(2, 2), (2, 2), (2, 2), (0, 0), (0, 0), (2, 2), (0, 0), (0, 0), (0, 0)]
    assert [served for served, _ in targets] == [library for _, library in targets]
    assert [served for served, _ in targets] == [7, None, None, None, 5, 5, None, None, None]


# ------------------------------------------------------------------ the answer's hmi
@pytest.mark.parametrize("curve_level", [0, 1, 2])
@pytest.mark.parametrize("fcw_level", [0, 1, 2])
def test_the_hmi_is_the_more_urgent_warning(curve_level, fcw_level):
    order = [("curve", 1), ("fcw", 1), ("curve", 2), ("fcw", 2)]  # least urgent first (docs/service.md)
    shown = max([("curve", curve_level), ("fcw", fcw_level)], key=lambda s: order.index(s) if s[1] else -1)
    hint = combined_hmi(curve_level, fcw_level)
    expected = FCW_HMI_HINTS[fcw_level] if shown[0] == "fcw" and fcw_level else HmiHint.for_level(Level(curve_level))
    assert hint == expected


@pytest.fixture
def curve_client(tmp_path):
    settings = ServiceSettings(nets=[str(T7_NET)], state_db=str(tmp_path / "vehicles.sqlite3"))
    with TestClient(create_app(settings)) as client:
        yield client


def test_the_answer_shows_the_fcw_over_the_curve_warning_by_the_priority(curve_client):
    """15 m before curve 1 of Table 7 at 80 km/h a truck gets the curve's level 2; a car 16.5 m ahead closing at
    8 m/s a
    preliminary collision warning (level 1), one stopped 28 m ahead a collision warning (level 2)."""
    speed_mps = 80.0 / 3.6
    at_curve = {"category": "N", "speed_kmh": 80.0, "lane_id": "curve_0", "lane_pos_m": 85.0, "timestamp_s": 1.0}
    levels = {}
    for name, objects in (
        ("none", []),
        ("slower", [stopped_car(16.5, 8.0)]),
        ("near", [stopped_car(28.0, speed_mps)]),
    ):
        answer = curve_client.post("/v1/warning", json={"vehicle_id": name, **at_curve, "objects": objects}).json()
        levels[name] = (answer["level"], answer["fcw"]["level"], answer["hmi"])
    curve_2 = {"visual": "curve-warning-red-flashing", "audible": "warning-tone"}
    fcw_2 = {"visual": FCW_HMI_HINTS[2].visual, "audible": FCW_HMI_HINTS[2].audible}
    assert levels == {"none": (2, 0, curve_2), "slower": (2, 1, curve_2), "near": (2, 2, fcw_2)}
    assert stopped_car_level(16.5, 8.0) == 1 and stopped_car_level(28.0, speed_mps) == 2


def test_an_fcw_level_without_a_curve_warning_shows_in_the_hmi(client):
    answer = client.post("/v1/warning", json=fcw_query("alone", objects=[stopped_car(67.0, 20.0)])).json()
    assert (answer["level"], answer["fcw"]["level"]) == (0, stopped_car_level(67.0, 20.0)) == (0, 1)
    assert answer["hmi"] == {"visual": FCW_HMI_HINTS[1].visual, "audible": FCW_HMI_HINTS[1].audible}


# ------------------------------------------------------------------ 422
def _post_objects(client, objects) -> list[dict]:
    return _refused(client, json.dumps({"queries": [fcw_query("bad", objects=objects)]}).encode())


def test_an_object_with_nan_is_a_422_naming_the_field(client):
    errors = _post_objects(client, [{**stopped_car(30.0, 20.0), "x_m": math.nan}])
    assert ["body", "queries", 0, "objects", 0, "x_m"] in [e["loc"] for e in errors]


def test_duplicate_object_ids_are_a_422_naming_them(client):
    errors = _post_objects(client, [stopped_car(30.0, 20.0), stopped_car(50.0, 20.0)])
    (error,) = errors
    assert error["loc"] == ["body", "queries", 0, "objects"] and "duplicate id(s) [7]" in error["msg"]


def test_more_objects_than_the_limit_are_a_422(client):
    objects = [stopped_car(10.0 + i, 20.0, object_id=i) for i in range(MAX_OBJECTS + 1)]
    errors = _post_objects(client, objects)
    assert [e["loc"] for e in errors] == [["body", "queries", 0, "objects"]] and errors[0]["type"] == "too_long"
    assert client.post("/v1/warning", json=fcw_query("limit", objects=objects[:MAX_OBJECTS])).status_code == 200


def test_an_unknown_object_field_is_a_422_naming_it(client):
    errors = _post_objects(client, [{**stopped_car(30.0, 20.0), "speed_kmh": 3.0}])
    assert [e["loc"] for e in errors] == [["body", "queries", 0, "objects", 0, "speed_kmh"]]


def test_both_accelerations_of_an_object_are_a_422(client):
    errors = _post_objects(client, [{**stopped_car(30.0, 20.0), "relative_accel_mps2": 1.0}])
    assert errors[0]["loc"] == ["body", "queries", 0, "objects"]


def test_the_openapi_document_describes_the_objects(client):
    schema = client.get("/openapi.json").json()
    body = schema["paths"]["/v1/warning"]["post"]["requestBody"]["content"]["application/json"]["schema"]
    objects = body["properties"]["objects"]
    assert objects["anyOf"][0]["maxItems"] == MAX_OBJECTS
    item = objects["anyOf"][0]["items"]
    assert item["additionalProperties"] is False
    assert {"id", "x_m", "y_m", "relative_speed_mps", "accel_mps2", "relative_accel_mps2", "width_m", "lane"} <= set(
        item["properties"]
    )
    assert {"accel_mps2", "yaw_rate_dps", "braking", "turn_signal"} <= set(body["properties"])


# ------------------------------------------------------------------ the map path
@pytest.mark.parametrize("lane_pos_m", [40.0, 90.0, 150.0, 190.0, 280.0])
def test_the_map_path_puts_objects_where_the_librarys_full_profile_does(lane_pos_m):
    """The service keeps of the horizon's curvature profile only the knots where its slope changes: across the
    path, a point on or beside the road ahead is as far from it (to a millimetre) as by the library's full
    profile (every vertex), on a straight running into R 120 m, on the arc, and running out of it; and the
    service's path has far fewer knots."""
    (network,) = load_networks([Path(TRACK_NET)], ServiceSettings(nets=[TRACK_NET]).engine_settings())
    answer = network.engine.evaluate(VehicleInput("probe", "N", 72.0, "curve_0", lane_pos_m, None, 1.0, None))
    ahead = answer.path
    assert ahead is not None
    full = path_curvature_ahead(ahead.path, ahead.vehicle_s, N_SETTINGS.range_m)
    served = _paths([ahead], N_SETTINGS.range_m)
    assert served is not None and served.s_m.size < len(full.s_m) / 10
    served_path = PathCurvature(tuple(served.s_m.tolist()), tuple(served.curvature_1pm.tolist()))
    for x_m in np.arange(5.0, 190.0, 7.0):
        for y_m in (-3.5, 0.0, 1.0, 3.5):
            offsets = [
                offset_from_circle_m(x_m, y_m, equivalent_curvature_1pm(path_table(path), x_m, y_m))
                for path in (full, served_path)
            ]
            assert offsets[1] == pytest.approx(offsets[0], abs=1e-3), (x_m, y_m)


@given(st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=20))
def test_fcw_answer_numbers_are_plain_floats_or_null(values: list[float]) -> None:
    """An FcwAnswer's numbers are Python floats, null where NaN or infinite (the contract's JSON)."""
    listed = _json_values(np.array(values, dtype=float))
    assert listed == [v if math.isfinite(v) else None for v in values]
    assert all(v is None or type(v) is float for v in listed)


@given(st.lists(st.integers(min_value=-1, max_value=2**31 - 1), max_size=20))
def test_fcw_answer_target_ids_are_plain_ints_or_null(ids: list[int]) -> None:
    """An FcwAnswer's target id is a Python int, null where the frame has none (-1)."""
    listed = _json_values(np.array(ids, dtype=np.int64))
    assert listed == [i if i >= 0 else None for i in ids]
    assert all(i is None or type(i) is int for i in listed)


@given(st.lists(st.frozensets(st.integers(min_value=0, max_value=MAX_OBJECT_ID), max_size=6), max_size=20))
def test_kept_object_ids_come_back_by_vehicle(id_sets: list[frozenset[int]]) -> None:
    """The ids kept per vehicle (in the path, cutting in) go into the fleet memory's keys and come back to the same
    vehicles, in ascending order."""
    kept = [tuple(sorted(ids)) for ids in id_sets]
    assert _ids_by_row(_keys(kept), len(kept)) == kept
