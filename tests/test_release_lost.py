"""Release rule 4 (csws.warning.release): a warned curve missing from the path for one fix.

A fix matched onto another road at a junction takes the warned curve off the path ahead. The
warning then stays on, for at most the hold, while the vehicle cannot have reached the curve;
it goes off at once when it may have, and a vehicle that really turned away loses it after the
hold. The road: a 400 m straight ``a`` to a junction J, then ``b`` (the warned road: 80 m
straight, then a left arc of R 60 m) and ``side`` (a straight leaving J to the right). What
6.1 requires at each fix is computed here from Tables 1-2 and formula (1); the distance the
vehicle can have driven between fixes from its speed and the time between them.
"""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from builders import edge_xml, node_xml
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from csws.engine import Answer, Engine, VehicleInput
from csws.geometry import arc, sample_pieces, straight
from csws.road.roadmap import RoadMap
from csws.standard import Category, kmh_to_mps, warning_distance, warning_speed
from csws.sumo.netbuild import netconvert
from csws.warning.rules import WarningSettings
from service.horizon import CpoiPositions

JUNCTION_S_M = 400.0
CURVE_AFTER_JUNCTION_M = 80.0
CURVE_START_S_M = JUNCTION_S_M + CURVE_AFTER_JUNCTION_M
CURVE_RADIUS_M = 60.0
#: How far the map's lane positions may be from the constructed road's arc length: netconvert
#: cuts the edges a few metres short of J to make room for the junction.
JUNCTION_TOLERANCE_M = 10.0
SETTINGS = WarningSettings()


@pytest.fixture(scope="module")
def road_map(tmp_path_factory: pytest.TempPathFactory) -> RoadMap:
    """The straight to J, the warned road ``b`` and the side road, built by netconvert."""
    folder: Path = tmp_path_factory.mktemp("lost")
    junction = np.array([JUNCTION_S_M, 0.0])
    a_xy, _ = sample_pieces((straight(JUNCTION_S_M),), 2.0, (0.0, 0.0), 0.0)
    b_xy, _ = sample_pieces(
        (straight(CURVE_AFTER_JUNCTION_M), arc(CURVE_RADIUS_M, 90.0, "left"), straight(100.0)),
        2.0,
        (JUNCTION_S_M, 0.0),
        0.0,
    )
    side_xy, _ = sample_pieces((straight(300.0),), 2.0, (JUNCTION_S_M, 0.0), math.radians(-40.0))
    nodes = [node_xml("A", (0.0, 0.0)), node_xml("J", junction), node_xml("B", b_xy[-1]), node_xml("S", side_xy[-1])]
    edges = [
        edge_xml("a", "A", "J", a_xy, priority=3),
        edge_xml("b", "J", "B", b_xy, priority=3),
        edge_xml("side", "J", "S", side_xy, priority=1),
    ]
    net = netconvert(
        "<nodes>" + "".join(nodes) + "</nodes>", "<edges>" + "".join(edges) + "</edges>", folder / "lost.net.xml"
    )
    return RoadMap.load(net)


def _fix(route_s_m: float, speed_kmh: float, time_s: float, on_side: bool = False) -> VehicleInput:
    """A fix ``route_s_m`` along a then b, or as far past J on the side road; no route (a telematics feed)."""
    if on_side:
        lane_id, lane_pos_m = "side_0", route_s_m - JUNCTION_S_M
    elif route_s_m < JUNCTION_S_M:
        lane_id, lane_pos_m = "a_0", route_s_m
    else:
        lane_id, lane_pos_m = "b_0", route_s_m - JUNCTION_S_M
    return VehicleInput("v", "N", speed_kmh, lane_id, lane_pos_m, timestamp_s=time_s)


def _required(route_s_m: float, speed_kmh: float) -> bool:
    """Whether 6.1 surely requires level 1 on the warned road at ``route_s_m`` (the map's tolerance inside)."""
    warning_speed_kmh = warning_speed(CURVE_RADIUS_M, Category.N, 1)
    distance_m = max(CURVE_START_S_M - route_s_m, 0.0) + JUNCTION_TOLERANCE_M
    return speed_kmh > warning_speed_kmh and distance_m <= warning_distance(speed_kmh, warning_speed_kmh)


def _drive(road_map: RoadMap, fixes: list[VehicleInput]) -> list[Answer]:
    """The answers to the fixes one at a time; a second engine answers them as a fleet, alike."""
    single, batch = Engine(road_map), Engine(road_map)
    answers = []
    for fix in fixes:
        answer = single.evaluate(fix)
        assert answer.warning == batch.evaluate_many([fix])[0].warning
        answers.append(answer)
    return answers


def _onsets(answers: list[Answer]) -> int:
    levels = [int(answer.level) for answer in answers]
    return sum(1 for before, now in zip([0, *levels], levels, strict=False) if now and not before)


SPEED_KMH = 90.0
PERIOD_S = 1.0
STEP_M = kmh_to_mps(SPEED_KMH) * PERIOD_S


def _positions(last_s_m: float, count: int) -> list[float]:
    """``count`` fixes at SPEED_KMH every PERIOD_S, the last at ``last_s_m``."""
    return [last_s_m - STEP_M * k for k in range(count - 1, -1, -1)]


def test_one_fix_on_a_side_road_before_the_curve_does_not_switch_the_warning_off(road_map: RoadMap) -> None:
    """Warned past J, one fix on the side road, then back: one onset, on at the side fix."""
    side_s_m = CURVE_START_S_M - 30.0
    positions = _positions(side_s_m, 6) + [side_s_m + STEP_M * k for k in (1, 2, 3)]
    side = 5
    # The truth: warned at the fix before it and at the fix after it; the curve not reached at the side fix.
    assert _required(positions[side - 1], SPEED_KMH) and _required(positions[side + 1], SPEED_KMH)
    assert positions[side - 1] > JUNCTION_S_M + JUNCTION_TOLERANCE_M
    assert positions[side] < CURVE_START_S_M - JUNCTION_TOLERANCE_M
    fixes = [_fix(s, SPEED_KMH, PERIOD_S * k, on_side=k == side) for k, s in enumerate(positions)]
    answers = _drive(road_map, fixes)
    assert _onsets(answers) == 1
    held, before = answers[side].warning, answers[side - 1].warning
    assert held.level == before.level >= 1
    assert held.target is not None and before.target is not None and held.target.held
    assert held.target.curve_id == before.target.curve_id
    assert held.target.distance_m == pytest.approx(before.target.distance_m - STEP_M)


def test_a_vehicle_that_turns_away_loses_the_warning_after_the_hold(road_map: RoadMap) -> None:
    """From the side fix on it stays on the side road: off once the hold has passed since last warned on b."""
    side_s_m = CURVE_START_S_M - 30.0
    positions = _positions(side_s_m, 6) + [side_s_m + STEP_M * k for k in (1, 2, 3)]
    side = 5
    assert _required(positions[side - 1], SPEED_KMH)
    fixes = [_fix(s, SPEED_KMH, PERIOD_S * k, on_side=k >= side) for k, s in enumerate(positions)]
    answers = _drive(road_map, fixes)
    hold_s = SETTINGS.hold_s(PERIOD_S)
    last_warned_s = PERIOD_S * (side - 1)
    for k in range(side, len(fixes)):
        if PERIOD_S * k - last_warned_s >= hold_s:
            assert answers[k].level == 0, k
    assert answers[side].level >= 1  # within the hold, the curve still ahead
    assert answers[side + 1].level == 0  # two periods: past the hold of 1.5


def test_the_warning_goes_off_at_once_when_the_vehicle_may_have_reached_the_curve(road_map: RoadMap) -> None:
    """Warned a few metres before the curve, or inside it: a side fix then is answered with no warning."""
    for last_on_b_s in (CURVE_START_S_M - 5.0, CURVE_START_S_M + 10.0):
        positions = _positions(last_on_b_s + STEP_M, 6)
        assert _required(positions[4], SPEED_KMH)
        fixes = [_fix(s, SPEED_KMH, PERIOD_S * k, on_side=k == 5) for k, s in enumerate(positions)]
        answers = _drive(road_map, fixes)
        target = answers[4].warning.target
        assert target is not None
        # The truth: from S at the last fix the vehicle may have driven into the curve since.
        assert target.distance_m <= STEP_M
        assert answers[5].level == 0


@settings(max_examples=25, deadline=None)
@given(
    st.floats(min_value=75.0, max_value=110.0),
    st.floats(min_value=0.3, max_value=2.0),
    st.floats(min_value=JUNCTION_S_M + JUNCTION_TOLERANCE_M, max_value=CURVE_START_S_M + 30.0),
)
def test_a_lost_curve_is_kept_only_while_unreached_and_within_the_hold(
    road_map: RoadMap, speed_kmh: float, period_s: float, side_s_m: float
) -> None:
    """Any speed, period and side fix: on at the side fix (the side road has no curve) exactly when the
    level was on at the fix before, the vehicle cannot have reached the curve since (its S then less the
    distance driven is positive) and the hold has not passed; single and batch alike."""
    times_s = [period_s * k for k in range(7)]
    step_m = kmh_to_mps(speed_kmh) * (times_s[6] - times_s[5])
    positions = [side_s_m - kmh_to_mps(speed_kmh) * (times_s[6] - time_s) for time_s in times_s]
    fixes = [
        _fix(s, speed_kmh, time_s, on_side=k == 6) for k, (s, time_s) in enumerate(zip(positions, times_s, strict=True))
    ]
    answers = _drive(road_map, fixes)
    before = answers[5].warning
    assume(before.target is None or not before.target.held)  # kept on by 6.1 at the fix before, or off
    unreached = before.target is not None and before.target.distance_m - step_m > 0.0
    within_hold = times_s[6] - times_s[5] < SETTINGS.hold_s(period_s)
    assert (answers[6].level > 0) == (unreached and within_hold)


def test_the_service_places_a_recalled_curve_where_it_lies_on_the_road(road_map: RoadMap) -> None:
    """The answer's position of a CPOI recalled at a side fix is its part's first point, as on the path."""
    network = SimpleNamespace(road_map=road_map)
    fixes = [
        _fix(s, SPEED_KMH, PERIOD_S * k, on_side=k == 5) for k, s in enumerate(_positions(CURVE_START_S_M - 30, 6))
    ]
    answers = _drive(road_map, fixes)
    on_path, recalled = answers[4], answers[5]
    assert on_path.path is not None and recalled.path is not None
    assert on_path.warning.target is not None and recalled.warning.target is not None
    key = ([on_path.warning.target.curve_id], [on_path.warning.target.part_index])
    assert key == ([recalled.warning.target.curve_id], [recalled.warning.target.part_index])
    placed = CpoiPositions(network).of(on_path.path, *key)[0]  # type: ignore[arg-type]
    placed_recalled = CpoiPositions(network).of(recalled.path, *key)[0]  # type: ignore[arg-type]
    assert placed_recalled == pytest.approx(placed, abs=1e-6)
    # The truth: the arc starts CURVE_AFTER_JUNCTION_M past J on the x axis.
    assert math.hypot(placed["x"] - CURVE_START_S_M, placed["y"]) < JUNCTION_TOLERANCE_M
