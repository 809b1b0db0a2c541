"""The subject's acceleration through the driver's reaction (GB/T 33577-2017 3.22, 4.5.6, Annex A.1) against
constructed truth.

GB/T 33577 Annex A.1 (ISO 15623 A.1) takes the subject at its speed through the reaction T,
D = v_SV T + ..., and formula (5) x_r = 0.8 v_r: a positive subject acceleration is not held
through it, a deceleration is. Each truth is computed here in closed form:

* a subject at v accelerating at a > 0 toward a stopped object x_c ahead needs, after T at its
  speed, a_req = v^2 / (2 (x_c - v T)); holding a it would be (v + a T)^2 / (2 (x_c - v T - a T^2 / 2));
* a subject slowing at d (not braking: T still counts) needs (v - d T)^2 / (2 (x_c - v T + d T^2 / 2));
* along a real approach with the acceleration kept, the clearance is x_c(t) = D - v0 t - a t^2 / 2 and
  the speed v(t) = v0 + a t: the collision warning comes where x_c(t) = v T + v^2 / (2 a_col), the
  latest useful warning (a driver who keeps accelerating 0.8 s after it, then brakes at 0.68 g, stops
  at the object) where x_c(t) = v 0.8 + a 0.8^2 / 2 + (v + 0.8 a)^2 / (2 * 0.68 g); each a quadratic
  in t solved here, and the warning comes first.
"""

from __future__ import annotations

import math

import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from csws.fcw.objects import EgoMotion, SensorObject
from csws.fcw.physics import reaction_accel_mps2, required_deceleration_mps2
from csws.fcw.settings import MAX_COLLISION_A_REQ_MPS2, MIN_REACTION_TIME_S, FcwSettings
from csws.fcw.tracker import ForwardCollisionWarning

DEFAULT = FcwSettings()
REACTION_S = DEFAULT.reaction_time_s + DEFAULT.brake_response_s


def _steady_a_req_mps2(clearance_m: float, speed_mps: float, reaction_s: float) -> float:
    """a_req toward a stopped object with the subject at its speed through the reaction (Annex A.1)."""
    return speed_mps**2 / (2.0 * (clearance_m - speed_mps * reaction_s))


def _held_a_req_mps2(clearance_m: float, speed_mps: float, accel_mps2: float, reaction_s: float) -> float:
    """a_req toward a stopped object with the subject's acceleration held through the reaction."""
    after_mps = speed_mps + accel_mps2 * reaction_s
    return after_mps**2 / (2.0 * (clearance_m - speed_mps * reaction_s - accel_mps2 * reaction_s**2 / 2.0))


@settings(deadline=None, max_examples=200)
@given(st.floats(10.0, 27.8), st.floats(0.05, 2.0), st.floats(1.05, 4.0))
def test_an_accelerating_subjects_a_req_takes_it_at_its_speed_through_the_reaction(speed_mps, accel_mps2, room):
    """Toward a stopped object a_req is the constant-speed value of Annex A.1, below the value holding the
    acceleration; the same in the vehicle's tracker as in the formula."""
    clearance_m = room * speed_mps * REACTION_S + 1.0
    expected = _steady_a_req_mps2(clearance_m, speed_mps, REACTION_S)
    a_req = required_deceleration_mps2(clearance_m, -speed_mps, 0.0, REACTION_S, accel_mps2, speed_mps)
    assert a_req == pytest.approx(expected, rel=1e-9)
    held_left_m = clearance_m - speed_mps * REACTION_S - accel_mps2 * REACTION_S**2 / 2.0
    if held_left_m > 0.0:
        assert a_req < _held_a_req_mps2(clearance_m, speed_mps, accel_mps2, REACTION_S)
    frame = ForwardCollisionWarning(DEFAULT).update(
        0.0, EgoMotion(speed_mps, accel_mps2), [SensorObject(1, clearance_m, 0.0, -speed_mps, 0.0)]
    )
    assert frame.a_req_mps2 == pytest.approx(expected, rel=1e-9)


@settings(deadline=None, max_examples=200)
@given(st.floats(10.0, 27.8), st.floats(0.05, 3.0), st.floats(1.05, 4.0))
def test_a_slowing_subjects_deceleration_is_held_through_the_reaction(speed_mps, decel_mps2, room):
    """A subject slowing (off the throttle, not braking: T counts, 4.5.4) keeps slowing through the reaction;
    a_req is the closed form with that deceleration held, below the constant-speed value."""
    assume(speed_mps - decel_mps2 * REACTION_S > 0.5)
    clearance_m = room * speed_mps * REACTION_S + 1.0
    after_mps = speed_mps - decel_mps2 * REACTION_S
    expected = after_mps**2 / (2.0 * (clearance_m - speed_mps * REACTION_S + decel_mps2 * REACTION_S**2 / 2.0))
    a_req = required_deceleration_mps2(clearance_m, -speed_mps, 0.0, REACTION_S, -decel_mps2, speed_mps)
    assert a_req == pytest.approx(expected, rel=1e-9)
    assert a_req < _steady_a_req_mps2(clearance_m, speed_mps, REACTION_S)


def test_the_subjects_acceleration_held_through_the_reaction_is_its_deceleration_alone():
    """Annex A.1: a positive acceleration is taken as 0, a deceleration kept; floats and arrays alike."""
    assert reaction_accel_mps2(1.1) == 0.0
    assert reaction_accel_mps2(-2.5) == -2.5
    assert list(reaction_accel_mps2([0.4, 0.0, -1.0])) == [0.0, 0.0, -1.0]


def _first_time_within_s(start_m: float, speed_mps: float, accel_mps2: float, p0: float, p1: float, p2: float):
    """The first t at which x_c(t) = start_m - v0 t - a t^2 / 2 falls to p0 + p1 v(t) + p2 v(t)^2, v(t) = v0 + a t:
    the positive root of A t^2 + B t + C = 0 (A, B < 0 < C), s."""
    a_coef = -accel_mps2 / 2.0 - p2 * accel_mps2**2
    b_coef = -speed_mps - p1 * accel_mps2 - 2.0 * p2 * speed_mps * accel_mps2
    c_coef = start_m - p0 - p1 * speed_mps - p2 * speed_mps**2
    return (-b_coef - math.sqrt(b_coef**2 - 4.0 * a_coef * c_coef)) / (2.0 * a_coef)


def _collision_warning_s(start_m: float, speed_mps: float, accel_mps2: float, step_s: float) -> float | None:
    """The first frame at which the default tracker gives the collision warning on the approach, s."""
    fcw = ForwardCollisionWarning(DEFAULT)
    for index in range(int(60.0 / step_s)):
        t = index * step_s
        clearance_m, now_mps = start_m - speed_mps * t - accel_mps2 * t * t / 2.0, speed_mps + accel_mps2 * t
        if clearance_m <= 0.0:
            return None
        frame = fcw.update(t, EgoMotion(now_mps, accel_mps2), [SensorObject(1, clearance_m, 0.0, -now_mps, 0.0)])
        if frame.level >= 2:
            return t
    return None


@settings(deadline=None, max_examples=60)
@given(st.floats(10.0, 20.0), st.floats(0.1, 1.5), st.sampled_from([0.02, 0.05]))
def test_an_accelerating_subject_is_warned_before_the_latest_useful_warning(speed_mps, accel_mps2, step_s):
    """A subject accelerating toward a stopped car, 6 s away at its speed, keeps accelerating: the collision
    warning comes where the closed form puts it (the subject at its speed through the 1.2 s reaction) and
    before the latest useful warning, which a driver who keeps accelerating for 0.8 s after it and then brakes
    at 0.68 g needs (computed with his real acceleration through the 0.8 s)."""
    start_m = 6.0 * speed_mps
    col = DEFAULT.collision_a_req_mps2
    design_s = _first_time_within_s(start_m, speed_mps, accel_mps2, 0.0, REACTION_S, 1.0 / (2.0 * col))
    assume(speed_mps + accel_mps2 * design_s <= DEFAULT.max_speed_mps)
    late, hardest = MIN_REACTION_TIME_S, MAX_COLLISION_A_REQ_MPS2
    latest_s = _first_time_within_s(
        start_m,
        speed_mps,
        accel_mps2,
        accel_mps2 * late**2 / 2.0 + (accel_mps2 * late) ** 2 / (2.0 * hardest),
        late + accel_mps2 * late / hardest,
        1.0 / (2.0 * hardest),
    )
    warned_s = _collision_warning_s(start_m, speed_mps, accel_mps2, step_s)
    assert warned_s is not None
    assert design_s - 1e-9 <= warned_s < design_s + step_s + 1e-9
    assert warned_s < latest_s, (warned_s, latest_s)
    held_s = _first_time_within_s(
        start_m,
        speed_mps,
        accel_mps2,
        accel_mps2 * REACTION_S**2 / 2.0 + (accel_mps2 * REACTION_S) ** 2 / (2.0 * col),
        REACTION_S + accel_mps2 * REACTION_S / col,
        1.0 / (2.0 * col),
    )
    assert held_s < design_s  # holding the acceleration warned earlier: the change moves the warning later
