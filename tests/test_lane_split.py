"""The path ahead at a lane split: a one-lane motorway whose lane splits in two 60 m before an exit, the right lane
going straight on onto the exit ramp alone (its curve of R 40 m starts 40 m past the diverge), the left one, a lane
width aside, going on as the road (tests/exit_ramp.py, ``write_lane_split``). Without a route the path ahead of the
one lane follows the road, never the straighter lane that leads onto the ramp: a vehicle going on along the road is
never warned of the ramp's curve, at any speed; a vehicle in the exit lane, which leads only onto the ramp, is warned
of it where formula (1) requires, or, where that point lies before the split, from its first position past the split.
Truth: the constructed geometry, the drives at constant speed, formula (1) and Table 1's V_w computed here."""

from __future__ import annotations

import numpy as np
import pytest
from exit_ramp import RAMP_STRAIGHT_M, path_starts_s, ramp_curve_start_s, write_lane_split
from hypothesis import given, settings
from hypothesis import strategies as st
from markers import marks_its_tests

from csws.ahead.lookahead import LookAhead
from csws.ahead.roadlane import RoadLanes
from csws.engine import Engine, VehicleInput
from csws.road.roadmap import RoadMap

#: The lane split lies this far before the diverge, m.
SPLIT_M = 60.0
#: Table 1, level 1, column M3/N/O at R = 40 m (T/ITS 0091-2018 6.1): V_w = 39 km/h.
LEVEL_1_SPEED_AT_40_M_KMH = 39.0
#: Formula (1) (6.1): S_w = 0.8 v + (v^2 - v_w^2) / g, with g = 9.8 m/s^2.
REACTION_S, G_MPS2 = 0.8, 9.8
#: The vehicles report every 0.1 s; the system's own delay (WarningSettings' default) is 0.1 s: the warning comes
#: on where S_w plus the travel over both is reached (6.1 with the latency allowed for).
STEP_S, SYSTEM_DELAY_S = 0.1, 0.1
#: How far the curve fitted on the ramp's lane may start from the authored one, and lane positions from the
#: authored arc length (netconvert's trimming at the nodes), m.
TOLERANCE_M = 1.5
#: Drives start this far along the one-lane road, well before any warning, so that the system is active by then, m.
START_M = 100.0


@pytest.fixture(scope="module")
@marks_its_tests("sumo")
def split_map(tmp_path_factory) -> RoadMap:
    return RoadMap.load(write_lane_split(tmp_path_factory.mktemp("lane_split"), SPLIT_M))


def _formula_1_m(speed_kmh: float, warning_speed_kmh: float) -> float:
    """S_w of formula (1), m."""
    v, v_w = speed_kmh / 3.6, warning_speed_kmh / 3.6
    return REACTION_S * v + (v * v - v_w * v_w) / G_MPS2


def _drive(
    road_map: RoadMap, lanes: list[str], speed_kmh: float, category: str, phase_s: float
) -> tuple[tuple[str, ...], np.ndarray, list[tuple[float, object]]]:
    """Drive ``lanes`` at constant speed from :data:`START_M`, an exact lane position every 0.1 s, to the end of the
    last lane's first 150 m: the path, where its lanes start, and each position's arc length with its answer."""
    path, starts_s = path_starts_s(road_map, lanes)
    engine = Engine(road_map)
    speed_mps = speed_kmh / 3.6
    answers = []
    s, k = START_M + speed_mps * phase_s, 0
    while s < starts_s[-2] + 150.0:
        lane = int(np.searchsorted(starts_s, s, side="right") - 1)
        fix = VehicleInput("car", category, speed_kmh, path[lane], s - float(starts_s[lane]), timestamp_s=k * STEP_S)
        answers.append((s, engine.evaluate(fix)))
        s, k = s + speed_mps * STEP_S, k + 1
    return path, starts_s, answers


def test_the_path_of_the_one_lane_goes_on_with_the_road(split_map: RoadMap) -> None:
    lookahead = LookAhead(split_map)
    # Both lanes after the split continue the road through S; only the left one keeps it past D.
    lanes, _ = lookahead.lanes_ahead("WS_0", 10.0, 400.0, None)
    assert "SD_1" in lanes and "DE_0" in lanes and "DR_0" not in lanes
    # The exit lane leads onto the ramp alone: its path is the ramp's.
    lanes, _ = lookahead.lanes_ahead("SD_0", 10.0, 400.0, None)
    assert lanes[-1] == "DR_0"
    # A route is followed on through the lane that leads along it, whichever way it goes at D.
    lanes, _ = lookahead.lanes_ahead("WS_0", 10.0, 400.0, ["WS", "SD", "DE"])
    assert "SD_1" in lanes and lanes[-1] == "DE_0"
    lanes, _ = lookahead.lanes_ahead("WS_0", 10.0, 400.0, ["WS", "SD", "DR"])
    assert "SD_0" in lanes and lanes[-1] == "DR_0"
    # A fix on the one lane keeps its path (it is the road's); one on the exit lane is given the road's, as ever.
    road_lanes = RoadLanes(lookahead)
    assert road_lanes.leads_to("WS_0") == ("SD", True)
    assert road_lanes("WS_0", 200.0) == ("WS_0", 200.0)
    assert road_lanes("SD_0", 20.0)[0] == "SD_1"


@settings(max_examples=20, deadline=None)
@given(
    speed_kmh=st.floats(50.0, 130.0),
    category=st.sampled_from(["M1", "M2", "M3", "N", "O"]),
    phase_s=st.floats(0.0, STEP_S),
)
def test_a_vehicle_going_on_along_the_road_is_never_warned_of_the_ramps_curve(
    split_map: RoadMap, speed_kmh: float, category: str, phase_s: float
) -> None:
    _, _, answers = _drive(split_map, ["WS_0", "SD_1", "DE_0"], speed_kmh, category, phase_s)
    assert answers[-1][1].state.value == "active"
    assert all(answer.level == 0 for _, answer in answers), [
        (round(s, 1), answer.level) for s, answer in answers if answer.level
    ]


@settings(max_examples=20, deadline=None)
@given(speed_kmh=st.floats(50.0, 120.0), phase_s=st.floats(0.0, STEP_S))
def test_a_vehicle_in_the_exit_lane_is_warned_where_formula_1_requires_or_from_the_split(
    split_map: RoadMap, speed_kmh: float, phase_s: float
) -> None:
    path, starts_s, answers = _drive(split_map, ["WS_0", "SD_0", "DR_0"], speed_kmh, "N", phase_s)
    curve_s = ramp_curve_start_s(split_map, path, starts_s, RAMP_STRAIGHT_M)
    speed_mps = speed_kmh / 3.6
    # 6.1: on once S <= S_w plus the travel during the next update and the system's delay.
    required_s = curve_s - _formula_1_m(speed_kmh, LEVEL_1_SPEED_AT_40_M_KMH) - speed_mps * (STEP_S + SYSTEM_DELAY_S)
    # Before the split the one lane's path is the road's: the exit lane counts from the split (the end of WS_0) on.
    split_s = float(starts_s[path.index("WS_0") + 1])
    expected_s = max(required_s, split_s)
    warned = [s for s, answer in answers if answer.level >= 1 and answer.warning.target.curve_id.startswith("DR@")]
    assert warned, speed_kmh
    assert expected_s - TOLERANCE_M <= warned[0] <= expected_s + speed_mps * STEP_S + TOLERANCE_M, (
        speed_kmh,
        warned[0],
        required_s,
        split_s,
    )
    # Nothing else warns before it: the one lane's path never offered the ramp's curve.
    assert all(answer.level == 0 for s, answer in answers if s < warned[0])
