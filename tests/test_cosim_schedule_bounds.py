"""The curve warning's wake schedule (:mod:`csws.cosim.schedule`) against bounds written out here: a sleeping
vehicle cannot be warned before it wakes (formula (1) at the curve's V_w bound, and with V_w = 0 at its path's
end), the array test keeps awake only vehicles that could be warned at the next step, vehicles scheduled together
wake as each would alone, the road ahead is read from the horizons as its definition says, and the V_w bound is
below Tables 1-2 at every radius. The runs that compare scheduled with every-step warnings are in
tests/test_cosim_schedule.py."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from csws.ahead.horizon import END_MARGIN_M
from csws.cosim.schedule import (
    LANE_CHANGE_MARGIN_M,
    LANE_CHANGE_MARGIN_SHARE,
    PartsAhead,
    RoadAhead,
    WakeSchedule,
    lowest_accelerations_mps2,
    lowest_warning_speeds_mps,
    speed_bound_mps,
)
from csws.standard import G_MPS2, REACTION_TIME_S, kmh_to_mps, warning_speed
from csws.warning.rules import column_index
from csws.warning.settings import WarningSettings

STEP_S = 0.1


def _formula_1_reach_m(speed_mps: float, settings: WarningSettings, warning_speed_mps: float = 0.0) -> float:
    """S_w at V_w plus the latency allowance at ``speed_mps``, m: formula (1) written out here."""
    return (
        REACTION_TIME_S * speed_mps
        + (speed_mps**2 - warning_speed_mps**2) / G_MPS2
        + speed_mps * (settings.update_period_s + settings.system_delay_s)
    )


#: A sleeping vehicle: its distance to the curve and beyond it to the end of its path, the lowest V_w of the curve
#: (none: inf), its speed, SUMO's bound on it, its acceleration and the lane's length factor.
SLEEPERS = {
    "distance_m": st.floats(0.0, 3000.0),
    "beyond_m": st.floats(0.0, 3000.0),
    "warning_speed_mps": st.one_of(st.just(math.inf), st.floats(0.0, 40.0)),
    "speed_mps": st.floats(0.0, 40.0),
    "bound_mps": st.floats(1.0, 40.0),
    "accel_mps2": st.one_of(st.just(math.inf), st.floats(0.5, 5.0)),
    "factor": st.floats(0.9, 1.1),
}


def _road(*sleepers: dict) -> RoadAhead:
    """The road ahead of sleepers: the curve (none where its V_w is inf), the path's end beyond it."""
    curve_m = [math.inf if math.isinf(x["warning_speed_mps"]) else x["distance_m"] for x in sleepers]
    columns = (curve_m, [x["distance_m"] + x["beyond_m"] for x in sleepers])
    columns += ([x["warning_speed_mps"] for x in sleepers], [x["factor"] for x in sleepers])
    return RoadAhead(*(np.array(column, dtype=float) for column in columns))


@given(**SLEEPERS)
def test_a_sleeping_vehicle_cannot_be_warned_before_it_wakes(
    distance_m, beyond_m, warning_speed_mps, speed_mps, bound_mps, accel_mps2, factor
):
    """Driven as fast as SUMO allows (speed rising by at most its acceleration up to its bound, each step
    advancing that step's speed times the step), a sleeping vehicle is at every step before its wake-up either
    below the curve's V_w or still farther from it than S_w + allowance at its speed then (formula (1)), and
    farther from its path's end than S_w + allowance with V_w = 0."""
    settings = WarningSettings(update_period_s=STEP_S)
    schedule = WakeSchedule(STEP_S, settings)
    schedule.add("v", bound_mps, accel_mps2)
    sleeper = locals()
    schedule.sleep(0, ["v"], np.array([speed_mps]), _road(sleeper))
    wake = schedule.wake_step.get("v")
    if wake is None:
        return
    curve = not math.isinf(warning_speed_mps)
    fastest_mps = max(speed_mps, bound_mps)
    now_mps, driven_m = speed_mps, 0.0
    for _ in range(1, wake):
        now_mps = min(fastest_mps, now_mps + accel_mps2 * STEP_S)
        driven_m += now_mps * STEP_S
        for ahead_m, v_w in ((distance_m, warning_speed_mps), (distance_m + beyond_m, 0.0)):
            if v_w == warning_speed_mps and not curve:
                continue
            left_m = ahead_m - (LANE_CHANGE_MARGIN_M + LANE_CHANGE_MARGIN_SHARE * ahead_m) - driven_m / factor
            assert now_mps < v_w or left_m > _formula_1_reach_m(now_mps, settings, v_w) - 1e-6
    assert schedule.wake_due(wake) == {"v": 0}


@given(**SLEEPERS, period_s=st.one_of(st.none(), st.floats(STEP_S, 2.0)))
def test_a_vehicle_kept_awake_by_the_array_test_is_one_that_could_be_warned_at_the_next_step(
    distance_m, beyond_m, warning_speed_mps, speed_mps, bound_mps, accel_mps2, factor, period_s
):
    """The array test keeps a vehicle awake only where, at its present speed, the step it drives and the reach of
    formula (1) plus the allowance over the step, it could be warned at the curve (at or above its V_w) or come
    within reach of its path's end at the next step; and a vehicle it keeps awake is one the schedule itself would
    not put to sleep."""
    settings = WarningSettings(update_period_s=STEP_S)
    schedule = WakeSchedule(STEP_S, settings)
    road = _road(locals())
    awake = schedule.awake_next_step(np.array([speed_mps]), road)
    near = []
    for ahead_m, v_w in ((road.curve_m[0], warning_speed_mps), (road.end_m[0], 0.0)):
        if math.isinf(ahead_m):  # no curve part ahead
            continue
        left_m = ahead_m - (LANE_CHANGE_MARGIN_M + LANE_CHANGE_MARGIN_SHARE * ahead_m) - speed_mps * STEP_S / factor
        near.append(speed_mps >= v_w and left_m <= _formula_1_reach_m(speed_mps, settings, v_w) * (1 + 1e-9) + 1e-6)
    if not any(near):
        assert not awake[0]
    if awake[0]:
        schedule.add("v", bound_mps, accel_mps2)
        periods_s = None if period_s is None else np.array([period_s])
        schedule.sleep(0, ["v"], np.array([speed_mps]), road, periods_s)
        assert "v" not in schedule.wake_step


@given(sleepers=st.lists(st.fixed_dictionaries(SLEEPERS), min_size=1, max_size=6), shared=st.booleans())
def test_vehicles_put_to_sleep_together_wake_as_each_would_alone(sleepers, shared):
    """Scheduling many vehicles in one call wakes each at the step it would wake scheduled alone (the arrays of one
    vehicle never reach another's), also with one departing bound shared by all."""
    settings = WarningSettings(update_period_s=STEP_S)
    together = WakeSchedule(STEP_S, settings)
    ids = [f"v{i}" for i in range(len(sleepers))]
    for vehicle_id, sleeper in zip(ids, sleepers, strict=True):
        sleeper = sleepers[0] if shared else sleeper
        together.add(vehicle_id, sleeper["bound_mps"], sleeper["accel_mps2"])
    together.sleep(3, ids, np.array([sleeper["speed_mps"] for sleeper in sleepers]), _road(*sleepers))
    for vehicle_id, sleeper in zip(ids, sleepers, strict=True):
        alone = WakeSchedule(STEP_S, settings)
        bound = sleepers[0] if shared else sleeper
        alone.add("v", bound["bound_mps"], bound["accel_mps2"])
        alone.sleep(3, ["v"], np.array([sleeper["speed_mps"]]), _road(sleeper))
        assert together.wake_step.get(vehicle_id) == alone.wake_step.get("v")


#: A horizon's curve parts: (start, length, radius at its start, at its end), m.
PARTS = st.lists(
    st.tuples(st.floats(0.0, 2000.0), st.floats(0.0, 300.0), st.floats(10.0, 2000.0), st.floats(10.0, math.inf)),
    max_size=8,
)


@given(
    roads=st.lists(st.tuples(PARTS, st.floats(100.0, 2600.0)), min_size=1, max_size=4),
    vehicles=st.lists(st.tuples(st.integers(0, 3), st.floats(0.0, 2500.0), st.integers(0, 2)), max_size=12),
    capacity=st.integers(1, 6),
    road_width_m=st.floats(0.0, 20.0),
)
def test_the_road_ahead_is_the_nearest_part_not_passed_its_lowest_warning_speed_and_the_paths_end(
    roads, vehicles, capacity, road_width_m
):
    """The distance to the first curve part is that to the nearest start among the parts whose end (plus the
    CPOIs' end margin) is still ahead, 0 inside one; the V_w bound is the lowest of those parts' at their
    tightest radius less the road's width, for the vehicle's column; with none ahead, neither; the end is
    the path's; for many vehicles on several horizons at once, over calls that lay out new horizons and empty
    a small pool."""
    horizons = []
    for parts, length_m in roads:
        starts = np.array([start for start, _, _, _ in parts], dtype=float)
        ends = np.array([start + length for start, length, _, _ in parts], dtype=float)
        radii, end_radii = (np.array([part[k] for part in parts], dtype=float) for k in (2, 3))
        path = SimpleNamespace(length_m=length_m, lane_position_factor=np.array([1.02, 0.98]))
        horizons.append(
            SimpleNamespace(
                part_start_s=starts, part_end_s=ends, part_radius_m=radii, part_end_radius_m=end_radii, path=path
            )
        )
    pool = PartsAhead(capacity, radius_margin_m=road_width_m)
    lowest = lowest_accelerations_mps2(WarningSettings().policy)
    for batch in (vehicles[: len(vehicles) // 2], vehicles):
        chosen = [horizons[k % len(horizons)] for k, _, _ in batch]
        vehicle_s = np.array([s for _, s, _ in batch], dtype=float)
        columns = np.array([column for _, _, column in batch], dtype=np.intp)
        road = pool.ahead(chosen, vehicle_s, columns)
        for k, (horizon, s, column) in enumerate(zip(chosen, vehicle_s.tolist(), columns.tolist(), strict=True)):
            ahead = [
                (start, min(radius, end_radius))
                for start, end, radius, end_radius in zip(
                    horizon.part_start_s.tolist(),
                    (horizon.part_end_s + END_MARGIN_M).tolist(),
                    horizon.part_radius_m.tolist(),
                    horizon.part_end_radius_m.tolist(),
                    strict=True,
                )
                if end > s
            ]
            nearest = min((start for start, _ in ahead), default=math.inf)
            assert road.curve_m[k] == max(nearest - s, 0.0)
            assert road.end_m[k] == max(horizon.path.length_m - s, 0.0)
            slowest = min((tightest for _, tightest in ahead), default=math.inf) - road_width_m
            expected_mps = math.sqrt(lowest[column] * max(slowest, 0.0)) - kmh_to_mps(1e-6) if ahead else math.inf
            assert road.warning_speed_mps[k] == pytest.approx(max(expected_mps, 0.0), rel=1e-12, abs=1e-12)
            assert road.factor[k] == 0.98


@pytest.mark.parametrize("category", ["M1", "M2", "M3", "N", "O"])
def test_the_warning_speed_bound_is_below_both_levels_at_every_radius_from_its_own_on(category):
    """sqrt(a_min R) with the least lateral acceleration of the category's column is below Tables 1-2's V_w of
    both levels at R and at every larger radius, so a vehicle below it cannot be warned at a part of radius R."""
    radii_m = np.geomspace(1.0, 5000.0, 4000)
    column = column_index(category)
    bound_mps = lowest_warning_speeds_mps(radii_m, lowest_accelerations_mps2(WarningSettings().policy))[column]
    v_w_mps = np.array([[kmh_to_mps(warning_speed(r, category, level)) for r in radii_m] for level in (1, 2)])
    assert np.all(bound_mps < v_w_mps.min(axis=0))
    assert np.all(np.diff(bound_mps) >= 0.0)
    assert np.all(bound_mps > 0.9 * v_w_mps.min(axis=0))  # close to the tables: the schedule gains by it


def test_the_speed_bound_is_the_lower_of_the_types_and_the_fastest_lanes():
    assert speed_bound_mps(30.0, 1.2, 25.0) == 30.0
    assert speed_bound_mps(50.0, 1.2, 25.0) == pytest.approx(30.0)
    assert math.isclose(speed_bound_mps(22.0, 0.8, 25.0), 20.0)
    assert np.isfinite(speed_bound_mps(22.0, 0.8, 25.0))
