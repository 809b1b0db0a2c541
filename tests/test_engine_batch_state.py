"""The batch state update and the columnar fleet evaluation give what one vehicle at a time gives."""

from __future__ import annotations

import json
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from csws.engine import Engine, VehicleInput
from csws.networks import networks_dir
from csws.road.roadmap import RoadMap
from csws.state import ActivationSettings, Fault, SystemState, VehicleStatus, next_status, next_statuses, switch

TRACK = "t9_m1_test1_left"

_times = st.one_of(st.none(), st.floats(min_value=-5.0, max_value=20.0), st.sampled_from([math.nan, math.inf]))
_speeds = st.one_of(st.floats(min_value=-10.0, max_value=150.0), st.sampled_from([math.nan, math.inf, 0.0, 35.0]))
_statuses = st.builds(
    VehicleStatus,
    state=st.sampled_from(list(SystemState)),
    switched_on=st.booleans(),
    activated=st.booleans(),
    last_timestamp_s=st.one_of(st.none(), st.floats(min_value=0.0, max_value=10.0)),
    fault=st.one_of(st.none(), st.sampled_from(list(Fault))),
)
_updates = st.tuples(_statuses, _speeds, _times, _times, st.one_of(st.none(), st.sampled_from(list(Fault))))


@settings(max_examples=200, deadline=None)
@given(st.lists(_updates, min_size=1, max_size=12), st.floats(min_value=0.0, max_value=60.0))
def test_batch_state_update_is_the_single_update_of_each_vehicle(updates, activation_speed_kmh):
    activation = ActivationSettings(activation_speed_kmh=activation_speed_kmh, hysteresis_kmh=5.0)
    statuses, speeds, times, ages, faults = map(list, zip(*updates, strict=False))
    batch = next_statuses(statuses, speeds, timestamp_s=times, age_s=ages, found_fault=faults, settings=activation)
    for status, speed, time_s, age_s, fault, updated in zip(statuses, speeds, times, ages, faults, batch, strict=False):
        assert updated == next_status(
            status, speed, timestamp_s=time_s, age_s=age_s, found_fault=fault, settings=activation
        )


def test_stale_and_invalid_inputs_are_found_in_a_batch():
    active = next_status(VehicleStatus(), 50.0, timestamp_s=10.0)
    updated = next_statuses(
        [active, active, active, active, switch(active, False)],
        [50.0, math.nan, 50.0, 50.0, 50.0],
        timestamp_s=[9.0, 11.0, 11.0, 11.0, 11.0],
        age_s=[None, None, 3.0, None, None],
    )
    assert [s.fault for s in updated] == [Fault.STALE_INPUT, Fault.INVALID_INPUT, Fault.STALE_INPUT, None, None]
    assert [s.state for s in updated] == [SystemState.FAULT] * 3 + [SystemState.ACTIVE, SystemState.OFF]
    assert updated[3].last_timestamp_s == 11.0 and updated[0].last_timestamp_s == 10.0
    assert updated[0].activated  # the latch survives a fault


@pytest.fixture(scope="module")
def track():
    truth = json.loads((networks_dir() / f"{TRACK}.truth.json").read_text())
    return RoadMap.load(networks_dir() / f"{TRACK}.net.xml"), truth


def test_fleet_answers_are_the_single_answers(track):
    road_map, truth = track
    route = tuple(truth["route"]["edges"])
    curve_s = truth["curves"][0]["start_s"]
    vehicles = []
    for i, s in enumerate([curve_s - 400.0, curve_s - 150.0, curve_s - 40.0, curve_s + 10.0, curve_s - 100.0]):
        lane = next(lane for lane in reversed(truth["lanes"]) if lane["start_s"] <= s)
        vehicles.append(
            VehicleInput(
                f"v{i}",
                "M1" if i % 2 else "N",
                60.0 + 25.0 * i,
                lane["lane"],
                s - lane["start_s"],
                route if i != 4 else None,
                timestamp_s=1.0,
            )
        )
    vehicles.append(VehicleInput("lost", "M1", 80.0, None, 0.0, route, timestamp_s=1.0))
    vehicles.append(VehicleInput("nan", "M1", 80.0, vehicles[0].lane_id, math.nan, route, timestamp_s=1.0))
    fleet = Engine(road_map).evaluate_fleet(
        [v.vehicle_id for v in vehicles],
        [v.category for v in vehicles],
        [v.speed_kmh for v in vehicles],
        [v.lane_id for v in vehicles],
        [v.lane_pos_m for v in vehicles],
        [v.route_edges for v in vehicles],
        timestamp_s=[v.timestamp_s for v in vehicles],
    )
    single = Engine(road_map)
    answers = [single.evaluate(v) for v in vehicles]
    assert fleet.state == [a.state for a in answers]
    assert fleet.fault == [a.fault for a in answers]
    assert fleet.warning == [a.warning for a in answers]
    assert any(w.level for w in fleet.warning) and not all(w.level for w in fleet.warning)
    assert fleet.active == [i for i, a in enumerate(answers) if a.path is not None]


def test_an_unknown_category_changes_no_status(track):
    road_map, _ = track
    engine = Engine(road_map)
    with pytest.raises(ValueError):
        engine.evaluate_fleet(
            ["a", "b"], ["M1", "X9"], [50.0, 50.0], ["approach_0", "approach_0"], [1.0, 1.0], [None, None]
        )
    assert engine.statuses == {}
