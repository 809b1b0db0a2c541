"""A fix at a junction's branching point (the end of a lane, where its connections start together) is placed on
the lane it comes from, never at the start of one of the connections (csws.road.hmm), against constructed truth:
the junction town of tests/junction_town.py, whose side streets' R 20 m curves are a level-2 warning at 50 km/h.

At the branching point every connection from the lane starts; a fix level with or behind it projects onto each
connection's first point, the same point for all of them, so it holds no evidence for any one turn. The tests
place fixes there, behind it and beside it toward either side street, at 50 to 80 km/h after a fix on the road,
and check the matcher never reports the start of a turning connection and the engine never warns of a side street; and
that a vehicle truly turning is still matched and warned from its first fix on the side street.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from junction_town import JUNCTION_XY, drive

from csws.engine import Engine, VehicleInput
from csws.networks import networks_dir
from csws.road.hmm import Fixes, SequenceMatcher, Track
from csws.road.lanegraph import LaneGraph
from csws.road.match_settings import MatchSettings
from csws.road.matching import Probes
from csws.road.roadmap import RoadMap
from csws.standard import Level

#: GNSS position noise of the fixes, m (the issue's 1 Hz feed).
SIGMA_M = 3.0


def _branching_point(town: RoadMap) -> np.ndarray:
    """Where the connections from the main road's lane into the junction start: the end of that lane, m."""
    return np.asarray(town.lane_shape("WJ_0"), dtype=float)[-1]


def _one(matcher: SequenceMatcher, xy, time_s: float, heading_deg: float, speed_mps: float, track: Track | None):
    """Match one fix continuing ``track``."""
    fixes = Fixes.of(Probes.everywhere(np.array([xy])), [time_s], [heading_deg], [speed_mps], [SIGMA_M])
    return matcher.match(fixes, [track])


@settings(max_examples=60, deadline=None)
@given(
    speed_kmh=st.floats(50.0, 80.0),
    behind_m=st.floats(0.0, 4.0),
    beside_m=st.floats(-3.0, 3.0),
    heading_off_deg=st.floats(-10.0, 10.0),
)
def test_a_fix_at_the_branching_point_is_never_placed_at_the_start_of_a_turn(
    town: RoadMap, matcher: SequenceMatcher, speed_kmh: float, behind_m: float, beside_m: float, heading_off_deg: float
) -> None:
    # The main road runs east along y = 0: a fix 1 s before is a second's travel back on it; the fix lies
    # behind_m back from the branching point and beside_m north (+) or south (-), toward either side street.
    speed_mps = speed_kmh / 3.6
    point = _branching_point(town)
    before = _one(matcher, point - (speed_mps + behind_m, 0.0), 0.0, 90.0, speed_mps, None)
    assert before.lane_id == ["WJ_0"]
    answer = _one(matcher, point + (-behind_m, beside_m), 1.0, 90.0 + heading_off_deg, speed_mps, before.tracks[0])
    lane_id, lane_pos_m = answer.lane_id[0], float(answer.lane_pos_m[0])
    assert lane_id is not None
    lane = town.lane(lane_id)
    assert not (lane.is_internal and not lane.continues_road and lane_pos_m <= 0.0), (lane_id, lane_pos_m)
    assert lane_id not in {"JS_0", "JN_0"}
    engine = Engine(town)
    warning = engine.evaluate(VehicleInput("v", "M1", speed_kmh, lane_id, lane_pos_m, timestamp_s=1.0)).warning
    assert not any(t.curve_id.startswith(("JS@", "JN@")) for t in warning.triggers), warning.triggers


@pytest.mark.parametrize("to_side", ["JS_0", "JN_0"])
def test_a_vehicle_turning_into_the_side_street_is_warned_from_its_first_fix_there(
    town: RoadMap, matcher: SequenceMatcher, to_side: str
) -> None:
    # At 50 km/h the side street's R 20 m curve is due a warning (the engine's own answer on the true lane says
    # so); every noisy drive that turns is placed on the turn (the side street or the connection into it) and
    # warned of that curve at its first fix on the side street.
    speed_kmh = 50.0
    speed_mps = speed_kmh / 3.6
    warned = 0
    for seed in range(20):
        route = drive(town, ["WJ_0", to_side], speed_mps, seed, sigma_m=SIGMA_M)
        first = route.lane_id.index(to_side)
        truth = Engine(town).evaluate(VehicleInput("t", "M1", speed_kmh, to_side, float(route.lane_pos_m[first])))
        engine, track = Engine(town), None
        for k in range(first + 1):
            x, y = route.xy[k]
            answer = _one(matcher, (x, y), float(route.time_s[k]), float(route.heading_deg[k]), speed_mps, track)
            track = answer.tracks[0]
            vehicle = VehicleInput("v", "M1", speed_kmh, answer.lane_id[0], float(answer.lane_pos_m[0]), timestamp_s=k)
            warning = engine.evaluate(vehicle).warning
        assert answer.lane_id[0] in {to_side, *town.expand_path(["WJ_0", to_side])[1:-1]}, seed
        if truth.warning.level >= Level.LEVEL_1:
            warned += 1
            assert any(t.curve_id.startswith(to_side[:2] + "@") for t in warning.triggers), seed
    assert warned > 0


def test_the_branching_point_is_where_the_connections_start(town: RoadMap) -> None:
    # The premise: every connection from the main road's lane starts at its end, the junction's entry.
    point = _branching_point(town)
    assert math.dist(point, JUNCTION_XY) < 15.0
    for following in town.successors("WJ_0"):
        assert math.dist(np.asarray(town.lane_shape(following))[0], point) < 1e-6, following


@pytest.fixture(scope="module")
def eager_matcher(town: RoadMap) -> SequenceMatcher:
    """A matcher that commits to a turn once it holds half the connections' probability (the least allowed)."""
    return SequenceMatcher([town], MatchSettings(commit_share=0.5))


@settings(max_examples=40, deadline=None)
@given(behind_m=st.floats(0.5, 3.0), beside_m=st.floats(-1.5, 1.5), turned_deg=st.floats(20.0, 44.0))
def test_a_fix_behind_the_branching_point_turned_toward_a_side_street_is_not_placed_on_the_turn(
    town: RoadMap, eager_matcher: SequenceMatcher, behind_m: float, beside_m: float, turned_deg: float
) -> None:
    # A fix before the junction whose heading already turns toward the south side street (up to the heading
    # tolerance): its projection onto every connection is their shared first point, the end of the main road's
    # lane. The heading gives the turn most of the connections' probability there, enough for a matcher that
    # commits at half of it; yet nothing shows the vehicle on the turn, so it is placed on the road (the lane
    # it drives or the road's continuation), never on the turn.
    matcher = eager_matcher
    speed_mps = 60.0 / 3.6
    point = _branching_point(town)
    before = _one(matcher, point - (speed_mps + behind_m, 0.0), 0.0, 90.0, speed_mps, None)
    answer = _one(matcher, point + (-behind_m, beside_m), 1.0, 90.0 + turned_deg, speed_mps, before.tracks[0])
    road_on = town.expand_path(["WJ_0", "JE_0"])
    assert answer.lane_id[0] in road_on, (answer.lane_id, answer.lane_pos_m)


def test_only_the_first_internal_lane_of_a_connection_is_its_start() -> None:
    # Bad Hersfeld's left turns are split by SUMO where turning vehicles wait for a gap: the start of the second
    # internal lane lies inside the turn, not at the end of the lane the connection comes from.
    city = RoadMap.load(networks_dir() / "badhersfeld.net.xml.gz")
    graph = LaneGraph([city], MatchSettings().reach_m)
    reached_from_a_road = {
        following
        for lane_id in city.lane_ids
        if not city.lane(lane_id).is_internal
        for following in city.successors(lane_id)
        if city.lane(following).is_internal
    }
    starts = {city.lane_ids[i] for i in np.flatnonzero(graph.connection_start)}
    assert starts == reached_from_a_road
    later = {lane_id for lane_id in city.lane_ids if city.lane(lane_id).is_internal} - starts
    assert later, "the city has split connections"
    internal_before = {
        following
        for lane_id in city.lane_ids
        if city.lane(lane_id).is_internal
        for following in city.successors(lane_id)
    }
    assert later <= internal_before  # each is reached from within a junction only
