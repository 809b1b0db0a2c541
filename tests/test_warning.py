"""The two-level warning (clause 6) against the standard's test tables and constructed approaches."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from csws.data import standard_tables
from csws.standard import Category, Level, warning_distance, warning_speed
from csws.warning.rules import (
    CurvaturePointOfInterest,
    HmiHint,
    PathKind,
    WarningSettings,
    column_indices,
    evaluate_batch,
)
from csws.warning.single import evaluate

TABLES = standard_tables()
COLUMN_CATEGORY = {"M1": "M1", "M2": "M2", "M3_N_O": "N"}
NO_LATENCY = WarningSettings(update_period_s=0.0, system_delay_s=0.0)


def _single_curve_rows(table_key: str):
    for radius, row in TABLES[table_key].items():
        if radius.startswith("_"):
            continue
        for column, cells in row.items():
            for speed_kmh, distance_m in cells:
                yield pytest.param(
                    float(radius), COLUMN_CATEGORY[column], speed_kmh, distance_m, id=f"R{radius}-{column}-V{speed_kmh}"
                )


def _cpoi(distance_m: float, radius_m: float, curve_id: str = "c1", part_index: int = 0):
    return CurvaturePointOfInterest(curve_id, part_index, distance_m, radius_m)


@pytest.mark.parametrize(
    "radius_m, category, speed_kmh, table_distance_m", list(_single_curve_rows("table5_single_curve_level1_tests"))
)
def test_table_5_level_1_is_on_at_the_table_distance(radius_m, category, speed_kmh, table_distance_m):
    result = evaluate(speed_kmh, category, [_cpoi(table_distance_m, radius_m)])
    assert result.level >= Level.LEVEL_1
    assert result.target.curve_id == "c1"


@pytest.mark.parametrize(
    "radius_m, category, speed_kmh, table_distance_m", list(_single_curve_rows("table6_single_curve_level2_tests"))
)
def test_table_6_level_2_is_on_at_the_table_distance(radius_m, category, speed_kmh, table_distance_m):
    result = evaluate(speed_kmh, category, [_cpoi(table_distance_m, radius_m)])
    assert result.level == Level.LEVEL_2
    assert result.hmi == HmiHint.for_level(Level.LEVEL_2)


def test_without_latency_compensation_the_rows_where_the_table_exceeds_formula_1_fail():
    """Table 5, R=200, M3-N-O, V=100 km/h: table 43 m, formula (1) 41.36 m."""
    cpois = [_cpoi(43.0, 200.0)]
    assert evaluate(100.0, "N", cpois, settings=NO_LATENCY).level == Level.NONE
    assert evaluate(100.0, "N", cpois).level == Level.LEVEL_1


@pytest.mark.parametrize(
    "radius_m, category, speed_kmh, table_distance_m", list(_single_curve_rows("table5_single_curve_level1_tests"))
)
def test_no_warning_3_kmh_below_the_level_1_warning_speed(radius_m, category, speed_kmh, table_distance_m):
    slow_kmh = warning_speed(radius_m, category, 1) - 3.0
    assert evaluate(slow_kmh, category, [_cpoi(0.0, radius_m)]).level == Level.NONE


def _onsets(speed_kmh: float, category: str, curve_starts_m: dict, radii_m: dict, step_m: float = 0.01):
    """Distance from each curve's start at which each (curve, level) first triggers, driving at constant speed.

    Every position of the approach is one row of a batch evaluation.
    """
    positions_m = np.arange(0.0, max(curve_starts_m.values()) + step_m, step_m)
    curves = list(curve_starts_m)
    starts = np.array([curve_starts_m[c] for c in curves])
    owner, which = np.divmod(np.arange(positions_m.size * len(curves)), len(curves))
    distance = np.maximum(starts[which] - positions_m[owner], 0.0)
    radius = np.array([radii_m[c] for c in curves])[which]
    batch = evaluate_batch(
        np.full(positions_m.size, speed_kmh), column_indices([category] * positions_m.size), owner, distance, radius
    )
    onsets = {}
    for index, curve in enumerate(curves):
        for level in (1, 2):
            on = (which == index) & (batch.cpoi_level >= level) & (positions_m[owner] <= starts[index])
            if on.any():
                onsets[(curve, level)] = float(starts[index] - positions_m[owner[on]].min())
    return onsets


def _multi_curve_tests(table_key: str):
    table = TABLES[table_key]
    for column in ("M1", "M2", "M3_N_O"):
        for test in table[column]:
            yield pytest.param(COLUMN_CATEGORY[column], test, table["R2_m"], id=f"{column}-test{test['test']}")


def _multi_curve_onsets(category: str, test: dict, curve2_radius_m: float) -> dict:
    """Onset distances (to each curve's start) on curve 1 of the test's R1, L1 joined directly to curve 2."""
    starts = {"curve1": APPROACH_M, "curve2": APPROACH_M + test["L1_m"]}
    radii = {"curve1": float(test["R1_m"]), "curve2": float(curve2_radius_m)}
    return _onsets(test["V_kmh"], category, starts, radii)


APPROACH_M = 300.0


@pytest.mark.parametrize(
    "category, test, curve2_radius_m", list(_multi_curve_tests("table8_multi_curve_curve2_first_all_before_curve1"))
)
def test_table_8_curve_2_warnings_come_before_curve_1(category, test, curve2_radius_m):
    onsets = _multi_curve_onsets(category, test, curve2_radius_m)
    for level in (1, 2):
        table_m = test["S_w_m"][f"curve2_level{level}"]
        assert onsets[("curve2", level)] >= table_m
        # 7.5.3.2: both curve-2 warning points lie before curve 1.
        assert onsets[("curve2", level)] > test["L1_m"]


@pytest.mark.parametrize(
    "category, test, curve2_radius_m", list(_multi_curve_tests("table9_multi_curve_curve2_first_alternating"))
)
def test_table_9_warnings_alternate_curve_2_first(category, test, curve2_radius_m):
    onsets = _multi_curve_onsets(category, test, curve2_radius_m)
    # Position along the road (from curve 1's start, negative before it) of each onset.
    curve_offset_m = {"curve1": 0.0, "curve2": test["L1_m"]}
    position = {key: curve_offset_m[key[0]] - distance for key, distance in onsets.items()}
    order = sorted(position, key=position.get)
    assert order == [("curve2", 1), ("curve1", 1), ("curve2", 2), ("curve1", 2)]
    for (curve, level), distance in onsets.items():
        assert distance >= test["S_w_m"][f"{curve}_level{level}"]


def test_level_2_has_priority_and_the_target_is_the_nearest_of_the_highest_level():
    # M1 at 90 km/h: R=120 only reaches level 1 (V_w1 83, V_w2 96); R=40 reaches level 2 (V_w2 55).
    near_level_1 = _cpoi(5.0, 120.0, "near")
    far_level_2 = _cpoi(30.0, 40.0, "far")
    farther_level_2 = _cpoi(40.0, 40.0, "farther")
    result = evaluate(90.0, "M1", [farther_level_2, far_level_2, near_level_1])
    assert result.level == Level.LEVEL_2
    assert result.target.curve_id == "far"
    assert [(t.curve_id, t.level) for t in result.triggers] == [
        ("near", Level.LEVEL_1),
        ("far", Level.LEVEL_2),
        ("farther", Level.LEVEL_2),
    ]
    only_level_1 = evaluate(90.0, "M1", [near_level_1])
    assert only_level_1.level == Level.LEVEL_1
    assert only_level_1.hmi.audible is None and only_level_1.hmi.visual is not None
    assert result.hmi.audible is not None and result.hmi.visual != only_level_1.hmi.visual


def test_several_triggering_curves_are_all_listed():
    result = evaluate(90.0, "N", [_cpoi(10.0, 40.0, "a"), _cpoi(30.0, 40.0, "b"), _cpoi(40.0, 120.0, "c")])
    assert {t.curve_id for t in result.triggers} == {"a", "b", "c"}
    assert result.path_kind is PathKind.ROUTE


def test_nothing_on_a_straight():
    assert evaluate(130.0, "M1", []).level == Level.NONE
    assert evaluate(130.0, "M1", [_cpoi(0.0, math.inf)]).level == Level.NONE


@settings(max_examples=200, deadline=None)
@given(
    speed_kmh=st.floats(0.0, 200.0),
    distance_m=st.floats(0.0, 300.0),
    radius_m=st.floats(15.0, 600.0),
    category=st.sampled_from(list(Category)),
)
def test_level_2_implies_the_level_1_condition_and_nothing_below_v_w(speed_kmh, distance_m, radius_m, category):
    result = evaluate(speed_kmh, category, [_cpoi(distance_m, radius_m)])
    v_w1 = warning_speed(radius_m, category, 1)
    allowance_m = speed_kmh / 3.6 * WarningSettings().latency_s
    level_1_condition = speed_kmh >= v_w1 and distance_m <= warning_distance(speed_kmh, v_w1) + allowance_m
    if result.level == Level.LEVEL_2:
        assert level_1_condition
    if speed_kmh < v_w1:
        assert result.level == Level.NONE
    assert (result.level >= Level.LEVEL_1) == level_1_condition


@settings(max_examples=100, deadline=None)
@given(
    radius_m=st.floats(30.0, 300.0),
    excess_kmh=st.floats(3.0, 40.0),
    category=st.sampled_from(list(Category)),
)
def test_the_warning_distance_grows_with_speed(radius_m, excess_kmh, category):
    v_w1 = warning_speed(radius_m, category, 1)
    slower = _onsets(v_w1 + excess_kmh, category, {"c": 400.0}, {"c": radius_m}, step_m=0.05)
    faster = _onsets(v_w1 + excess_kmh + 5.0, category, {"c": 400.0}, {"c": radius_m}, step_m=0.05)
    assert faster[("c", 1)] > slower[("c", 1)]


def _drive_compliant(speed_kmh: float, radius_m: float, category: str, update_period_s: float) -> float:
    """Speed (km/h) at the curve start of a driver who brakes at 4.9 m/s^2 0.8 s after a level-1 warning.

    The vehicle moves in steps of 1 ms; the system sees it only every ``update_period_s``.
    """
    settings = WarningSettings(update_period_s=update_period_s)
    target_mps = warning_speed(radius_m, category, 1) / 3.6
    speed_mps = speed_kmh / 3.6
    curve_m = warning_distance(speed_kmh, warning_speed(radius_m, category, 1)) + 50.0
    step_s, updates_every = 0.001, round(update_period_s / 0.001)
    position_m, brake_at_s, tick = 0.0, math.inf, 0
    while position_m < curve_m:
        time_s = tick * step_s
        if brake_at_s == math.inf and tick % updates_every == 0:
            warning = evaluate(speed_mps * 3.6, category, [_cpoi(curve_m - position_m, radius_m)], settings=settings)
            if warning.level >= Level.LEVEL_1:
                brake_at_s = time_s + 0.8
        decel = 4.9 if time_s >= brake_at_s and speed_mps > target_mps else 0.0
        position_m += speed_mps * step_s - 0.5 * decel * step_s**2
        speed_mps = max(speed_mps - decel * step_s, target_mps) if decel else speed_mps
        tick += 1
    return speed_mps * 3.6


@settings(max_examples=100, deadline=None)
@given(
    radius_m=st.floats(30.0, 300.0),
    excess_kmh=st.floats(1.0, 50.0),
    category=st.sampled_from(list(Category)),
    update_period_s=st.sampled_from([0.01, 0.05, 0.1]),
)
def test_a_compliant_driver_reaches_the_curve_at_the_level_1_warning_speed(
    radius_m, excess_kmh, category, update_period_s
):
    """What formula (1) promises: 0.8 s reaction then 4.9 m/s^2 (= g/2) reaches V_w1 by the curve."""
    v_w1 = warning_speed(radius_m, category, 1)
    assert _drive_compliant(v_w1 + excess_kmh, radius_m, category, update_period_s) <= v_w1 + 1.0


def test_batch_evaluation_equals_one_vehicle_at_a_time():
    rng = np.random.default_rng(7)
    categories = [str(c) for c in rng.choice(list(Category), 200)]
    speeds = rng.uniform(20, 130, 200)
    owners = rng.integers(0, 200, 600)
    distances = rng.uniform(0, 150, 600)
    radii = rng.uniform(25, 400, 600)
    batch = evaluate_batch(speeds, column_indices(categories), owners, distances, radii)
    for vehicle in range(200):
        mine = np.flatnonzero(owners == vehicle)
        single = evaluate(speeds[vehicle], categories[vehicle], [_cpoi(distances[i], radii[i], str(i)) for i in mine])
        assert int(batch.level[vehicle]) == single.level
        target = int(batch.target[vehicle])
        assert (target >= 0) == (single.target is not None)
        if target >= 0:
            assert str(target) == single.target.curve_id


def test_settings_reject_bad_values():
    with pytest.raises(ValueError, match="update_period_s must be a non-negative"):
        WarningSettings(update_period_s=-0.1)
    with pytest.raises(ValueError, match="g_mps2 must be a positive"):
        WarningSettings(g_mps2=0.0)
