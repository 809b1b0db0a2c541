"""The whole system on the bundled test tracks: map -> look-ahead -> warning -> state.

Distances come from each track's truth file, written by the generator from the
constructed geometry, never from the extractor.
"""

from __future__ import annotations

import json
from functools import cache

import numpy as np
import pytest

from csws.ahead.horizon import END_MARGIN_M
from csws.data import standard_tables
from csws.engine import Engine, VehicleInput
from csws.networks import networks_dir
from csws.road.roadmap import RoadMap
from csws.standard import Level
from csws.state import Fault, SystemState

TABLES = standard_tables()
COLUMN_CATEGORY = {"M1": "M1", "M2": "M2", "M3_N_O": "N"}


@cache
def _track(name: str) -> tuple[Engine, dict]:
    truth = json.loads((networks_dir() / f"{name}.truth.json").read_text())
    return Engine(RoadMap.load(networks_dir() / f"{name}.net.xml")), truth


def _at(truth: dict, route_s: float) -> tuple[str, float]:
    """Lane and lane position of a route arc length, from the truth's lane table."""
    lane = next(lane for lane in reversed(truth["lanes"]) if lane["start_s"] <= route_s)
    return lane["lane"], route_s - lane["start_s"]


def _vehicle(truth: dict, route_s: float, speed_kmh: float, category: str, vehicle_id: str = "v") -> VehicleInput:
    lane_id, lane_pos_m = _at(truth, route_s)
    return VehicleInput(vehicle_id, category, speed_kmh, lane_id, lane_pos_m, route_edges=truth["route"]["edges"])


def _single_rows(table_key: str):
    for radius, row in TABLES[table_key].items():
        if radius.startswith("_"):
            continue
        for column, cells in row.items():
            for speed_kmh, distance_m in cells:
                for direction in ("left", "right"):
                    yield pytest.param(
                        f"single_r{radius}_{direction}",
                        COLUMN_CATEGORY[column],
                        speed_kmh,
                        distance_m,
                        id=f"R{radius}-{direction}-{column}-V{speed_kmh}",
                    )


def _answer_at_table_distance(track: str, category: str, speed_kmh: float, table_distance_m: float):
    """The engine's answer for a vehicle ``table_distance_m`` before the track's curve, at the test speed."""
    engine, truth = _track(track)
    return engine.evaluate(_vehicle(truth, truth["curves"][0]["start_s"] - table_distance_m, speed_kmh, category))


@pytest.mark.parametrize(
    "track, category, speed_kmh, table_distance_m", list(_single_rows("table5_single_curve_level1_tests"))
)
def test_table_5_level_1_on_the_track_at_the_table_distance(track, category, speed_kmh, table_distance_m):
    answer = _answer_at_table_distance(track, category, speed_kmh, table_distance_m)
    assert answer.state is SystemState.ACTIVE
    assert answer.level >= Level.LEVEL_1
    assert answer.warning.target.distance_m == pytest.approx(table_distance_m, abs=1.0)


@pytest.mark.parametrize(
    "track, category, speed_kmh, table_distance_m", list(_single_rows("table6_single_curve_level2_tests"))
)
def test_table_6_level_2_on_the_track_at_the_table_distance(track, category, speed_kmh, table_distance_m):
    answer = _answer_at_table_distance(track, category, speed_kmh, table_distance_m)
    assert answer.level == Level.LEVEL_2
    assert answer.warning.path_kind == "route"


def _onsets_along(track: str, category: str, speed_kmh: float, step_m: float = 0.25) -> dict[tuple[int, int], float]:
    """Route position at which each (curve number, level) first triggers, driving at constant speed."""
    engine, truth = _track(track)
    last_start_s = truth["curves"][-1]["start_s"]
    positions = np.arange(last_start_s - 300.0, last_start_s, step_m)
    vehicles = [_vehicle(truth, s, speed_kmh, category, f"v{i}") for i, s in enumerate(positions)]
    number_of = {}
    onsets: dict[tuple[int, int], float] = {}
    for s, answer in zip(positions, engine.evaluate_many(vehicles), strict=False):
        for trigger in answer.warning.triggers:
            curve_start_s = s + trigger.distance_m
            if trigger.distance_m <= 0:
                continue
            key = (trigger.curve_id, trigger.part_index)
            number = number_of.setdefault(key, _curve_number(truth, curve_start_s, trigger.radius_m))
            for level in range(1, int(trigger.level) + 1):
                onsets.setdefault((number, level), s)
    return onsets


def _curve_number(truth: dict, start_s: float, radius_m: float) -> int:
    """The truth curve (1, 2) whose start is nearest to ``start_s`` and whose radius matches."""
    candidates = [c for c in truth["curves"] if abs(c["radius_m"] - radius_m) <= 0.02 * c["radius_m"]]
    return min(candidates, key=lambda c: abs(c["start_s"] - start_s))["number"]


def _multi_rows(table_key: str, directions=("left", "right")):
    number = table_key[5]
    for column in ("M1", "M2", "M3_N_O"):
        for test in TABLES[table_key][column]:
            for direction in directions:
                track = f"t{number}_{column.lower()}_test{test['test']}_{direction}"
                yield pytest.param(track, COLUMN_CATEGORY[column], test, id=track)


@pytest.mark.parametrize(
    "track, category, test", list(_multi_rows("table8_multi_curve_curve2_first_all_before_curve1"))
)
def test_table_8_on_the_track_curve_2_warns_first_and_in_time(track, category, test):
    _, truth = _track(track)
    curve1_s, curve2_s = (c["start_s"] for c in truth["curves"])
    onsets = _onsets_along(track, category, test["V_kmh"])
    for level in (1, 2):
        assert curve2_s - onsets[(2, level)] >= test["S_w_m"][f"curve2_level{level}"]
        assert onsets[(2, level)] < curve1_s


@pytest.mark.parametrize(
    "track, category, test",
    list(_multi_rows("table9_multi_curve_curve2_first_alternating"))
    + [
        pytest.param(
            "t9_m1_test1_s", "M1", TABLES["table9_multi_curve_curve2_first_alternating"]["M1"][0], id="t9_m1_test1_s"
        )
    ],
)
def test_table_9_on_the_track_warnings_alternate_and_come_in_time(track, category, test):
    _, truth = _track(track)
    start = {c["number"]: c["start_s"] for c in truth["curves"]}
    onsets = _onsets_along(track, category, test["V_kmh"])
    assert sorted(onsets, key=onsets.get) == [(2, 1), (1, 1), (2, 2), (1, 2)]
    for (curve, level), s in onsets.items():
        assert start[curve] - s >= test["S_w_m"][f"curve{curve}_level{level}"]


def test_many_vehicles_at_once_get_the_answers_they_get_alone():
    engine, truth = _track("t9_m2_test2_left")
    start_s = truth["curves"][0]["start_s"]
    rng = np.random.default_rng(3)
    vehicles = [
        _vehicle(truth, start_s - d, v, c, f"v{i}")
        for i, (d, v, c) in enumerate(
            zip(
                rng.uniform(-20, 200, 100),
                rng.uniform(30, 130, 100),
                rng.choice(["M1", "M2", "M3", "N", "O"], 100),
                strict=False,
            )
        )
    ]
    together = engine.evaluate_many(vehicles)
    alone = [Engine(engine.road_map).evaluate(v) for v in vehicles]
    assert [a.warning for a in together] == [a.warning for a in alone]


def test_faults_and_switches():
    engine, truth = _track("single_r40_left")
    near = _vehicle(truth, truth["curves"][0]["start_s"] - 10.0, 80.0, "N", "truck")
    assert engine.evaluate(near).level == Level.LEVEL_2
    engine.switch("truck", on=False)
    off = engine.evaluate(near)
    assert off.state is SystemState.OFF and off.level == Level.NONE
    engine.switch("truck", on=True)
    lost = engine.evaluate(VehicleInput("truck", "N", 80.0, None))
    assert lost.state is SystemState.FAULT and lost.fault is Fault.NO_MAP_MATCH and lost.level == Level.NONE
    unknown = engine.evaluate(VehicleInput("truck", "N", 80.0, "no_such_lane", 3.0))
    assert unknown.fault is Fault.NO_MAP_MATCH
    assert engine.evaluate(near).level == Level.LEVEL_2
    no_map = Engine(None).evaluate(near)
    assert no_map.state is SystemState.FAULT and no_map.fault is Fault.NO_MAP
    invalid = engine.evaluate(VehicleInput("truck", "N", float("nan"), near.lane_id, near.lane_pos_m))
    assert invalid.fault is Fault.INVALID_INPUT and invalid.level == Level.NONE


def test_passing_the_curve_or_slowing_down_ends_the_warning():
    engine, truth = _track("single_r120_right")
    curve = truth["curves"][0]
    assert engine.evaluate(_vehicle(truth, curve["start_s"] - 20.0, 100.0, "N")).level == Level.LEVEL_2
    assert engine.evaluate(_vehicle(truth, curve["start_s"] + 5.0, 100.0, "N")).level == Level.LEVEL_2
    # Past the curve's end by more than the margin for position noise there (rule 3 of csws.warning.release).
    assert engine.evaluate(_vehicle(truth, curve["end_s"] + END_MARGIN_M + 0.5, 100.0, "N")).level == Level.NONE
    assert engine.evaluate(_vehicle(truth, curve["start_s"] - 20.0, 60.0, "N")).level == Level.NONE
