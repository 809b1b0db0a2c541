"""The lane a fix's path ahead starts from (csws.ahead.roadlane.RoadLanes) when the lane split lies one junction on:
the motorway exit of tests/exit_ramp.py with the road before the diverge cut in two, its last stretch only metres
long. The right lane of the first stretch goes on as the right lane of the last, which alone leads onto the ramp,
so a fix matched to it is on the exit lane as much as one matched on the last stretch: its path is the road's.
The same network shows which moves between two fixes the sequence matcher counts as lane changes."""

from __future__ import annotations

import numpy as np
import pytest
from exit_ramp import write_exit_ramp
from markers import marks_its_tests

from csws.ahead.lookahead import LookAhead
from csws.ahead.roadlane import RoadLanes
from csws.road.lanegraph import LaneGraph
from csws.road.roadmap import RoadMap


@pytest.fixture(scope="module")
@marks_its_tests("sumo")
def split_ahead(tmp_path_factory) -> RoadMap:
    return RoadMap.load(write_exit_ramp(tmp_path_factory.mktemp("split"), approach_m=15.0))


def test_a_lane_that_leads_onto_the_ramp_one_junction_on_starts_the_roads_path(split_ahead: RoadMap) -> None:
    road_lanes = RoadLanes(LookAhead(split_ahead))
    assert road_lanes.leads_to("WA_0") == ("DR", False)
    assert road_lanes.leads_to("WA_1") == ("WD", True) and road_lanes.leads_to("WA_2") == ("WD", True)
    fraction = 300.0 / split_ahead.lane("WA_0").length_m
    lane_id, lane_pos_m = road_lanes("WA_0", 300.0)
    assert lane_id == "WA_1" and lane_pos_m == pytest.approx(fraction * split_ahead.lane("WA_1").length_m)
    # the path of the road's lane does not reach the ramp
    lanes, _kind = road_lanes.lookahead.lanes_ahead(lane_id, 10.0, 600.0, None)
    assert not any(split_ahead.lane(lane).edge_id == "DR" for lane in lanes)
    # on the last stretch, as before, and a route onto the ramp keeps the matched lane
    assert road_lanes("WD_0", 5.0)[0] == "WD_1"
    assert road_lanes("WA_0", 300.0, route_edges=["WA", "WD", "DR"]) == ("WA_0", 300.0)


def test_lanes_that_keep_the_road_throughout_keep_their_own_path(split_ahead: RoadMap) -> None:
    road_lanes = RoadLanes(LookAhead(split_ahead))
    assert road_lanes("WA_2", 100.0) == ("WA_2", 100.0)
    assert road_lanes("WA_1", 100.0) == ("WA_1", 100.0)
    assert road_lanes("DR_0", 5.0) == ("DR_0", 5.0)


def test_a_vehicle_keeps_its_lane_through_a_junction_unless_it_changes_it(split_ahead: RoadMap) -> None:
    # Each lane of WA goes on as the same lane of WD; WD's right lane onto the ramp, the two others onto DE's lanes.
    graph = LaneGraph([split_ahead], reach_m=250.0)
    number = {lane_id: k for k, lane_id in enumerate(split_ahead.lane_ids)}
    onto_de = split_ahead.expand_path(["WD_1", "DE_0"])[1]
    moves = {
        ("WA_0", "WD_0"): False,
        ("WA_1", "WD_1"): False,
        ("WA_0", "WD_1"): True,  # across the node onto the neighbouring lane
        ("WA_0", "WA_1"): True,  # within the edge
        ("WA_2", "WA_2"): False,
        ("WD_1", onto_de): False,
        ("WD_0", onto_de): True,  # onto a connection another lane of the edge leads to
        (onto_de, "DE_0"): False,
        (onto_de, "DE_1"): True,  # off a connection onto a lane beside the one it leads to
        ("WD_0", "DR_0"): False,
        ("WA_0", "DE_1"): False,  # no junction between them: a route, not a lane change
    }
    from_lane = np.array([number[a] for a, _ in moves])
    to_lane = np.array([number[b] for _, b in moves])
    assert graph.changes_lane(from_lane, to_lane).tolist() == list(moves.values())


def _changes_lane_by_definition(road_map: RoadMap, graph: LaneGraph, a: int, b: int) -> bool:
    """Whether moving from lane ``a`` to lane ``b`` changes lanes, from the rule's wording: within an edge onto
    another lane; onto a connection another lane of the edge leads to; off a connection onto a lane beside the
    one it leads to; across a junction between normal lanes that no connection joins although one joins their
    edges (the connections followed here from the map's successors)."""
    ids = road_map.lane_ids
    lane_a, lane_b = road_map.lane(ids[a]), road_map.lane(ids[b])
    if lane_a.edge_id == lane_b.edge_id:
        return a != b
    entry_b, exit_a = int(graph.entry_lane[b]), int(graph.exit_lane[a])
    if lane_b.is_internal and entry_b >= 0 and road_map.lane(ids[entry_b]).edge_id == lane_a.edge_id:
        return entry_b != a
    if lane_a.is_internal and exit_a >= 0 and road_map.lane(ids[exit_a]).edge_id == lane_b.edge_id:
        return exit_a != b
    if lane_a.is_internal or lane_b.is_internal:
        return False
    reached_edges = set()
    for lane_id in road_map.lane_ids:
        if road_map.lane(lane_id).edge_id != lane_a.edge_id:
            continue
        for first in road_map.successors(lane_id):
            current = first
            while road_map.lane(current).is_internal and road_map.successors(current):
                current = road_map.successors(current)[0]
            if not road_map.lane(current).is_internal:
                reached_edges.add(road_map.lane(current).edge_id)
                if lane_id == ids[a] and current == ids[b]:
                    return False
    return lane_b.edge_id in reached_edges


def test_lane_changes_are_those_the_rule_names_for_every_pair_of_lanes(split_ahead: RoadMap) -> None:
    graph = LaneGraph([split_ahead], reach_m=250.0)
    count = len(split_ahead.lane_ids)
    from_lane, to_lane = (pair.ravel() for pair in np.meshgrid(np.arange(count), np.arange(count), indexing="ij"))
    expected = [_changes_lane_by_definition(split_ahead, graph, a, b) for a, b in zip(from_lane, to_lane, strict=True)]
    assert graph.changes_lane(from_lane, to_lane).tolist() == expected
    assert any(expected) and not all(expected)
