"""The forward collision warning from a sensor's object list, against constructed truth: scenarios
driven here as closed-form kinematics, the latest useful warning time computed here (a driver
reacting 0.8 s after the warning and braking at 0.68 g avoids the collision), and vehicles placed
on the circles of an R 125 m curve."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_fcw_traffic import least_deceleration_mps2

from csws.fcw.objects import EgoMotion, SensorObject
from csws.fcw.path import PathCurvature, straight_beam_range_m
from csws.fcw.physics import warning_level
from csws.fcw.settings import LOWEST_MAX_SPEED_MPS, STANDARD_GRAVITY_MPS2, FcwSettings
from csws.fcw.tracker import ForwardCollisionWarning
from csws.state import SystemState

G = STANDARD_GRAVITY_MPS2
#: The driver of the judgement: reacts 0.8 s after the warning, then brakes at 0.68 g.
DRIVER_REACTION_S, DRIVER_DECEL_MPS2 = 0.8, 0.68 * G
FRAME_S = 0.05


def _first_warning_s(frames: list[tuple[float, int]], level: int = 2) -> float:
    return next(t for t, shown in frames if shown >= level)


# --- a stopped car at 110 km/h -------------------------------------------------------------


def _approach_stopped(settings: FcwSettings, speed_mps: float, start_m: float) -> list[tuple[float, int]]:
    fcw, frames, t = ForwardCollisionWarning(settings), [], 0.0
    while speed_mps * t < start_m - 1.0:
        gap_m = start_m - speed_mps * t
        frame = fcw.update(t, EgoMotion(speed_mps, yaw_rate_rps=0.0), [SensorObject(7, gap_m, 0.0, -speed_mps)])
        frames.append((t, frame.level, frame.state))
        t = round(t + FRAME_S, 9)
    return frames


def test_an_m1_at_110_kmh_is_warned_of_a_stopped_car_in_time():
    speed_mps, start_m = 110.0 / 3.6, 250.0
    frames = _approach_stopped(FcwSettings.for_category("M1"), speed_mps, start_m)
    stopping_m = speed_mps * DRIVER_REACTION_S + speed_mps**2 / (2.0 * DRIVER_DECEL_MPS2)
    latest_s = (start_m - stopping_m) / speed_mps
    assert _first_warning_s([(t, level) for t, level, _ in frames]) <= latest_s
    # A V_max of 27.8 m/s (the commercial default) leaves the car at 30.6 m/s in standby.
    commercial = _approach_stopped(FcwSettings(), speed_mps, start_m)
    assert {state for _, _, state in commercial} == {SystemState.STANDBY}


# --- a lead braking at 0.5 g from the ego's speed ------------------------------------------------


def _gap_m(t: np.ndarray, gap0_m: float, speed_mps: float, lead_decel: float, brake_at_s: float) -> np.ndarray:
    """The gap at times t: the lead brakes to a stop from t = 0, the ego brakes from ``brake_at_s``."""
    lead_t = np.minimum(t, speed_mps / lead_decel)
    lead_m = speed_mps * lead_t - lead_decel * lead_t**2 / 2.0
    ego_t = np.clip(t - brake_at_s, 0.0, speed_mps / DRIVER_DECEL_MPS2)
    ego_m = speed_mps * np.minimum(t, brake_at_s) + speed_mps * ego_t - DRIVER_DECEL_MPS2 * ego_t**2 / 2.0
    return gap0_m + lead_m - ego_m


def _latest_useful_s(gap0_m: float, speed_mps: float, lead_decel: float) -> float:
    """The latest warning after which the driver (0.8 s, 0.68 g) still avoids the braking lead: bisection."""
    t = np.linspace(0.0, 30.0, 300_001)
    low, high = -DRIVER_REACTION_S, 10.0
    for _ in range(60):
        mid = (low + high) / 2.0
        if np.min(_gap_m(t, gap0_m, speed_mps, lead_decel, mid + DRIVER_REACTION_S)) > 0.0:
            low = mid
        else:
            high = mid
    return low


@pytest.mark.parametrize(("speed_mps", "gap0_m"), [(25.0, 20.0), (30.0, 35.0), (20.0, 12.0)])
def test_a_lead_braking_at_half_g_from_the_ego_speed_is_warned_in_time_though_ttc_is_over_4_s(speed_mps, gap0_m):
    lead_decel = 0.5 * G
    latest_s = _latest_useful_s(gap0_m, speed_mps, lead_decel)
    assert latest_s > 0.0  # the scenario can be saved
    fcw = ForwardCollisionWarning(FcwSettings.for_category("M1"))
    ego = EgoMotion(speed_mps, yaw_rate_rps=0.0)
    fcw.update(-FRAME_S, ego, [SensorObject(3, gap0_m, 0.0, 0.0)])  # following before the lead brakes
    t = 0.0
    while True:
        lead_speed = max(speed_mps - lead_decel * t, 0.0)
        gap = float(_gap_m(np.array([t]), gap0_m, speed_mps, lead_decel, math.inf)[0])
        accel = -lead_decel if lead_speed > 0.0 else 0.0
        frame = fcw.update(t, ego, [SensorObject(3, gap, 0.0, lead_speed - speed_mps, accel)])
        if frame.level == 2:
            break
        t = round(t + FRAME_S, 9)
    assert t <= latest_s
    assert frame.ttc_s > 4.0  # the old rule (TTC above 4 s alone suppresses) held it


# --- a cut-out reveals a stopped car -------------------------------------------------------------


@pytest.mark.parametrize("seen_behind_the_lead", [False, True])
def test_a_cut_out_revealing_a_stopped_car_warns_in_the_frame_of_the_reveal(seen_behind_the_lead):
    """Ego and lead at 25 m/s 25 m apart; the lead moves to the left lane at 1.75 m/s; a stopped car
    stands 70 m ahead. The warning comes in the frame the lead leaves the path (its centre more than
    1.75 m off), and what it requires then is a collision warning."""
    speed_mps, stopped_m, fcw = 25.0, 70.0, ForwardCollisionWarning(FcwSettings())
    reveal = None
    for k in range(60):
        t = k * FRAME_S
        lead_y = min(1.75 * t, 3.5)
        revealed = lead_y > 1.75
        objects = [SensorObject(1, 25.0, lead_y, 0.0)]
        if revealed or seen_behind_the_lead:
            objects.append(SensorObject(2, stopped_m - speed_mps * t, 0.0, -speed_mps))
        frame = fcw.update(t, EgoMotion(speed_mps, yaw_rate_rps=0.0), objects)
        if revealed and reveal is None:
            reveal = frame
            break
    assert reveal is not None and reveal.target_id == 2 and reveal.level == 2


# --- adjacent lanes on an R 125 m curve ---------------------------------------------------------

RADIUS_M, LANE_M, CAR_HALF_LENGTH_M = 125.0, 3.5, 2.25


def _on_curve(arc_m: float, offset_m: float, half_length_m: float = CAR_HALF_LENGTH_M) -> tuple[float, float]:
    """What a sensor reports of a vehicle whose rear is ``arc_m`` along the ego's lane of a left R 125 m
    curve and ``offset_m`` left of it: x of its rear, y of its centre (half a length further on)."""
    radius = RADIUS_M - offset_m
    rear, centre = arc_m / RADIUS_M, (arc_m + half_length_m) / RADIUS_M
    return radius * math.sin(rear), RADIUS_M - radius * math.cos(centre)


CURVE_EGO = {
    "yaw rate": EgoMotion(17.0, yaw_rate_rps=17.0 / RADIUS_M),
    "map": EgoMotion(17.0, map_path=PathCurvature((0.0, 300.0), (1.0 / RADIUS_M, 1.0 / RADIUS_M))),
}


@pytest.mark.parametrize("ego_name", CURVE_EGO)
def test_on_r_125_adjacent_lane_cars_are_never_warned_an_in_lane_car_is(ego_name):
    ego = CURVE_EGO[ego_name]
    adjacent = [
        SensorObject(10 * i + side, *_on_curve(float(arc), offset), -17.0)
        for i, arc in enumerate(range(10, 101, 10))
        for side, offset in ((1, LANE_M), (2, -LANE_M))
    ]
    x, y = _on_curve(29.0, -LANE_M)
    assert abs(y) < 1.75  # straight ahead of the ego, where a straight beam would take it
    fcw = ForwardCollisionWarning(FcwSettings())
    for k in range(5):
        frame = fcw.update(k * FRAME_S, ego, adjacent)
        assert frame.level == 0 and frame.target_id is None
    in_lane = SensorObject(500, *_on_curve(40.0, 0.5), -17.0)
    frame = fcw.update(1.0, ego, [*adjacent, in_lane])
    assert frame.target_id == 500 and frame.level == 2
    assert frame.path_offset_m == pytest.approx(0.5, abs=0.1)


@settings(deadline=None, max_examples=60)
@given(st.sampled_from(list(CURVE_EGO)), st.floats(5.0, 100.0), st.floats(-0.5, 0.5), st.sampled_from([-1, 1]))
def test_on_r_125_every_in_lane_car_is_in_the_path_and_no_adjacent_one(ego_name, arc_m, in_lane_m, side):
    fcw = ForwardCollisionWarning(FcwSettings())
    adjacent = SensorObject(1, *_on_curve(arc_m, side * LANE_M), -17.0)
    assert fcw.update(0.0, CURVE_EGO[ego_name], [adjacent]).target_id is None
    own = SensorObject(2, *_on_curve(arc_m, in_lane_m), -5.0)
    assert fcw.update(0.1, CURVE_EGO[ego_name], [adjacent, own]).target_id == 2


def test_annex_b_a_straight_beam_keeps_to_the_lane_only_to_formula_b1():
    """Table B.1 (W_L 3.75 m): D = 19.27 m at R 100 m ... 51.20 m at R 700 m."""
    table_b1 = {100: 19.27, 200: 27.32, 300: 33.49, 400: 38.68, 500: 43.26, 600: 47.40, 700: 51.20}
    for radius_m, distance_m in table_b1.items():
        assert straight_beam_range_m(radius_m, 3.75) == pytest.approx(distance_m, abs=0.006)
    # The lane's centre line leaves a straight beam's half lane at D (its offset there is W_L / 2).
    d = straight_beam_range_m(RADIUS_M, LANE_M)
    assert RADIUS_M - math.sqrt(RADIUS_M**2 - d**2) == pytest.approx(LANE_M / 2.0, rel=0.01)


@pytest.mark.parametrize("arc_m", [5.0, 20.0, 40.0, 60.0, 80.0, 100.0])
def test_on_r_125_a_truck_in_the_middle_of_the_lane_is_in_the_path(arc_m):
    """A truck (half length 6 m) centred in the lane: its centre, half a truck beyond the rear the
    sensor ranges, is off the car half length the in-path test assumes, but within the corridor."""
    truck = SensorObject(9, *_on_curve(arc_m, 0.0, half_length_m=6.0), -5.0, width_m=2.5)
    frame = ForwardCollisionWarning(FcwSettings()).update(0.0, CURVE_EGO["yaw rate"], [truck])
    assert frame.target_id == 9 and abs(frame.path_offset_m) < FcwSettings().path_half_width_m


def test_the_sensor_lane_assignment_decides_where_given():
    fcw, ego = ForwardCollisionWarning(FcwSettings()), EgoMotion(20.0)
    assert fcw.update(0.0, ego, [SensorObject(1, 30.0, 0.0, -10.0, lane=1)]).target_id is None
    assert fcw.update(0.1, ego, [SensorObject(1, 30.0, 3.0, -10.0, lane=0)]).target_id == 1


def _path_points(profile: PathCurvature, arcs_m: np.ndarray, offset_m: float) -> np.ndarray:
    """Points ``offset_m`` left of the map path at the arc lengths: the heading and position integrated
    here from the curvature profile in 1 cm steps (the midpoint rule)."""
    s = np.arange(0.0, arcs_m.max() + 0.01, 0.01)
    kappa = np.interp(s, profile.s_m, profile.curvature_1pm)
    heading = np.concatenate(([0.0], np.cumsum((kappa[1:] + kappa[:-1]) / 2.0 * 0.01)))
    mid = (heading[1:] + heading[:-1]) / 2.0
    x = np.concatenate(([0.0], np.cumsum(np.cos(mid) * 0.01)))
    y = np.concatenate(([0.0], np.cumsum(np.sin(mid) * 0.01)))
    at = np.interp(arcs_m, s, np.arange(s.size)).round().astype(int)
    return np.column_stack((x[at] - offset_m * np.sin(heading[at]), y[at] + offset_m * np.cos(heading[at])))


@pytest.mark.parametrize("offset_m", [0.0, 0.5, -0.5, LANE_M, -LANE_M])
def test_a_map_path_into_and_out_of_r_125_keeps_the_own_lane_and_not_the_adjacent_ones(offset_m):
    """A straight 30 m, a 30 m clothoid into R 125 m, 40 m of arc, a 30 m clothoid out: the objects'
    centres on the lane at ``offset_m`` (found by integrating the path here) are in the path
    exactly when they are in the own lane."""
    k = 1.0 / RADIUS_M
    profile = PathCurvature((0.0, 30.0, 60.0, 100.0, 130.0, 200.0), (0.0, 0.0, k, k, 0.0, 0.0))
    arcs = np.arange(10.0, 150.0, 5.0)
    centres = _path_points(profile, arcs + CAR_HALF_LENGTH_M, offset_m)
    rears = _path_points(profile, arcs, offset_m)
    ego = EgoMotion(17.0, yaw_rate_rps=0.0, map_path=profile)
    for i, (rear, centre) in enumerate(zip(rears, centres, strict=True)):
        frame = ForwardCollisionWarning(FcwSettings()).update(0.0, ego, [SensorObject(i, rear[0], centre[1], -5.0)])
        assert (frame.target_id == i) is (abs(offset_m) < 1.0), (arcs[i], frame.path_offset_m)


# --- state (Figure 2) and V_max -------------------------------------------------------------------


def test_v_max_per_category_never_below_the_standards_and_overridable():
    assert FcwSettings.for_category("M1").max_speed_mps == pytest.approx(250.0 / 3.6)
    for category in ("M2", "M3", "N", "O"):
        assert FcwSettings.for_category(category).max_speed_mps >= LOWEST_MAX_SPEED_MPS
    assert FcwSettings.for_category("N", max_speed_mps=40.0).max_speed_mps == 40.0
    with pytest.raises(ValueError, match="4.3.3"):
        FcwSettings.for_category("M1", max_speed_mps=25.0)


def test_the_state_follows_figure_2_with_its_delta():
    """V_min 10, V_max 27.8, delta 1 m/s: standby below V_min, active from it, kept active down to
    V_min - delta and up to V_max + delta, standby beyond; off when switched off; standby in reverse."""
    fcw = ForwardCollisionWarning(FcwSettings())
    steps = [
        (9.5, {}, SystemState.STANDBY),
        (10.0, {}, SystemState.ACTIVE),
        (9.2, {}, SystemState.ACTIVE),  # within delta
        (8.9, {}, SystemState.STANDBY),
        (9.5, {}, SystemState.STANDBY),  # not back until V_min
        (20.0, {}, SystemState.ACTIVE),
        (28.6, {}, SystemState.ACTIVE),  # V_max + delta
        (28.9, {}, SystemState.STANDBY),
        (28.0, {}, SystemState.STANDBY),  # back only at V_max
        (27.0, {}, SystemState.ACTIVE),
        (27.0, {"forward_gear": False}, SystemState.STANDBY),
        (27.0, {"sensor_ok": False}, SystemState.FAULT),
        (27.0, {}, SystemState.ACTIVE),
        (27.0, {"switched_on": False}, SystemState.OFF),
    ]
    for k, (speed, flags, state) in enumerate(steps):
        frame = fcw.update(float(k), EgoMotion(speed, **flags), [SensorObject(1, 5.0, 0.0, -10.0)])
        assert frame.state == state, (k, speed, flags)
        assert frame.level == 0 or state == SystemState.ACTIVE


# --- the suppression rule and the level hold -----------------------------------------------------


def _required_by_thresholds(
    settings: FcwSettings, x_m: float, v_r: float, a_tv: float, a_sv: float, braking: bool, v_sv: float
) -> int:
    """The level the thresholds require, a_req computed here: for a lead moving forward, 3.22's least
    avoiding deceleration by exact kinematics (:func:`test_fcw_traffic.least_deceleration_mps2`);
    for an object coming toward the subject, formula (4) at the end of the reaction T with both
    accelerations held through it: a_req = d_TV + v_r'^2 / (2 x_c'), x_c' and v_r' the clearance and the
    closing speed then (T cut where the vehicles stop closing first). Through the reaction the subject keeps
    a deceleration, an acceleration not (Annex A.1: at its speed). The preliminary level only at a
    TTC of at most ``max_ttc_s`` (4.5.5 e); a_req just at a threshold (within 1e-6) is left out."""
    lost = 0.0 if braking else settings.reaction_time_s + settings.brake_response_s
    a_sv = min(a_sv, 0.0)
    if v_sv + v_r >= 0.0:
        a_req = least_deceleration_mps2(x_m, v_sv, v_sv + v_r, a_sv, a_tv, lost) - 1e-6
    else:
        a_rel = a_tv - a_sv
        reaction = -v_r / a_rel if v_r < 0.0 < a_rel and -v_r < a_rel * lost else lost
        left = x_m + v_r * reaction + a_rel * reaction**2 / 2.0
        closing = min(v_r + a_rel * reaction, 0.0)
        a_req = math.inf if left <= 0.0 else -a_tv + closing**2 / (2.0 * left)
    ttc_s = x_m / -v_r if v_r < 0.0 else math.inf
    if a_req >= settings.collision_a_req_mps2:
        return 2
    return 1 if a_req >= settings.preliminary_a_req_mps2 and ttc_s <= settings.max_ttc_s else 0


OBJECT = st.tuples(st.floats(0.5, 150.0), st.floats(-40.0, 10.0), st.floats(-8.0, 3.0))


@settings(deadline=None, max_examples=200)
@given(
    st.lists(st.tuples(st.lists(OBJECT, max_size=4), st.floats(-4.0, 2.0), st.booleans()), min_size=1, max_size=8),
    st.floats(0.02, 0.5),
)
def test_no_frame_shows_a_lower_level_than_its_thresholds_require(frames, step_s):
    """Over random frames (any TTC, ETTC, a_req; the ego decelerating below the collision
    threshold), the level shown is at least what the most demanding object requires, by a_req
    computed here; TTC above 4 s never lowers the collision warning (4.5.5 e only where no measure shows
    a threat)."""
    settings_ = FcwSettings()
    fcw = ForwardCollisionWarning(settings_)
    for k, (objects, a_sv, braking) in enumerate(frames):
        sensed = [SensorObject(i, x, 0.0, v_r, a) for i, (x, v_r, a) in enumerate(objects)]
        frame = fcw.update(k * step_s, EgoMotion(20.0, a_sv, braking=braking), sensed)
        # Objects faster than the ego that entered the path are cut-ins (4.5.5 c), never warned.
        needed = max(
            (_required_by_thresholds(settings_, x, v, a, a_sv, braking, 20.0) for x, v, a in objects if v <= 0.0),
            default=0,
        )
        assert frame.level >= needed >= 0
        assert frame.level >= frame.required_level


def test_the_level_is_held_over_one_noisy_frame_and_released_after_the_hold():
    settings_ = FcwSettings()
    fcw, ego = ForwardCollisionWarning(settings_), EgoMotion(20.0)
    near, gone = [SensorObject(1, 30.0, 0.0, -15.0)], []
    assert fcw.update(0.0, ego, near).level == 2
    held = fcw.update(0.1, ego, gone)  # one frame without the object
    assert held.level == 2 and held.required_level == 0
    assert fcw.update(0.2, ego, near).level == 2
    assert fcw.update(0.3, ego, gone).level == 2
    assert fcw.update(0.3 + settings_.level_hold_s, ego, gone).level == 0
    # Braking at the collision threshold (4.5.5 a) drops the hold at once.
    assert fcw.update(1.0, ego, near).level == 2
    assert fcw.update(1.1, EgoMotion(20.0, -settings_.collision_a_req_mps2), gone).level == 0


def test_a_faster_cut_in_is_not_warned_of_until_it_is_slower():
    """4.5.5 c: a car cutting in faster than the ego and braking hard: no warning while faster."""
    fcw, ego = ForwardCollisionWarning(FcwSettings()), EgoMotion(20.0)
    assert fcw.update(0.0, ego, [SensorObject(4, 15.0, 3.5, 2.0, -6.0)]).target_id is None  # beside
    frame = fcw.update(0.1, ego, [SensorObject(4, 15.0, 0.5, 2.0, -6.0)])
    assert frame.target_id is None and frame.level == 0
    frame = fcw.update(0.2, ego, [SensorObject(4, 15.0, 0.0, -1.0, -6.0)])
    assert frame.target_id == 4 and frame.level == 2


def test_the_new_4_5_5_e_suppresses_only_where_no_measure_shows_a_threat():
    settings_ = FcwSettings()
    threshold = settings_.collision_a_req_mps2
    assert warning_level(0.0, math.inf, 3.6, threshold, settings_) == 2  # TTC inf, ETTC 3.6 s
    assert warning_level(0.0, math.inf, 3.6, threshold, settings_, suppress_above_max_ttc=True) == 0
    assert warning_level(0.0, 5.0, 5.0, settings_.preliminary_a_req_mps2 * 0.99, settings_) == 0
    assert warning_level(-threshold, 1.0, 1.0, 20.0, settings_) == 0  # 4.5.5 a


# --- bad input ----------------------------------------------------------------------------------


def test_bad_input_raises_naming_it():
    with pytest.raises(ValueError, match="x_m"):
        SensorObject(1, math.nan, 0.0, -1.0)
    with pytest.raises(ValueError, match="relative_speed_mps"):
        SensorObject(1, 10.0, 0.0, math.inf)
    with pytest.raises(ValueError, match="speed_mps"):
        EgoMotion(math.nan)
    with pytest.raises(ValueError, match="yaw_rate_rps"):
        EgoMotion(10.0, yaw_rate_rps=math.nan)
    with pytest.raises(ValueError, match="duplicate object ids \\[3\\]"):
        ForwardCollisionWarning().update(0.0, EgoMotion(20.0), [SensorObject(3, 10.0, 0.0, 0.0)] * 2)
    with pytest.raises(ValueError, match="s_m"):
        PathCurvature((0.0, 10.0, 5.0), (0.0, 0.0, 0.0))
    fcw = ForwardCollisionWarning()
    fcw.update(1.0, EgoMotion(20.0), [])
    with pytest.raises(ValueError, match="time_s"):
        fcw.update(1.0, EgoMotion(20.0), [])


def test_the_map_path_is_taken_from_the_horizon_profile_from_the_vehicle_front():
    """A profile's vertices (s, curvature) from the front at s = 25 m over 100 m: the curvature
    at the front interpolated, the vertices within the range kept, shifted to start at 0."""
    from types import SimpleNamespace

    from csws.fcw.path import path_curvature_ahead

    profile = SimpleNamespace(s=np.array([0.0, 50.0, 100.0, 150.0]), curvature=np.array([0.0, 0.01, 0.01, 0.0]))
    path = path_curvature_ahead(SimpleNamespace(profile=profile), 25.0, 100.0)
    assert path.s_m == (0.0, 25.0, 75.0) and path.curvature_1pm == pytest.approx((0.005, 0.01, 0.01))
