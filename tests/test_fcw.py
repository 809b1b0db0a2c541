"""Forward collision warning against GB/T 33577-2017: its formulas computed by hand, and its
tests (5.4.1, 5.5.2.1) and IVISTA's FCW scenarios driven here as exact kinematics."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from csws.fcw.physics import (
    enhanced_time_to_collision_s,
    evaluate_fcw,
    formula_5_clearance_m,
    required_deceleration_mps2,
    time_to_collision_s,
)
from csws.fcw.settings import STANDARD_GRAVITY_MPS2, FcwSettings

G = STANDARD_GRAVITY_MPS2


def test_ttc_is_clearance_over_closing_speed_and_none_while_not_closing():
    assert time_to_collision_s(50.0, -10.0) == pytest.approx(5.0)
    assert time_to_collision_s(50.0, 0.0) == math.inf and time_to_collision_s(50.0, 3.0) == math.inf


def test_ettc_of_a_lead_braking_from_equal_speed_is_when_the_gap_is_gone():
    # Both at 20 m/s, 30 m apart, the lead brakes at 0.3 g: 30 = 0.3 g t^2 / 2.
    assert enhanced_time_to_collision_s(30.0, 0.0, -0.3 * G) == pytest.approx(math.sqrt(60.0 / (0.3 * G)))


def test_ettc_is_the_smaller_root_of_formula_3_and_ttc_without_relative_acceleration():
    x_c, v_r, a = 40.0, -12.0, 1.5  # the lead pulls away while still slower
    by_formula_3 = (-v_r - math.sqrt(v_r**2 - 2.0 * a * x_c)) / a
    assert enhanced_time_to_collision_s(x_c, v_r, a) == pytest.approx(by_formula_3)
    assert enhanced_time_to_collision_s(x_c, v_r, 0.0) == pytest.approx(time_to_collision_s(x_c, v_r))
    assert enhanced_time_to_collision_s(10.0, -2.0, 1.0) == math.inf  # the lead gets away first


def test_required_deceleration_meets_the_warning_distance_of_formula_5():
    """Formula (5): with T_resp 0.8 s and a_req 6.67 m/s^2, the shortest warning distance for a
    closing speed v_r on a steady lead is v_r^2 / (2 * 6.67) + 0.8 v_r; formula (4) gives exactly
    6.67 m/s^2 there. On a lead that brakes, formula (4) read at the end of the reaction asks for
    more there: the lead's braking during the reaction adds closing speed that (5) leaves out."""
    for closing_mps in (20.0, 12.0):
        distance_m = closing_mps**2 / (2.0 * 6.67) + 0.8 * closing_mps
        assert formula_5_clearance_m(closing_mps) == pytest.approx(distance_m)
        assert required_deceleration_mps2(distance_m, -closing_mps, 0.0, 0.8) == pytest.approx(6.67)
    braking_m = 8.0**2 / (2.0 * (6.67 - 2.0)) + 0.8 * 8.0
    assert formula_5_clearance_m(8.0, -2.0) == pytest.approx(braking_m)
    assert required_deceleration_mps2(braking_m, -8.0, -2.0, 0.8) > 6.67


def _closest_clearance_m(
    clearance_m: float,
    subject_mps: float,
    lead_mps: float,
    lead_accel_mps2: float,
    reaction_s: float,
    brake_mps2: float,
) -> float:
    """The least clearance, stepped finely: the subject holds its speed for ``reaction_s``, then brakes at
    ``brake_mps2``; the lead brakes at ``-lead_accel_mps2`` until it stops (independent of formula (4))."""
    step_s, time_s, least_m = 1e-4, 0.0, clearance_m
    while subject_mps > 0.0:
        subject_accel = 0.0 if time_s < reaction_s else -brake_mps2
        lead_accel = lead_accel_mps2 if lead_mps > 0.0 else 0.0
        clearance_m += (lead_mps - subject_mps) * step_s + (lead_accel - subject_accel) * step_s**2 / 2.0
        subject_mps = max(subject_mps + subject_accel * step_s, 0.0)
        lead_mps = max(lead_mps + lead_accel * step_s, 0.0)
        least_m, time_s = min(least_m, clearance_m), time_s + step_s
    return least_m


@pytest.mark.parametrize(
    ("subject_mps", "lead_mps", "lead_accel_mps2"), [(13.9, 13.9, -2.0), (20.0, 15.0, -1.5), (25.0, 25.0, -2.5)]
)
def test_a_driver_reacting_to_a_braking_lead_just_avoids_it_at_the_threshold(subject_mps, lead_mps, lead_accel_mps2):
    """3.22, formula (4) at the end of the reaction: warned where a_req reaches the threshold, a driver who
    reacts 1.2 s later and then brakes at exactly the threshold comes to rest just behind a braking lead
    (closest clearance 0, within the integration step); formula (4) with x_r = -v_r T alone would let him hit it."""
    settings = FcwSettings()
    threshold, reaction_s = settings.collision_a_req_mps2, settings.reaction_time_s
    v_r = lead_mps - subject_mps
    low, high = 0.1, 500.0  # the clearance where a_req falls to the threshold, by bisection
    for _ in range(200):
        middle = (low + high) / 2.0
        low, high = (
            (middle, high)
            if required_deceleration_mps2(middle, v_r, lead_accel_mps2, reaction_s) > threshold
            else (low, middle)
        )
    warned_at_m = high
    # The lead must still be moving when the relative speed reaches 0 for formula (4)'s held d_TV to hold.
    closing_after = subject_mps - lead_mps - lead_accel_mps2 * reaction_s
    assert lead_mps + lead_accel_mps2 * (reaction_s + closing_after / (threshold + lead_accel_mps2)) > 0.0
    least_m = _closest_clearance_m(warned_at_m, subject_mps, lead_mps, lead_accel_mps2, reaction_s, threshold)
    assert least_m == pytest.approx(0.0, abs=0.01)
    steady_reading = -lead_accel_mps2 + v_r**2 / (2.0 * (warned_at_m + v_r * reaction_s))
    assert steady_reading < threshold


def test_settings_keep_to_the_standards_limits():
    with pytest.raises(ValueError, match="0.68 g"):
        FcwSettings(collision_a_req_mps2=0.7 * G)
    with pytest.raises(ValueError, match="0.8 s"):
        FcwSettings(reaction_time_s=0.6)
    with pytest.raises(ValueError, match="preliminary"):
        FcwSettings(preliminary_a_req_mps2=0.6 * G)


def _drive(subject_mps: float, lead_mps: float, clearance_m: float, lead_accel_mps2: float, step_s: float):
    """The subject at constant speed behind a lead (braking to a stop where it brakes), one
    evaluation a step: the clearance and TTC at the first preliminary and collision warnings."""
    first: dict[int, tuple[float, float]] = {}
    while clearance_m > 0.0 and 2 not in first:
        accel = lead_accel_mps2 if lead_mps > 0.0 else 0.0
        batch = evaluate_fcw([0.0], [clearance_m], [lead_mps - subject_mps], [accel], [False])
        for level in range(1, int(batch.level[0]) + 1):
            first.setdefault(level, (clearance_m, float(batch.ttc_s[0])))
        new_lead_mps = max(0.0, lead_mps + accel * step_s)
        clearance_m += (0.5 * (lead_mps + new_lead_mps) - subject_mps) * step_s
        lead_mps = new_lead_mps
    return first


#: (subject m/s, lead m/s, clearance at the start m, lead acceleration m/s^2, TTC at the warning at least s)
TESTS = {
    "5.5.2.1.1 stationary lead": (20.0, 0.0, 150.0, 0.0, 2.1),
    "5.5.2.1.2 lead braking at 0.3 g": (20.0, 20.0, 30.0, -0.3 * G, 2.4),
    "5.5.2.1.3 slower lead": (20.0, 9.0, 150.0, 0.0, 2.0),
    "IVISTA A.1.1 stationary lead at 72 km/h": (72.0 / 3.6, 0.0, 150.0, 0.0, 2.1),
    "IVISTA A.1.2 lead at 20 km/h, 80 km/h": (80.0 / 3.6, 20.0 / 3.6, 150.0, 0.0, 2.0),
}


@pytest.mark.parametrize("step_s", [0.01, 0.05, 0.1, 0.2])
@pytest.mark.parametrize("test", TESTS.values(), ids=TESTS.keys())
def test_the_collision_warning_comes_in_time_for_each_test(test, step_s):
    subject_mps, lead_mps, clearance_m, lead_accel_mps2, least_ttc_s = test
    first = _drive(subject_mps, lead_mps, clearance_m, lead_accel_mps2, step_s)
    assert 2 in first, "no collision warning before the clearance was gone"
    assert first[2][1] >= least_ttc_s
    assert 1 in first and first[1][0] >= first[2][0]  # the preliminary warning came first (or with it)


@pytest.mark.parametrize("step_s", [0.01, 0.1])
def test_the_warning_distance_is_at_least_formula_5(step_s):
    """5.4.1: the subject at 20 m/s, the lead at 8 m/s on the same lane: the clearance at the
    collision warning is at least formula (5)'s (T_resp 0.8 s, a_req 6.67 m/s^2)."""
    shortest_m = 12.0**2 / (2.0 * 6.67) + 0.8 * 12.0
    assert _drive(20.0, 8.0, 150.0, 0.0, step_s)[2][0] >= shortest_m


def test_no_warning_while_braking_hard_not_closing_or_far_in_time():
    settings = FcwSettings()
    braking = evaluate_fcw([-settings.collision_a_req_mps2], [20.0], [-15.0], [0.0], [True])
    opening = evaluate_fcw([0.0], [5.0], [1.0], [0.0], [False])
    far = evaluate_fcw([0.0], [250.0], [-50.0], [0.0], [False])  # TTC 5 s
    assert braking.level[0] == 0 and opening.level[0] == 0 and far.level[0] == 0
    assert far.a_req_mps2[0] >= settings.collision_a_req_mps2  # a_req alone would warn


def test_a_braking_driver_needs_no_reaction_time():
    reacting, braking = (evaluate_fcw([0.0], [40.0], [-15.0], [0.0], [pressed]) for pressed in (False, True))
    assert braking.a_req_mps2[0] == pytest.approx(15.0**2 / (2.0 * 40.0))
    assert reacting.a_req_mps2[0] > braking.a_req_mps2[0]


@given(st.floats(1.0, 40.0), st.floats(0.5, 30.0), st.floats(-3.0, 1.0))
def test_closer_is_never_a_lower_warning(closing_mps, clearance_m, lead_accel_mps2):
    """At fixed speeds and accelerations, a smaller clearance never lowers the level, and the
    required deceleration never falls."""
    clearances = np.array([clearance_m * 2.0, clearance_m * 1.5, clearance_m])
    count = len(clearances)
    batch = evaluate_fcw(
        np.zeros(count),
        clearances,
        np.full(count, -closing_mps),
        np.full(count, lead_accel_mps2),
        np.zeros(count, dtype=bool),
    )
    assert np.all(np.diff(batch.level) >= 0)
    assert np.all(batch.a_req_mps2[1:] >= batch.a_req_mps2[:-1])  # inf where the reaction uses up the clearance


@given(st.floats(0.0, 300.0), st.floats(-50.0, 20.0), st.floats(-10.0, 10.0), st.floats(0.0, 2.0))
def test_floats_and_arrays_give_the_same_values_to_the_bit(clearance_m, v_r, accel_mps2, lost_s):
    """One vehicle's warning runs the formulas on floats, a fleet's on arrays: the same values."""
    pairs = (
        (time_to_collision_s(clearance_m, v_r), time_to_collision_s([clearance_m], [v_r])),
        (
            enhanced_time_to_collision_s(clearance_m, v_r, accel_mps2),
            enhanced_time_to_collision_s([clearance_m], [v_r], [accel_mps2]),
        ),
        (
            required_deceleration_mps2(clearance_m, v_r, accel_mps2, lost_s),
            required_deceleration_mps2([clearance_m], [v_r], [accel_mps2], [lost_s]),
        ),
    )
    for one, many in pairs:
        assert isinstance(one, float) and one == many[0]
