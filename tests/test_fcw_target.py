"""FCW curve classes, formula (6), the state and the set warning distance against GB/T 33577's numbers,
and the bundled FCW tracks."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from csws.fcw.physics import required_deceleration_mps2, warning_clearance_m
from csws.fcw.settings import FcwSettings
from csws.fcw.state import ACTIVE, FAULT, OFF, STANDBY, next_fcw_states
from csws.fcw.target import CurveClass, curve_start_speed_mps
from csws.networks import networks_dir
from csws.networks.fcw_tracks import FCW_DIR, compare_fcw_tracks


def test_curve_classes_and_formula_6():
    assert [c.min_radius_m for c in CurveClass] == [500.0, 250.0, 125.0]
    assert curve_start_speed_mps(CurveClass.I, 500.0, 27.8) == 27.8  # sqrt(2 * 500) = 31.6 > V_max
    assert curve_start_speed_mps(CurveClass.II, 250.0, 27.8) == pytest.approx(math.sqrt(2.3 * 250.0))
    assert curve_start_speed_mps(CurveClass.III, 125.0, 27.8) == pytest.approx(16.956, abs=1e-3)


def test_the_state_follows_figure_2_with_the_hysteresis():
    settings = FcwSettings()
    previous = [STANDBY, STANDBY, ACTIVE, ACTIVE, ACTIVE, ACTIVE, STANDBY]
    speed = [9.0, 12.0, 9.5, 8.5, 20.0, 20.0, 20.0]
    switched = [True] * 5 + [False, True]
    measured = [True] * 6 + [False]
    assert next_fcw_states(previous, speed, switched, measured, settings).tolist() == [
        STANDBY,
        ACTIVE,
        ACTIVE,
        STANDBY,
        ACTIVE,
        OFF,
        FAULT,
    ]
    with pytest.raises(ValueError, match="4.3.3"):
        FcwSettings(min_speed_mps=12.0)


def test_the_set_warning_distance_is_where_a_req_reaches_the_threshold():
    """x_c = c T - a_TV T^2 / 2 + (c - a_TV T)^2 / (2 (a_thr + a_TV)), by hand (the clearance lost in the
    reaction and the closing speed at its end), and formula (4) gives a_thr there."""
    settings = replace(FcwSettings(), reaction_time_s=0.8, collision_a_req_mps2=6.6)
    for closing_mps, lead_accel_mps2 in ((20.0, 0.0), (12.0, -2.0)):
        closing_after = closing_mps - lead_accel_mps2 * 0.8
        by_hand_m = 0.8 * closing_mps - lead_accel_mps2 * 0.32 + closing_after**2 / (2.0 * (6.6 + lead_accel_mps2))
        clearance_m = warning_clearance_m(closing_mps, lead_accel_mps2, settings)
        assert clearance_m == pytest.approx(by_hand_m)
        assert required_deceleration_mps2(clearance_m, -closing_mps, lead_accel_mps2, 0.8) == pytest.approx(6.6)


@pytest.mark.sumo
def test_the_bundled_fcw_tracks_are_what_the_generator_builds():
    assert compare_fcw_tracks(networks_dir() / FCW_DIR) == []
