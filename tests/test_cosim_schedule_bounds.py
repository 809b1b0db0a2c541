"""The curve warning's wake schedule (:mod:`csws.cosim.schedule`) against bounds written out here: a sleeping
vehicle cannot come within formula (1) with V_w = 0 plus the allowance of its first curve part before it wakes, the
array test keeps awake only vehicles that could at the next step, vehicles scheduled together wake as each would
alone, and the first part ahead is read from the horizons as its definition says. The runs that compare scheduled
with every-step warnings are in tests/test_cosim_schedule.py."""

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
    WakeSchedule,
    speed_bound_mps,
)
from csws.standard import G_MPS2, REACTION_TIME_S
from csws.warning.settings import WarningSettings

STEP_S = 0.1


def _formula_1_reach_m(speed_mps: float, settings: WarningSettings) -> float:
    """S_w with V_w = 0 plus the latency allowance at ``speed_mps``, m: formula (1) written out here."""
    return (
        REACTION_TIME_S * speed_mps
        + speed_mps**2 / G_MPS2
        + speed_mps * (settings.update_period_s + settings.system_delay_s)
    )


#: A sleeping vehicle: its distance to the curve, its speed, SUMO's bound on it, its acceleration and the lane's
#: length factor.
SLEEPERS = {
    "distance_m": st.floats(0.0, 3000.0),
    "speed_mps": st.floats(0.0, 40.0),
    "bound_mps": st.floats(1.0, 40.0),
    "accel_mps2": st.one_of(st.just(math.inf), st.floats(0.5, 5.0)),
    "factor": st.floats(0.9, 1.1),
}


@given(**SLEEPERS)
def test_a_sleeping_vehicle_cannot_reach_a_warning_distance_before_it_wakes(
    distance_m, speed_mps, bound_mps, accel_mps2, factor
):
    """Driven as fast as SUMO allows (speed rising by at most its acceleration up to its bound, each step
    advancing that step's speed times the step), a sleeping vehicle is at every step before its wake-up
    still farther from the curve than S_w + allowance at its speed then (formula (1) with V_w = 0)."""
    settings = WarningSettings(update_period_s=STEP_S)
    schedule = WakeSchedule(STEP_S, settings)
    schedule.add("v", bound_mps, accel_mps2)
    schedule.sleep(0, ["v"], np.array([speed_mps]), np.array([distance_m]), np.array([factor]))
    wake = schedule.wake_step.get("v")
    if wake is None:
        return
    margin_m = LANE_CHANGE_MARGIN_M + LANE_CHANGE_MARGIN_SHARE * distance_m
    fastest_mps = max(speed_mps, bound_mps)
    now_mps, driven_m = speed_mps, 0.0
    for _ in range(1, wake):
        now_mps = min(fastest_mps, now_mps + accel_mps2 * STEP_S)
        driven_m += now_mps * STEP_S
        left_m = distance_m - margin_m - driven_m / factor
        assert left_m > _formula_1_reach_m(now_mps, settings) * (1 - 1e-9)
    assert schedule.wake_due(wake) == {"v": 0}


@given(**SLEEPERS, period_s=st.one_of(st.none(), st.floats(STEP_S, 2.0)))
def test_a_vehicle_kept_awake_by_the_array_test_is_one_that_could_be_warned_at_the_next_step(
    distance_m, speed_mps, bound_mps, accel_mps2, factor, period_s
):
    """The array test keeps a vehicle awake only where, at its present speed, the step it drives and the reach of
    formula (1) with V_w = 0 plus the allowance over the step, the margined distance to the curve is covered at
    the next step; and a vehicle it keeps awake is one the schedule itself would not put to sleep."""
    settings = WarningSettings(update_period_s=STEP_S)
    schedule = WakeSchedule(STEP_S, settings)
    awake = schedule.awake_next_step(np.array([speed_mps]), np.array([distance_m]), np.array([factor]))
    margin_m = LANE_CHANGE_MARGIN_M + LANE_CHANGE_MARGIN_SHARE * distance_m
    left_m = distance_m - margin_m - speed_mps * STEP_S / factor
    if left_m > _formula_1_reach_m(speed_mps, settings) * (1 + 1e-9):
        assert not awake[0]
    if awake[0]:
        schedule.add("v", bound_mps, accel_mps2)
        periods_s = None if period_s is None else np.array([period_s])
        schedule.sleep(0, ["v"], np.array([speed_mps]), np.array([distance_m]), np.array([factor]), periods_s)
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
    columns = {
        name: np.array([sleeper[name] for sleeper in sleepers]) for name in ("speed_mps", "distance_m", "factor")
    }
    together.sleep(3, ids, columns["speed_mps"], columns["distance_m"], columns["factor"])
    for vehicle_id, sleeper in zip(ids, sleepers, strict=True):
        alone = WakeSchedule(STEP_S, settings)
        bound = sleepers[0] if shared else sleeper
        alone.add("v", bound["bound_mps"], bound["accel_mps2"])
        alone.sleep(3, ["v"], *(np.array([sleeper[name]]) for name in ("speed_mps", "distance_m", "factor")))
        assert together.wake_step.get(vehicle_id) == alone.wake_step.get("v")


#: A horizon's curve parts: (start, length), m.
PARTS = st.lists(st.tuples(st.floats(0.0, 2000.0), st.floats(0.0, 300.0)), max_size=8)


@given(
    roads=st.lists(st.tuples(PARTS, st.floats(100.0, 2600.0)), min_size=1, max_size=4),
    vehicles=st.lists(st.tuples(st.integers(0, 3), st.floats(0.0, 2500.0)), max_size=12),
    capacity=st.integers(1, 6),
)
def test_the_first_part_ahead_is_the_nearest_start_among_the_parts_not_passed(roads, vehicles, capacity):
    """The distance to the first curve part is that to the nearest start among the parts whose end (plus the
    CPOIs' end margin) is still ahead, 0 inside one, else to the end of the path; for many vehicles on several
    horizons at once, over calls that lay out new horizons and empty a small pool."""
    horizons = []
    for parts, length_m in roads:
        starts = np.array([start for start, _ in parts], dtype=float)
        ends = np.array([start + length for start, length in parts], dtype=float)
        path = SimpleNamespace(length_m=length_m, lane_position_factor=np.array([1.02, 0.98]))
        horizons.append(SimpleNamespace(part_start_s=starts, part_end_s=ends, path=path))
    pool = PartsAhead(capacity)
    for batch in (vehicles[: len(vehicles) // 2], vehicles):
        chosen = [horizons[k % len(horizons)] for k, _ in batch]
        vehicle_s = np.array([s for _, s in batch], dtype=float)
        distances_m, factors = pool.distances_m(chosen, vehicle_s)
        for horizon, s, distance_m, factor in zip(chosen, vehicle_s.tolist(), distances_m, factors, strict=True):
            ends_s = horizon.part_end_s + END_MARGIN_M
            ahead = [a for a, end in zip(horizon.part_start_s.tolist(), ends_s.tolist(), strict=True) if end > s]
            assert distance_m == max(min(ahead, default=horizon.path.length_m) - s, 0.0)
            assert factor == 0.98


def test_the_speed_bound_is_the_lower_of_the_types_and_the_fastest_lanes():
    assert speed_bound_mps(30.0, 1.2, 25.0) == 30.0
    assert speed_bound_mps(50.0, 1.2, 25.0) == pytest.approx(30.0)
    assert math.isclose(speed_bound_mps(22.0, 0.8, 25.0), 20.0)
    assert np.isfinite(speed_bound_mps(22.0, 0.8, 25.0))
