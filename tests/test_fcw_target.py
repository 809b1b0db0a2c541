"""FCW target selection and state against constructed geometry and GB/T 33577's numbers, and
the target SUMO's leaders give on the FCW tracks (libsumo)."""

from __future__ import annotations

import math
import os
import tempfile
from dataclasses import replace
from pathlib import Path

import pytest

from csws.fcw.physics import (
    ACTIVE,
    FAULT,
    OFF,
    STANDBY,
    FcwSettings,
    next_fcw_states,
    required_deceleration_mps2,
    warning_clearance_m,
)
from csws.fcw.target import CurveClass, TargetSettings, curve_start_speed_mps, select_targets
from csws.networks import networks_dir
from csws.networks.fcw_tracks import FCW_DIR, LANE_WIDTH_M, compare_fcw_tracks
from csws.sumo.binaries import sumo_binary, sumo_home


def _on_arc(radius_m: float, arc_m: float, offset_m: float) -> tuple[float, float]:
    """A point ``arc_m`` along a left arc of ``radius_m`` from (0, 0) heading east, ``offset_m`` to its left."""
    angle = arc_m / radius_m
    r = radius_m - offset_m
    return r * math.sin(angle), radius_m - r * math.cos(angle)


def test_on_a_curve_the_adjacent_lane_vehicle_is_no_target_though_straight_ahead_it_would_be():
    """R 125 m: a vehicle 29 m ahead in the outer lane lies within half a lane of the subject's
    straight-ahead line, one 60 m ahead in the subject's own lane does not; in path coordinates
    (along the lane, off its centre) the selection takes the one in the lane."""
    radius_m = 125.0
    adjacent_xy, own_xy = _on_arc(radius_m, 29.0, -LANE_WIDTH_M), _on_arc(radius_m, 60.0, 0.0)
    assert abs(adjacent_xy[1]) < LANE_WIDTH_M / 2.0 < abs(own_xy[1])  # a straight beam would pick the wrong one
    targets = select_targets([0, 0], [29.0, 60.0], [-LANE_WIDTH_M, 0.0], [radius_m, radius_m], 1)
    assert targets.tolist() == [1]


@pytest.mark.parametrize(
    ("distance_m", "offset_m", "radius_m", "seen"),
    [
        (50.0, 0.0, math.inf, True),
        (50.0, 1.7, math.inf, True),  # within half a lane
        (50.0, 1.8, math.inf, False),  # beyond it
        (250.0, 0.0, math.inf, False),  # beyond the range
        (-1.0, 0.0, math.inf, False),  # behind
        (50.0, 0.0, 100.0, False),  # tighter than class III's 125 m
        (50.0, 0.0, 125.0, True),
    ],
)
def test_a_candidate_is_seen_in_the_lane_within_range_on_curves_of_the_class(distance_m, offset_m, radius_m, seen):
    assert bool(select_targets([0], [distance_m], [offset_m], [radius_m], 1)[0] == 0) is seen


def test_of_several_in_the_path_the_nearest_is_the_target_for_each_subject():
    owner = [1, 0, 1, 0, 1]
    distance = [80.0, 30.0, 20.0, 10.0, 25.0]
    offset = [0.0, 0.0, 0.5, 3.5, 0.0]
    targets = select_targets(owner, distance, offset, [math.inf] * 5, 3)
    assert targets.tolist() == [1, 2, -1]


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


def test_the_bundled_fcw_tracks_are_what_the_generator_builds():
    assert compare_fcw_tracks(networks_dir() / FCW_DIR) == []


def _sumo_targets(track: str, vehicles: str):
    """The subject's target on a FCW track one step after the vehicles depart."""
    os.environ.setdefault("SUMO_HOME", str(sumo_home()))
    import libsumo

    from csws.cosim.fcw import forward_targets

    types = '<vType id="t" length="12" minGap="2.5" sigma="0"/><vType id="c" length="4.5" minGap="3" sigma="0"/>'
    with tempfile.TemporaryDirectory() as work:
        routes = Path(work) / "r.rou.xml"
        routes.write_text(f"<routes>{types}{vehicles}</routes>", encoding="utf-8")
        libsumo.start(
            [
                str(sumo_binary("sumo")),
                "-n",
                str(networks_dir() / FCW_DIR / f"{track}.net.xml"),
                "-r",
                str(routes),
                "--no-step-log",
                "true",
                "--no-warnings",
                "true",
            ]
        )
        try:
            libsumo.simulationStep()
            return forward_targets(libsumo, ["sv"], TargetSettings())
        finally:
            libsumo.close()


def _vehicle(vehicle_id: str, vtype: str, lane: int, pos_m: float) -> str:
    return (
        f'<vehicle id="{vehicle_id}" type="{vtype}" depart="0" departLane="{lane}" departPos="{pos_m}" '
        f'departSpeed="0" insertionChecks="none"><route edges="road"/></vehicle>'
    )


def test_sumo_leaders_give_the_clearance_with_min_gap_and_beyond_the_default_search():
    """sv's front at 100 m, tv's rear 150 m ahead (front at 254.5 m): SUMO's gap leaves out sv's
    minGap (2.5 m); the clearance is the lane positions' difference. The nearer vehicle in the
    other lane is not the target."""
    found = _sumo_targets(
        "fcw_straight", _vehicle("sv", "t", 0, 100.0) + _vehicle("tv", "c", 0, 254.5) + _vehicle("adj", "c", 1, 130.0)
    )
    assert found.target_id == ["tv"] and found.clearance_m[0] == pytest.approx(150.0)


def test_on_the_r125_curve_the_target_is_in_the_lane_and_the_outer_lane_vehicle_is_not():
    curve_start_m = 60.0
    found = _sumo_targets(
        "fcw_curve_r125",
        _vehicle("sv", "t", 1, curve_start_m + 20.0)
        + _vehicle("adj", "c", 0, curve_start_m + 35.0)
        + _vehicle("tv", "c", 1, curve_start_m + 80.0),
    )
    assert found.target_id == ["tv"]
    assert found.clearance_m[0] == pytest.approx(80.0 - 20.0 - 4.5)  # along SUMO's lane positions
