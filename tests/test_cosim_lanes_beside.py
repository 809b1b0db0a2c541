"""A sleeping vehicle's path counts the curves of the lanes beside it (csws.cosim.lanes_beside).

On a constructed road whose left lane swerves by bends its right lane does not make, the right lane's
path ends straight, and the first curve a vehicle on it can meet is the left lane's first bend, where
the geometry put it. On the bundled city, for positions drawn at random, no other lane of the same edge
has a curve nearer than the schedule's distance (each lane's curves found by its own horizon, the way the
warning sees them there); and the internal lanes beside one are those of the connections sumolib reads
between the same two edges, whose curves a vehicle on any of them sleeps towards from the lane's start.
"""

from __future__ import annotations

import random
from collections import defaultdict

import numpy as np
import pytest
import sumolib
from lane_bend import B_START_M, BEND_START_M, lane_bend_net

from csws.ahead.lookahead import LookAhead
from csws.cosim.lanes_beside import LanesBeside
from csws.cosim.schedule import PartsAhead
from csws.networks import networks_dir
from csws.road.roadmap import RoadMap

#: The bundled city.
CITY_NET = networks_dir() / "badhersfeld.net.xml.gz"
#: How far a fitted curve start may lie from where the geometry put it, m.
START_TOLERANCE_M = 3.0


@pytest.mark.sumo
def test_the_right_lanes_path_ends_at_the_left_lanes_first_bend(tmp_path):
    lookahead = LookAhead(RoadMap.load(lane_bend_net(tmp_path), cache=False))
    horizon = lookahead.horizon("a_0", ("a", "b", "c"), 300.0)
    assert "b_0" in horizon.path.lane_ids and not horizon.part_start_s.size  # its own path is straight
    alone, _ = PartsAhead().distances_m([horizon], np.zeros(1))
    beside, _ = PartsAhead(beside=LanesBeside(lookahead)).distances_m([horizon], np.zeros(1))
    assert alone[0] == pytest.approx(horizon.path.length_m)
    assert beside[0] == pytest.approx(B_START_M + BEND_START_M, abs=START_TOLERANCE_M)


def _first_curve_m(lookahead: LookAhead, lane_id: str, lane_pos_m: float) -> float:
    """How far ahead of ``lane_pos_m`` a curve of ``lane_id`` itself starts (0 inside one), along the lane's own
    shape, as the warning measures it on that lane; infinite where none does. A curve that starts where the lane
    ends (to a micrometre) is the next lane's."""
    horizon = lookahead.horizon(lane_id, None, 50.0)
    path = horizon.path
    factor, on_lane_m = float(path.lane_position_factor[0]), float(path.lane_shape_length_m[0])
    nearest = np.inf
    for start_s, end_s in zip(horizon.part_start_s.tolist(), horizon.part_end_s.tolist(), strict=True):
        if start_s < on_lane_m - 1e-6 and end_s * factor > lane_pos_m:
            nearest = min(nearest, max(start_s - lane_pos_m / factor, 0.0))
    return nearest


@pytest.mark.slow
def test_no_lane_beside_a_path_in_the_city_has_a_curve_nearer_than_the_schedule_counts():
    road_map = RoadMap.load(CITY_NET)
    lookahead = LookAhead(road_map)
    parts = PartsAhead(beside=LanesBeside(lookahead))
    edges: dict[str, list[str]] = {}
    for lane_id in road_map.lane_ids:
        lane = road_map.lane(lane_id)
        if not lane.is_internal:
            edges.setdefault(lane.edge_id, []).append(lane_id)
    rng = random.Random(5)
    checked = 0
    for lanes in edges.values():
        for lane_id in lanes:
            lane = road_map.lane(lane_id)
            others = [other for other in lanes if other != lane_id]
            beside_m = {other: _first_curve_m(lookahead, other, 0.0) for other in others}
            if not any(np.isfinite(list(beside_m.values()))):
                continue
            horizon = lookahead.horizon(lane_id, None, 50.0)
            for lane_pos_m in (0.0, *(rng.uniform(0.0, lane.length_m) for _ in range(3))):
                distance_m, _ = parts.distances_m([horizon], np.array([horizon.vehicle_s(lane_pos_m)]))
                for other in others:
                    nearest_m = _first_curve_m(lookahead, other, lane_pos_m)
                    if np.isfinite(nearest_m):
                        checked += 1
                        assert distance_m[0] <= nearest_m + 1e-6, (lane_id, other, lane_pos_m)
    assert checked > 100


def _internal_lanes_by_edges(net_path) -> dict[tuple[str, str], set[str]]:
    """The internal lanes of every connection between two normal edges (the first via lane and those after it),
    as sumolib reads them."""
    net = sumolib.net.readNet(str(net_path), withInternal=True)
    ways: dict[tuple[str, str], set[str]] = defaultdict(set)
    for edge in net.getEdges(withInternal=False):
        for to_edge, connections in edge.getOutgoing().items():
            for connection in connections:
                via = connection.getViaLaneID()
                while via:
                    ways[edge.getID(), to_edge.getID()].add(via)
                    onward = [following.getViaLaneID() for following in net.getLane(via).getOutgoing()]
                    via = onward[0] if onward else ""
    return ways


@pytest.mark.slow
def test_internal_lanes_in_the_city_are_beside_those_joining_the_same_two_edges():
    lookahead = LookAhead(RoadMap.load(CITY_NET))
    beside = LanesBeside(lookahead)
    parts = PartsAhead(beside=beside)
    curved = 0
    for lanes in _internal_lanes_by_edges(CITY_NET).values():
        for lane_id in lanes:
            assert set(beside.beside(lane_id)) == lanes - {lane_id}
        for lane_id in sorted(lanes):
            if any(np.isfinite(_first_curve_m(lookahead, other, 0.0)) for other in lanes - {lane_id}):
                curved += 1
                distance_m, _ = parts.distances_m([lookahead.horizon(lane_id, None, 50.0)], np.zeros(1))
                assert distance_m[0] == 0.0, lane_id
    assert curved > 100
