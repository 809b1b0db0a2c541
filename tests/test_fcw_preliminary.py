"""The preliminary warning's default threshold (GB/T 33577-2017 4.5.1, 4.5.3) against constructed truth.

Each truth is computed here in closed form. A steady subject closing at c on a lead at a constant
speed needs, after the reaction T, a_req = c^2 / (2 (x_c - c T)) (formula (4), x_r = c T), so a
level of threshold a comes on at x_c = c T + c^2 / (2 a), at a TTC of T + c / (2 a); the latest
useful warning (a driver reacting 0.8 s after it and braking at 0.68 g just stops closing at contact)
is at x_c = 0.8 c + c^2 / (2 * 0.68 g). A subject braking at d toward a stopped car (the driver
brakes: T = 0, 4.5.4) needs v^2 / (2 x_c).

* Approaching a slower or stopped lead, the default preliminary warning comes where the test puts it,
  before the collision warning by the time the test computes, and before the latest useful warning;
* a lead braking at 0.5 g from the subject's speed is warned no later than the latest useful warning
  (exact kinematics), as early as with the earlier 0.3 g preliminary threshold;
* approaching a queue's last car as SUMO's drivers do (cruising until a_req peaks between the earlier
  0.3 g and the default, then braking gently to a stop behind it), the default stays silent and the
  earlier 0.3 g, still a fleet's setting, gives the preliminary warning;
* the traffic benchmark's reference rules take an accelerating subject at its speed through the reaction
  (Annex A.1), by exact kinematics.
"""

from __future__ import annotations

import json
import math
from dataclasses import replace

import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from test_fcw_traffic import _braking_lead, least_deceleration_mps2

from csws.fcw.conforming import Lead, warning_due
from csws.fcw.objects import EgoMotion, SensorObject
from csws.fcw.settings import (
    EARLY_PRELIMINARY_A_REQ_MPS2,
    HIGHEST_MIN_SPEED_MPS,
    MAX_COLLISION_A_REQ_MPS2,
    MIN_REACTION_TIME_S,
    STANDARD_GRAVITY_MPS2,
    FcwSettings,
)
from csws.fcw.tracker import ForwardCollisionWarning
from csws.standard import Category
from csws.state import SystemState

G = STANDARD_GRAVITY_MPS2
DEFAULT = FcwSettings()
EARLY = replace(DEFAULT, preliminary_a_req_mps2=EARLY_PRELIMINARY_A_REQ_MPS2)
#: The approaches start this long (TTC) before contact, s.
START_TTC_S = 6.0
#: Where a braking subject stops behind the queue's last car, m.
STOP_BEHIND_M = 2.0


def _onset_clearance_m(closing_mps: float, threshold_mps2: float, reaction_s: float) -> float:
    """Where a_req = c^2 / (2 (x_c - c T)) of a steady approach reaches ``threshold_mps2``, m."""
    return closing_mps * reaction_s + closing_mps**2 / (2.0 * threshold_mps2)


def _approach_levels(subject_mps: float, lead_mps: float, step_s: float) -> list[tuple[float, int]]:
    """(clearance, level) per frame of the default system, a steady subject on a lead at a constant speed,
    from START_TTC_S to contact."""
    closing_mps = subject_mps - lead_mps
    fcw, frames = ForwardCollisionWarning(DEFAULT), []
    for index in range(int(START_TTC_S / step_s)):
        clearance_m = closing_mps * (START_TTC_S - index * step_s)
        lead = SensorObject(1, clearance_m, 0.0, -closing_mps, 0.0)
        frames.append((clearance_m, fcw.update(index * step_s, EgoMotion(subject_mps), [lead]).level))
    return frames


@settings(deadline=None, max_examples=80)
@given(st.floats(HIGHEST_MIN_SPEED_MPS, DEFAULT.max_speed_mps), st.floats(0.0, 1.0), st.sampled_from([0.01, 0.05]))
def test_approaching_a_lead_the_preliminary_warning_comes_before_the_collision_warning_and_in_time(
    subject_mps, lead_share, step_s
):
    """4.5.3: the preliminary warning at the clearance where a_req reaches its threshold, the collision warning
    at its own, (x_pre - x_col) / c later; both before the latest useful warning. Where the preliminary one's
    TTC, T + c / (2 a_pre), is above 4 s, 4.5.5 e holds it back: the closing speeds here keep it below."""
    lead_mps = lead_share * (subject_mps - 3.0)
    closing_mps, reaction_s = subject_mps - lead_mps, DEFAULT.reaction_time_s
    assume(reaction_s + closing_mps / (2.0 * DEFAULT.preliminary_a_req_mps2) <= DEFAULT.max_ttc_s - step_s)
    preliminary_m = _onset_clearance_m(closing_mps, DEFAULT.preliminary_a_req_mps2, reaction_s)
    collision_m = _onset_clearance_m(closing_mps, DEFAULT.collision_a_req_mps2, reaction_s)
    latest_useful_m = _onset_clearance_m(closing_mps, MAX_COLLISION_A_REQ_MPS2, MIN_REACTION_TIME_S)
    frames = _approach_levels(subject_mps, lead_mps, step_s)
    tolerance_m = 1e-6 * preliminary_m
    first_m, first_level = next(frame for frame in frames if frame[1] >= 1)
    assert preliminary_m - closing_mps * step_s - tolerance_m < first_m <= preliminary_m + tolerance_m
    collision_at_m = next(clearance_m for clearance_m, level in frames if level >= 2)
    assert collision_m - closing_mps * step_s - tolerance_m < collision_at_m <= collision_m + tolerance_m
    if preliminary_m - collision_m > closing_mps * step_s + 2.0 * tolerance_m:
        assert first_level == 1  # a frame of the preliminary warning alone before the collision warning
    lead_s = (first_m - collision_at_m) / closing_mps
    assert lead_s == pytest.approx((preliminary_m - collision_m) / closing_mps, abs=step_s + 1e-6)
    assert first_m > latest_useful_m


def _first_warning_s(settings_: FcwSettings, frames: list[tuple[float, float, float, float]], subject_mps: float):
    """The time of the first frame with any warning, s (None without one)."""
    fcw = ForwardCollisionWarning(settings_)
    for t, gap, lead_v, lead_a in frames:
        if fcw.update(t, EgoMotion(subject_mps), [SensorObject(1, gap, 0.0, lead_v - subject_mps, lead_a)]).level:
            return t
    return None


@pytest.mark.parametrize(("clearance_m", "speed_mps"), [(20.0, 15.0), (30.0, 20.0), (50.0, 20.0), (45.0, 25.0)])
@pytest.mark.parametrize("step_s", [0.01, 0.05])
def test_a_lead_braking_at_half_a_g_from_the_subjects_speed_is_warned_in_time(clearance_m, speed_mps, step_s):
    """The lead brakes at 0.5 g; the first warning comes no later than the last frame at which a driver reacting
    0.8 s after it and braking at 0.68 g avoids the lead (exact kinematics), and no later than with the earlier
    0.3 g preliminary threshold (at a TTC above 4 s, 4.5.5 e holds back either preliminary warning)."""
    frames = _braking_lead(clearance_m, speed_mps, speed_mps, 0.5 * G, step_s)
    useful = [
        t
        for t, gap, lead_v, lead_a in frames
        if least_deceleration_mps2(gap, speed_mps, lead_v, 0.0, lead_a, MIN_REACTION_TIME_S) <= MAX_COLLISION_A_REQ_MPS2
    ]
    assert useful and useful[0] == 0.0  # the scenario leaves time to warn
    warned_s = _first_warning_s(DEFAULT, frames, speed_mps)
    assert warned_s is not None and warned_s <= max(useful), (warned_s, max(useful))
    assert warned_s == _first_warning_s(EARLY, frames, speed_mps)


def _queue_approach(speed_mps: float, peak_a_req_mps2: float, step_s: float):
    """A subject cruising toward a stopped car until a_req after the reaction peaks at ``peak_a_req_mps2``, then
    braking (the driver: T = 0) at the constant deceleration that stops it STOP_BEHIND_M behind the car.
    Per frame (time, clearance, speed, acceleration, a_req of the closed form); and that deceleration."""
    reaction_s = DEFAULT.reaction_time_s
    brake_at_m = _onset_clearance_m(speed_mps, peak_a_req_mps2, reaction_s)
    decel_mps2 = speed_mps**2 / (2.0 * (brake_at_m - STOP_BEHIND_M))
    cruise_frames = math.ceil((START_TTC_S * speed_mps - brake_at_m) / (speed_mps * step_s))
    frames = []
    for index in range(cruise_frames + 1):
        clearance_m = brake_at_m + speed_mps * step_s * (cruise_frames - index)
        a_req = speed_mps**2 / (2.0 * (clearance_m - speed_mps * reaction_s))
        frames.append((index * step_s, clearance_m, speed_mps, 0.0, a_req))
    braking_s, stop_s = step_s, speed_mps / decel_mps2
    while braking_s < stop_s:
        speed_now = speed_mps - decel_mps2 * braking_s
        clearance_m = brake_at_m - speed_mps * braking_s + decel_mps2 * braking_s**2 / 2.0
        t = (cruise_frames + 1) * step_s + braking_s - step_s
        frames.append((t, clearance_m, speed_now, -decel_mps2, speed_now**2 / (2.0 * clearance_m)))
        braking_s += step_s
    return frames, decel_mps2


def _queue_levels(settings_: FcwSettings, frames) -> list[int]:
    """The level of each frame of a queue approach, the a_req of each checked against the closed form."""
    fcw, levels = ForwardCollisionWarning(settings_), []
    for t, clearance_m, speed_mps, accel_mps2, a_req in frames:
        ego = EgoMotion(speed_mps, accel_mps2, braking=accel_mps2 < 0.0)
        frame = fcw.update(t, ego, [SensorObject(1, clearance_m, 0.0, -speed_mps, 0.0)])
        if frame.state is SystemState.ACTIVE:
            assert frame.a_req_mps2 == pytest.approx(a_req, rel=1e-9)
        levels.append(frame.level)
    return levels


@settings(deadline=None, max_examples=60)
@given(st.floats(HIGHEST_MIN_SPEED_MPS, 16.0), st.floats(0.02, 0.98), st.sampled_from([0.02, 0.1]))
def test_a_queue_approach_whose_a_req_peaks_below_the_default_gets_no_warning(speed_mps, peak_share, step_s):
    """The false warnings of the traffic benchmark: a queue's last car approached at 11-16 m/s, the driver braking
    gently (below the threshold) before a_req after 1.2 s reaches the default preliminary threshold. The peak is
    drawn between the earlier 0.3 g and the default; its TTC, T + v / (2 a_peak), under 4 s (4.5.5 e does not
    hold the earlier warning back). The default gives no frame a warning, the earlier 0.3 g gives the
    preliminary warning, and a fleet's settings file still reaches it."""
    assert DEFAULT.preliminary_a_req_mps2 > EARLY_PRELIMINARY_A_REQ_MPS2
    early_mps2, default_mps2 = EARLY_PRELIMINARY_A_REQ_MPS2, DEFAULT.preliminary_a_req_mps2
    peak_mps2 = early_mps2 + peak_share * (default_mps2 - early_mps2)
    assert DEFAULT.reaction_time_s + speed_mps / (2.0 * peak_mps2) < DEFAULT.max_ttc_s
    frames, decel_mps2 = _queue_approach(speed_mps, peak_mps2, step_s)
    assert decel_mps2 < peak_mps2  # braking, a_req = d (x - 2 m) / x stays below the peak
    assert max(frame[4] for frame in frames) == pytest.approx(peak_mps2, rel=1e-9)
    assert min(frame[1] for frame in frames) > STOP_BEHIND_M - 1e-9  # the truth: no conflict
    assert max(_queue_levels(DEFAULT, frames)) == 0
    assert max(_queue_levels(EARLY, frames)) == 1


def test_a_fleet_keeps_the_earlier_preliminary_threshold_through_its_settings_file(tmp_path):
    """The earlier 0.3 g is a fleet's setting: a settings file that names it gives that fleet exactly the
    earlier settings, the other fleets the default; a fleet that lowers its collision threshold below the
    default preliminary one is not refused and keeps a preliminary threshold below its own."""
    from service.fcw_settings import FCW_SETTINGS_FORMAT, FleetFcwSettings

    path = tmp_path / "fcw.json"
    early = {"preliminary_a_req_mps2": EARLY_PRELIMINARY_A_REQ_MPS2}
    lower = {"collision_a_req_mps2": 0.9 * DEFAULT.preliminary_a_req_mps2}  # below the default preliminary
    content = {"format": FCW_SETTINGS_FORMAT, "fleets": {"early": early, "lower": lower}}
    path.write_text(json.dumps(content), encoding="utf-8")
    fleets = FleetFcwSettings(path)
    assert fleets.of("early", Category.N) == EARLY
    assert fleets.of("other", Category.N) == DEFAULT
    own = fleets.of("lower", Category.N)  # still a preliminary warning, at the default's share of its threshold
    share = DEFAULT.preliminary_a_req_mps2 / DEFAULT.collision_a_req_mps2
    assert own.preliminary_a_req_mps2 == pytest.approx(share * own.collision_a_req_mps2)


@settings(deadline=None, max_examples=200)
@given(st.floats(20.0, 60.0), st.floats(HIGHEST_MIN_SPEED_MPS, 16.0), st.floats(0.1, 1.5))
def test_the_traffic_benchmarks_rules_take_an_accelerating_subject_at_its_speed_through_the_reaction(
    clearance_m, subject_mps, accel_mps2
):
    """A subject accelerating toward a stopped car (SUMO's false warnings at 0.45 g, before Annex A.1's reading):
    the rule is due where the least deceleration avoiding contact after 1.2 s (3.22, exact kinematics here) with
    the subject at its speed through the reaction (Annex A.1) reaches the threshold; at a TTC of at most 4 s
    (4.5.5 e)."""
    threshold_mps2, reaction_s = DEFAULT.preliminary_a_req_mps2, DEFAULT.reaction_time_s
    ttc_s = clearance_m / subject_mps
    lead = Lead("tv", clearance_m, subject_mps, subject_accel_mps2=accel_mps2)
    truth = least_deceleration_mps2(clearance_m, subject_mps, 0.0, 0.0, 0.0, reaction_s)
    assume(abs(truth - threshold_mps2) > 1e-6 and abs(ttc_s - DEFAULT.max_ttc_s) > 1e-9)
    due = warning_due(lead, reaction_s, threshold_mps2, DEFAULT.min_speed_mps, False)
    assert due is (truth >= threshold_mps2 and ttc_s <= DEFAULT.max_ttc_s), truth
