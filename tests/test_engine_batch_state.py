"""The batch state update and the columnar fleet evaluation give what one vehicle at a time gives."""

from __future__ import annotations

import json
import math
import statistics
from dataclasses import replace

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from csws.engine import Engine, EngineSettings, VehicleInput
from csws.networks import networks_dir
from csws.road.roadmap import RoadMap
from csws.state import ActivationSettings, Fault, SystemState, VehicleStatus, next_status, next_statuses, switch
from csws.warning import latency
from csws.warning.rules import WarningSettings

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


_clock_gaps = st.lists(st.sampled_from([0.1, 0.1, 0.2, 0.5, 1.0, 3.0, -0.4]), min_size=3, max_size=12)


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.tuples(st.integers(0, 2), st.floats(40.0, 130.0), st.booleans()), min_size=1, max_size=9),
    st.lists(_clock_gaps, min_size=3, max_size=3),
)
def test_a_fleet_on_shared_clocks_learns_each_vehicles_own_intervals_and_answers(track, vehicles, clocks):
    road_map, truth = track
    route = tuple(truth["route"]["edges"])
    curve_s = truth["curves"][0]["start_s"]
    lane = next(lane for lane in reversed(truth["lanes"]) if lane["start_s"] <= curve_s - 120.0)
    ids = [f"v{i}" for i in range(len(vehicles))]
    fleet_engine, single_engine = Engine(road_map), Engine(road_map)
    accepted: dict[str, list[float]] = {vehicle_id: [] for vehicle_id in ids}
    for step in range(len(clocks[0])):
        # Vehicles on one clock share its timestamps (and so their intervals); a gap < 0 sends a stale fix.
        times = [sum(clocks[clock][: step + 1]) + 10.0 for clock, _, _ in vehicles]
        timed = [None if (step % 4 == 3 and untimed) else t for (_, _, untimed), t in zip(vehicles, times, strict=True)]
        inputs = [
            VehicleInput(
                vehicle_id, "M1", speed, lane["lane"], curve_s - 120.0 - lane["start_s"] + 8.0 * step, route, t
            )
            for vehicle_id, (_, speed, _), t in zip(ids, vehicles, timed, strict=True)
        ]
        columns = [[getattr(v, name) for v in inputs] for name in ("vehicle_id", "category", "speed_kmh", "lane_id")]
        fleet = fleet_engine.evaluate_fleet(
            *columns, [v.lane_pos_m for v in inputs], [route] * len(inputs), timestamp_s=timed
        )
        assert fleet.warning == [single_engine.evaluate(v).warning for v in inputs]
        for vehicle_id, t in zip(ids, timed, strict=True):
            kept = accepted[vehicle_id]
            if t is not None and (not kept or t >= kept[-1]):
                kept.append(t)
            gaps = [b - a for a, b in zip(kept, kept[1:], strict=False) if b > a][-latency.KEPT_INTERVALS :]
            assert fleet_engine.intervals.get(vehicle_id, ()) == tuple(gaps)
            assert fleet_engine.memory(vehicle_id) == single_engine.memory(vehicle_id)
            if len(gaps) >= latency.MIN_INTERVALS:
                expected_s = min(statistics.median(gaps), WarningSettings().max_update_period_s)
                assert fleet_engine.update_period_s(vehicle_id) == expected_s


@settings(max_examples=30, deadline=None)
@given(
    period_s=st.floats(0.1, 8.0),
    learn=st.booleans(),
    hold_s=st.floats(0.0, 3.0),
    margin_kmh=st.floats(0.0, 5.0),
    speeds=st.lists(st.floats(50.0, 130.0), min_size=4, max_size=10),
)
def test_a_fleets_warning_settings_given_per_call_answer_as_an_engine_built_with_them(
    track, period_s, learn, hold_s, margin_kmh, speeds
):
    """The update period, its learning and the release rule of one fleet, passed with its vehicles, answer each
    fix as an engine whose own settings they are, in the fleet's step and in the one-vehicle path."""
    road_map, truth = track
    route = tuple(truth["route"]["edges"])
    curve_s = truth["curves"][0]["start_s"]
    warning = replace(
        WarningSettings(),
        update_period_s=period_s,
        learn_update_period=learn,
        release_hold_s=hold_s,
        release_margin_kmh=margin_kmh,
    )
    shared, single, own = Engine(road_map), Engine(road_map), Engine(road_map, EngineSettings(warning=warning))
    for step, speed_kmh in enumerate(speeds):
        s = curve_s - 200.0 + 25.0 * step
        lane = next(lane for lane in reversed(truth["lanes"]) if lane["start_s"] <= s)
        vehicles = [
            VehicleInput(vehicle_id, category, speed_kmh, lane["lane"], s - lane["start_s"], route, 10.0 + step)
            for vehicle_id, category in (("car", "M1"), ("truck", "N"))
        ]
        columns = [[getattr(v, name) for v in vehicles] for name in ("vehicle_id", "category", "speed_kmh", "lane_id")]
        positions, routes, times = [v.lane_pos_m for v in vehicles], [route] * 2, [v.timestamp_s for v in vehicles]
        given_settings = shared.evaluate_fleet(*columns, positions, routes, timestamp_s=times, warning=warning)
        built_with_them = own.evaluate_fleet(*columns, positions, routes, timestamp_s=times)
        assert given_settings.warning == built_with_them.warning
        assert given_settings.warning == [single.evaluate(v, warning).warning for v in vehicles]
        for vehicle in vehicles:
            assert shared.memory(vehicle.vehicle_id) == own.memory(vehicle.vehicle_id)
            assert single.memory(vehicle.vehicle_id) == own.memory(vehicle.vehicle_id)
            assert shared.update_period_s(vehicle.vehicle_id, warning) == own.update_period_s(vehicle.vehicle_id)
