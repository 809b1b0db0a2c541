"""What each equipped vehicle's sensor sees of the SUMO vehicles around it (``csws.cosim.sensor``).

The grid's pairs against a brute force, the object frame on a circle, on SUMO's own straight
and R 125 m tracks, and along a map path (a hairpin, a turning leader) against closed-form
clearances and warning levels.
"""

from __future__ import annotations

import math
import os
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from csws.cosim.sensor import ONCOMING_MPS, MapLanes, SensorPairs, SumoVehicles, read_vehicles, sensor_view
from csws.fcw.fleet import UNKNOWN_LANE, FleetEgo, FleetMemory, FleetObjects, update_fleet
from csws.fcw.path import offset_from_circle_m
from csws.fcw.settings import FcwSettings
from csws.networks import networks_dir
from csws.networks.fcw_tracks import LANE_WIDTH_M
from csws.sumo.binaries import sumo_binary, sumo_home


def _vehicles(front_xy: np.ndarray, heading_rad: np.ndarray, speed_mps: np.ndarray) -> SumoVehicles:
    """Vehicles 4.5 m long and 1.8 m wide, all on one road and lane, at the given fronts, headings and speeds."""
    n = len(front_xy)
    return SumoVehicles(
        [f"v{i}" for i in range(n)],
        np.arange(n, dtype=np.int64),
        front_xy[:, 0],
        front_xy[:, 1],
        heading_rad,
        speed_mps,
        np.zeros(n),
        np.full(n, 4.5),
        np.full(n, 1.8),
        np.zeros(n, dtype=np.int64),
        np.zeros(n, dtype=np.int64),
        np.zeros(n, dtype=np.int64),
        np.zeros(n),
    )


@settings(deadline=None, max_examples=30)
@given(st.integers(0, 2**32 - 1), st.integers(2, 300), st.floats(50.0, 250.0))
def test_the_grid_finds_every_pair_the_brute_force_finds(seed, count, range_m):
    """The sensor view from the grid's 3 x 3 cells holds exactly the pairs that checking every vehicle
    against every other finds (the object's rear ahead, at most the range away, not coming toward the subject),
    with the same coordinates, computed here from the headings by hand."""
    rng = np.random.default_rng(seed)
    fronts = rng.uniform(-1500.0, 1500.0, (count, 2))
    headings = rng.uniform(-math.pi, math.pi, count)
    speeds = rng.uniform(0.0, 30.0, count)
    vehicles = _vehicles(fronts, headings, speeds)
    subjects = np.flatnonzero(rng.random(count) < 0.5)
    pairs = sensor_view(vehicles, subjects, range_m)
    expected = {}
    for k, i in enumerate(subjects.tolist()):
        ahead, left = np.array([math.sin(headings[i]), math.cos(headings[i])]), None
        left = np.array([-ahead[1], ahead[0]])
        for j in range(count):
            own = np.array([math.sin(headings[j]), math.cos(headings[j])])
            x_m = float((fronts[j] - 4.5 * own - fronts[i]) @ ahead)
            y_m = float((fronts[j] - 2.25 * own - fronts[i]) @ left)
            rear_m = float(np.hypot(*(fronts[j] - 4.5 * own - fronts[i])))
            sight = fronts[j] - 4.5 * own - fronts[i]
            oncoming = speeds[j] * float(own @ sight) / float(np.hypot(*sight)) < -ONCOMING_MPS
            if j != i and x_m >= 0.0 and rear_m <= range_m and not oncoming:
                expected[(k, j)] = (x_m, y_m)
    found = {
        (k, j): (x, y)
        for k, j, x, y in zip(
            pairs.subject.tolist(), pairs.seen.tolist(), pairs.x_m.tolist(), pairs.y_m.tolist(), strict=True
        )
    }
    assert found.keys() == expected.keys()
    for key, (x_m, y_m) in expected.items():
        assert found[key] == pytest.approx((x_m, y_m), abs=1e-9)


@settings(deadline=None, max_examples=30)
@given(st.integers(0, 2**32 - 1), st.integers(2, 200))
def test_a_part_of_the_subjects_sees_in_the_whole_view_what_it_sees_alone(seed, count):
    """The co-simulation views every subject at once and splits the view by settings: each part's pairs
    (``SensorPairs.of_subjects``) are, to the bit, those of viewing that part alone, in the same order."""
    rng = np.random.default_rng(seed)
    vehicles = _vehicles(
        rng.uniform(-600.0, 600.0, (count, 2)), rng.uniform(-math.pi, math.pi, count), rng.uniform(0.0, 30.0, count)
    )
    subjects = np.flatnonzero(rng.random(count) < 0.7)
    turn_rad = rng.uniform(-0.05, 0.05, subjects.size)
    chosen = rng.random(subjects.size) < 0.5
    part = sensor_view(vehicles, subjects, 200.0, turn_rad).of_subjects(chosen)
    alone = sensor_view(vehicles, subjects[chosen], 200.0, turn_rad[chosen])
    for name in ("subject", "seen", "x_m", "y_m", "relative_speed_mps", "accel_mps2", "lane"):
        assert np.array_equal(getattr(part, name), getattr(alone, name)), name


def test_two_vehicles_at_one_speed_on_one_circle_neither_close_nor_open():
    """On a circle of R 60 m, a car 30 m of arc behind another at the same speed: the range rate along
    the line of sight is about 0 (the chord between two points of the circle is constant), though the
    lead's speed along the follower's heading is 1.8 m/s lower; a stopped car straight ahead closes at
    the follower's speed."""
    radius_m, speed_mps = 60.0, 15.0
    lead_angle, follower_angle = 0.5, 0.0
    # Heading east-ward on a left circle centred at (0, R): a point at angle a is (R sin a, R (1 - cos a)).
    fronts = np.array([[radius_m * math.sin(a), radius_m * (1.0 - math.cos(a))] for a in (follower_angle, lead_angle)])
    # SUMO's heading is clockwise from north; the tangent at angle a points at east rotated left by a.
    headings = np.array([math.pi / 2.0 - a for a in (follower_angle, lead_angle)])
    pairs = sensor_view(_vehicles(fronts, headings, np.full(2, speed_mps)), np.array([0]), 200.0)
    assert pairs.seen.tolist() == [1]
    along_heading_mps = speed_mps * math.cos(lead_angle - follower_angle) - speed_mps
    assert along_heading_mps < -1.8  # the speeds' difference along the follower's heading
    assert abs(pairs.relative_speed_mps[0]) < 0.4  # 0 to the lead's rear, were it on the circle (4.5 m of tangent)
    straight = sensor_view(
        _vehicles(np.array([[0.0, 0.0], [54.5, 0.0]]), np.full(2, math.pi / 2.0), np.array([speed_mps, 0.0])),
        np.array([0]),
        200.0,
    )
    assert straight.x_m[0] == pytest.approx(50.0) and straight.y_m[0] == pytest.approx(0.0, abs=1e-9)
    assert straight.relative_speed_mps[0] == pytest.approx(-speed_mps)


def _sumo_view(track: str, vehicles: str, path_turn_rad: float = 0.0) -> tuple[SumoVehicles, SensorPairs]:
    """What the subject ``sv`` sees on a FCW track one step after the vehicles depart, its frame turned
    left by ``path_turn_rad``."""
    os.environ.setdefault("SUMO_HOME", str(sumo_home()))
    import libsumo

    types = '<vType id="t" length="12" minGap="2.5" sigma="0"/><vType id="c" length="4.5" minGap="3" sigma="0"/>'
    with tempfile.TemporaryDirectory() as work:
        routes = Path(work) / "r.rou.xml"
        routes.write_text(f"<routes>{types}{vehicles}</routes>", encoding="utf-8")
        net = networks_dir() / "fcw" / f"{track}.net.xml"
        libsumo.start([str(sumo_binary("sumo")), "-n", str(net), "-r", str(routes), "--no-step-log", "true"])
        try:
            libsumo.simulationStep()
            seen = read_vehicles(libsumo, {v: i for i, v in enumerate(libsumo.vehicle.getIDList())}, {})
            subject = seen.vehicle_id.index("sv")
            return seen, sensor_view(seen, np.array([subject]), 200.0, np.array([path_turn_rad]))
        finally:
            libsumo.close()


def _vehicle(vehicle_id: str, vtype: str, lane: int, pos_m: float) -> str:
    return (
        f'<vehicle id="{vehicle_id}" type="{vtype}" depart="0" departLane="{lane}" departPos="{pos_m}" '
        f'departSpeed="0" insertionChecks="none"><route edges="road"/></vehicle>'
    )


def test_on_the_straight_track_the_sensor_sees_the_lead_in_its_lane_and_the_other_lane_to_the_left():
    """sv's front at 100 m, tv's rear 150 m ahead in its lane, adj's rear 25.5 m ahead one lane (3.5 m) to the left."""
    seen, pairs = _sumo_view(
        "fcw_straight", _vehicle("sv", "t", 0, 100.0) + _vehicle("tv", "c", 0, 254.5) + _vehicle("adj", "c", 1, 130.0)
    )
    view = {
        seen.vehicle_id[j]: (x, y, lane)
        for j, x, y, lane in zip(pairs.seen, pairs.x_m, pairs.y_m, pairs.lane, strict=True)
    }
    assert view["tv"] == pytest.approx((150.0, 0.0, 0), abs=1e-6)
    assert view["adj"] == pytest.approx((25.5, LANE_WIDTH_M, 1), abs=1e-6)


def test_on_the_r125_curve_the_lead_in_the_lane_lies_on_the_lane_and_the_outer_lane_car_beside_it():
    """R 125 m (the inner lane, left curve): the lead's centre is on the lane's circle through sv's front,
    within half a lane, the outer lane's car a lane width off it. SUMO's angle is the truck's body
    (its chord), so the circle is tangent to the lane, not the body: the tangent is the body turned
    left by half the truck's length over R."""
    curve_start_m, radius_m = 60.0, 125.0
    seen, pairs = _sumo_view(
        "fcw_curve_r125",
        _vehicle("sv", "t", 1, curve_start_m + 30.0)
        + _vehicle("adj", "c", 0, curve_start_m + 45.0)
        + _vehicle("tv", "c", 1, curve_start_m + 80.0),
        path_turn_rad=6.0 / radius_m,
    )
    for name, expected_m in (("tv", 0.0), ("adj", -LANE_WIDTH_M)):
        k = seen.vehicle_id.index(name)
        at = int(np.flatnonzero(pairs.seen == k)[0])
        offset_m = offset_from_circle_m(pairs.x_m[at] + 2.25, pairs.y_m[at], 1.0 / radius_m)
        assert offset_m == pytest.approx(expected_m, abs=0.3)
    assert pairs.lane[np.flatnonzero(pairs.seen == seen.vehicle_id.index("tv"))[0]] == 0


def _on_roads(
    fronts: list[tuple[float, float]],
    headings_rad: list[float],
    speeds_mps: list[float],
    roads: list[int],
    lane_positions_m: list[float],
    accels_mps2: list[float],
) -> SumoVehicles:
    """Vehicles 4.5 m long and 1.8 m wide on the given roads (lane 0 each) at the given lane positions."""
    n = len(fronts)
    front = np.asarray(fronts, dtype=float)
    return SumoVehicles(
        [f"v{i}" for i in range(n)],
        np.arange(n, dtype=np.int64),
        front[:, 0],
        front[:, 1],
        np.asarray(headings_rad, dtype=float),
        np.asarray(speeds_mps, dtype=float),
        np.asarray(accels_mps2, dtype=float),
        np.full(n, 4.5),
        np.full(n, 1.8),
        np.asarray(roads, dtype=np.int64),
        np.zeros(n, dtype=np.int64),
        np.zeros(n, dtype=np.int64),
        np.asarray(lane_positions_m, dtype=float),
    )


def _one_path(lengths_m: list[float], subject_on_first_m: float) -> MapLanes:
    """The map path of subject 0: roads 0, 1, 2 (lane 0 each) of these lengths, its front this far into road 0."""
    ends = np.cumsum(lengths_m) - subject_on_first_m
    return MapLanes(
        np.zeros(3, np.int64),
        np.arange(3, dtype=np.int64),
        np.zeros(3, np.int64),
        np.array([ends[-1]]),
        ends - np.asarray(lengths_m),
        ends,
        np.ones(3),
    )


def _warning_level(vehicles: SumoVehicles, lanes: MapLanes) -> int:
    """The subject's (vehicle 0's) level after two frames 0.1 s apart of the object FCW on this view."""
    settings_ = FcwSettings()
    memory, level = FleetMemory.new(1), 0
    for t in (0.0, 0.1):
        pairs = sensor_view(vehicles, np.array([0]), settings_.range_m, None, lanes)
        objects = FleetObjects.of(
            pairs.subject, pairs.seen, pairs.x_m, pairs.y_m, pairs.relative_speed_mps, pairs.accel_mps2, lane=pairs.lane
        )
        frame, memory = update_fleet(settings_, memory, t, FleetEgo.of(vehicles.speed_mps[:1]), objects)
        level = int(frame.level[0])
    return level


def _closed_form_level(clearance_m: float, closing_mps: float, settings_: FcwSettings) -> int:
    """The level a steady subject closing at a constant speed on a steady target needs: a_req after the reaction
    T_resp, v^2 / (2 (x - v T)), against the thresholds, the preliminary one only at a TTC of at most 4 s."""
    left_m = clearance_m - closing_mps * settings_.reaction_time_s
    a_req = closing_mps * closing_mps / (2.0 * left_m) if left_m > 0.0 else math.inf
    if a_req >= settings_.collision_a_req_mps2:
        return 2
    return int(a_req >= settings_.preliminary_a_req_mps2 and clearance_m / closing_mps <= settings_.max_ttc_s)


def test_a_leader_round_a_hairpin_is_as_far_as_the_road_between_them():
    """The subject drives north at 15 m/s on road 0 (its front 40 m into it, 60 m before the bend); road 1 is a
    right hairpin of R 10 m (a half circle, 10 pi m), road 2 runs back south 20 m east of road 0. A stopped car
    on road 2, its front 60 m along it, is 20.5 m from the subject's front in the line of sight (its rear
    4.5 m ahead) but 60 + 10 pi + 60 - 4.5 = 146.9 m along the road: the clearance is the road's, the closing
    speed the subject's own, and the level what that clearance and speed need (none: TTC 9.8 s)."""
    radius_m, speed_mps = 10.0, 15.0
    lanes = _one_path([100.0, math.pi * radius_m, 200.0], 40.0)
    vehicles = _on_roads(
        [(0.0, 0.0), (2.0 * radius_m, 0.0)], [0.0, math.pi], [speed_mps, 0.0], [0, 2], [40.0, 60.0], [0.0, 0.0]
    )
    along_m = 60.0 + math.pi * radius_m + 60.0 - 4.5
    pairs = sensor_view(vehicles, np.array([0]), 200.0, None, lanes)
    assert pairs.seen.tolist() == [1] and pairs.lane.tolist() == [0]
    assert pairs.x_m[0] == pytest.approx(along_m, abs=1e-9)
    assert pairs.relative_speed_mps[0] == pytest.approx(-speed_mps, abs=1e-12)
    # The line of sight alone (no map path) puts the car 4.5 m ahead.
    assert sensor_view(vehicles, np.array([0]), 200.0).x_m[0] == pytest.approx(4.5, abs=1e-9)
    expected = _closed_form_level(along_m, speed_mps, FcwSettings())
    assert expected == 0 and _warning_level(vehicles, lanes) == expected
    # Round the bend beyond the range along the road (its front 150 m along road 2): not seen.
    far = _on_roads(
        [(0.0, 0.0), (2.0 * radius_m, -90.0)], [0.0, math.pi], [speed_mps, 0.0], [0, 2], [40.0, 150.0], [0.0, 0.0]
    )
    assert 60.0 + math.pi * radius_m + 150.0 - 4.5 > 200.0
    assert sensor_view(far, np.array([0]), 200.0, None, lanes).seen.size == 0


@pytest.mark.parametrize("turned_rad", [0.5, 1.0, 1.4])
def test_a_leader_turning_on_the_path_closes_at_the_speeds_difference(turned_rad):
    """The subject at 11 m/s on road 0 (its front 40 m into it, 10 m before the junction); the path turns left
    on road 1, a quarter circle of R 20 m, then road 2. The leader on road 1 at 8 m/s, braking at 0.5 m/s^2,
    has turned by ``turned_rad``: along the road its rear is 10 + 20 turned - 4.5 m ahead and both drive along
    the path, so it closes at 8 - 11 = -3 m/s and brakes at its own 0.5 m/s^2 (its velocity along the line of
    sight, turned away from it, would close faster). The level is what that clearance and closing speed need."""
    radius_m, subject_mps, leader_mps = 20.0, 11.0, 8.0
    lanes = _one_path([50.0, math.pi / 2.0 * radius_m, 200.0], 40.0)
    front = (-radius_m + radius_m * math.cos(turned_rad), 10.0 + radius_m * math.sin(turned_rad))
    vehicles = _on_roads(
        [(0.0, 0.0), front],
        [0.0, -turned_rad],
        [subject_mps, leader_mps],
        [0, 1],
        [40.0, radius_m * turned_rad],
        [0.0, -0.5],
    )
    along_m = 10.0 + radius_m * turned_rad - 4.5
    pairs = sensor_view(vehicles, np.array([0]), 200.0, None, lanes)
    assert pairs.seen.tolist() == [1] and pairs.lane.tolist() == [0]
    assert pairs.x_m[0] == pytest.approx(along_m, abs=1e-9)
    assert pairs.relative_speed_mps[0] == pytest.approx(leader_mps - subject_mps, abs=1e-12)
    assert pairs.accel_mps2[0] == pytest.approx(-0.5, abs=1e-12)
    # Along the line of sight to its rear the leader's velocity is turned away: the range rate closes faster.
    rear = np.array(front) - 4.5 * np.array([math.sin(-turned_rad), math.cos(-turned_rad)])
    unit = rear / np.hypot(*rear)
    sight_rate = (
        leader_mps * float(np.array([math.sin(-turned_rad), math.cos(-turned_rad)]) @ unit) - subject_mps * unit[1]
    )
    assert sight_rate < leader_mps - subject_mps - 0.5
    assert sensor_view(vehicles, np.array([0]), 200.0).relative_speed_mps[0] == pytest.approx(sight_rate, abs=1e-9)


def _two_way_road(rng: np.random.Generator, count: int) -> SumoVehicles:
    """``count`` vehicles on a straight two-way road: road 0 northward (+y), road 1 southward beside it, four
    lanes each 3.5 m wide, fronts anywhere along 800 m, random speeds and accelerations (up to hard braking)."""
    road = (rng.random(count) < 0.3).astype(np.int64)
    lane_index = rng.integers(0, 4, count)
    side = np.where(road == 0, 1.75 + 3.5 * lane_index, -1.75 - 3.5 * lane_index)
    fronts = np.column_stack((side + rng.uniform(-0.3, 0.3, count), rng.uniform(0.0, 800.0, count)))
    length = rng.choice([4.5, 7.0, 12.0, 16.5], count)
    return SumoVehicles(
        [f"v{i}" for i in range(count)],
        np.arange(count, dtype=np.int64),
        fronts[:, 0],
        fronts[:, 1],
        np.where(road == 0, 0.0, math.pi) + rng.uniform(-0.02, 0.02, count),
        np.where(rng.random(count) < 0.2, 0.0, rng.uniform(0.0, 35.0, count)),
        rng.uniform(-9.0, 2.0, count),
        length,
        np.full(count, 1.8),
        road,
        lane_index,
        np.zeros(count, dtype=np.int64),
        fronts[:, 1] * np.where(road == 0, 1.0, -1.0) + 800.0,
    )


def _own_road_paths(vehicles: SumoVehicles, subjects: np.ndarray, reach_m: np.ndarray) -> MapLanes:
    """Each subject's map path: its own road and lane from 50 m behind its front to ``reach_m`` ahead (0: none)."""
    mapped = np.flatnonzero(reach_m > 0.0)
    rows = subjects[mapped]
    return MapLanes(
        mapped.astype(np.int64),
        vehicles.road[rows],
        vehicles.lane_index[rows],
        reach_m,
        np.full(mapped.size, -50.0),
        reach_m[mapped],
        np.ones(mapped.size),
    )


@settings(deadline=None, max_examples=40)
@given(st.integers(0, 2**32 - 1), st.integers(2, 200), st.booleans())
def test_without_other_lanes_the_view_keeps_the_pairs_in_the_subjects_lane_or_an_unknown_one(seed, count, mapped):
    """The view without other lanes is, to the bit and in order, the full view's pairs whose lane is the subject's
    (0) or unknown, on a two-way road with and without map paths (some shorter than the range)."""
    rng = np.random.default_rng(seed)
    vehicles = _two_way_road(rng, count)
    subjects = np.flatnonzero(rng.random(count) < 0.6)
    lanes = None
    if mapped:
        reach_m = np.where(rng.random(subjects.size) < 0.8, rng.uniform(50.0, 400.0, subjects.size), 0.0)
        lanes = _own_road_paths(vehicles, subjects, reach_m)
    full = sensor_view(vehicles, subjects, 200.0, None, lanes)
    judged = sensor_view(vehicles, subjects, 200.0, None, lanes, other_lanes=False)
    kept = (full.lane == 0) | (full.lane == UNKNOWN_LANE)
    for name in ("subject", "seen", "x_m", "y_m", "relative_speed_mps", "accel_mps2", "lane"):
        assert np.array_equal(getattr(judged, name), getattr(full, name)[kept]), name


def _view(vehicles: SumoVehicles, subjects: np.ndarray, reach_m: np.ndarray | None, other_lanes: bool) -> SensorPairs:
    """The subjects' 200 m view, along their own roads' paths of ``reach_m`` where given."""
    lanes = None if reach_m is None else _own_road_paths(vehicles, subjects, reach_m)
    return sensor_view(vehicles, subjects, 200.0, None, lanes, other_lanes)


def _fcw_frames(
    frames: list[SumoVehicles], subjects: np.ndarray, reach_m: np.ndarray | None, other_lanes: bool
) -> list[tuple]:
    """The FCW's answers over ``frames`` 0.1 s apart on the subjects' views (:func:`_view`): per frame the levels,
    states, targets (by vehicle number) with their figures, and the objects remembered."""
    settings_, memory, answers = FcwSettings(), FleetMemory.new(subjects.size), []
    for k, vehicles in enumerate(frames):
        pairs = _view(vehicles, subjects, reach_m, other_lanes)
        ego = FleetEgo.of(
            vehicles.speed_mps[subjects], vehicles.accel_mps2[subjects], braking=vehicles.accel_mps2[subjects] < -3
        )
        objects = pairs.objects(vehicles)
        frame, memory = update_fleet(settings_, memory, 0.1 * k, ego, objects)
        target = np.where(frame.target >= 0, vehicles.number[pairs.seen][np.maximum(frame.target, 0)], -1)
        figures = [frame.clearance_m, frame.relative_speed_mps, frame.ttc_s, frame.ettc_s, frame.a_req_mps2]
        answers.append(
            (
                frame.state.tolist(),
                frame.level.tolist(),
                frame.required_level.tolist(),
                target.tolist(),
                [np.nan_to_num(figure, nan=-1.0).tolist() for figure in figures],
                frame.path_offset_m[frame.target >= 0].tolist(),
                memory.in_path_keys.tolist(),
                memory.cut_in_keys.tolist(),
                memory.held_level.tolist(),
            )
        )
    return answers


def _moved(vehicles: SumoVehicles, rng: np.random.Generator, step_s: float = 0.1) -> SumoVehicles:
    """The vehicles a step later: driven along their headings, new accelerations, a tenth changing lane."""
    speed = np.maximum(vehicles.speed_mps + vehicles.accel_mps2 * step_s, 0.0)
    changes = np.where(rng.random(speed.size) < 0.1, rng.choice([-1, 1], speed.size), 0)
    lane_index = np.clip(vehicles.lane_index + changes, 0, 3)
    side = np.where(vehicles.road == 0, 3.5, -3.5) * (lane_index - vehicles.lane_index)
    travel = speed * step_s
    return SumoVehicles(
        vehicles.vehicle_id,
        vehicles.number,
        vehicles.front_x_m + side + travel * np.sin(vehicles.heading_rad),
        vehicles.front_y_m + travel * np.cos(vehicles.heading_rad),
        vehicles.heading_rad,
        speed,
        rng.uniform(-9.0, 2.0, speed.size),
        vehicles.length_m,
        vehicles.width_m,
        vehicles.road,
        lane_index,
        vehicles.signals,
        vehicles.lane_position_m + travel,
    )


def test_objects_in_another_lane_change_no_answer_of_the_fcw():
    """4.5.5 b: over five frames of a busy two-way road (lane changes, hard braking, stopped vehicles), the FCW
    on the view without other lanes gives every subject the same states, levels, targets, figures and memory,
    to the bit, as on the full view, with and without map paths; the dropped objects are most of the view."""
    warned = dropped = seen = 0
    for seed in range(30):
        rng = np.random.default_rng(seed)
        frames = [_two_way_road(rng, 150)]
        for _ in range(4):
            frames.append(_moved(frames[-1], rng))
        subjects = np.flatnonzero(rng.random(150) < 0.7)
        reach_m = np.where(rng.random(subjects.size) < 0.5, rng.uniform(100.0, 400.0, subjects.size), 0.0)
        for paths in (None, reach_m):
            full = _fcw_frames(frames, subjects, paths, other_lanes=True)
            assert _fcw_frames(frames, subjects, paths, other_lanes=False) == full
            warned += sum(sum(level > 0 for level in answer[1]) for answer in full)
            views = [_view(vehicles, subjects, paths, other_lanes=True) for vehicles in frames]
            seen += sum(view.seen.size for view in views)
            dropped += sum(int(np.sum((view.lane != 0) & (view.lane != UNKNOWN_LANE))) for view in views)
    assert warned > 50, "the road must give warnings"
    assert dropped > seen / 2
