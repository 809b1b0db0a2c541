"""Road chains: a curve with a node inside it is a curve whole; only a turn into another road is a
junction manoeuvre. Every network is built by netconvert from geometry constructed here."""

from __future__ import annotations

import functools
import math
from pathlib import Path

import numpy as np
import pytest
import sumolib
from builders import APPROACH_M, CURVE_RADIUS_M
from builders import edge_xml as _edge
from builders import node_xml as _node
from builders import split_curve_map as _split_curve_map
from hypothesis import given, settings
from hypothesis import strategies as st

from csws.ahead.lookahead import LookAhead
from csws.engine import Engine, VehicleInput
from csws.networks import networks_dir
from csws.road.chains import RoadChains
from csws.road.continuations import road_continuations
from csws.road.roadmap import RoadMap
from csws.standard import kmh_to_mps, warning_distance, warning_speed
from csws.sumo.netbuild import netconvert
from csws.warning.rules import WarningSettings

pytestmark = pytest.mark.sumo  # every test here builds its network with netconvert


@pytest.mark.parametrize("node_after_start_m", [2.0, 9.5, 18.0, 24.0])
def test_a_node_inside_a_curve_leaves_the_curve_whole(tmp_path: Path, node_after_start_m: float) -> None:
    road_map = _split_curve_map(tmp_path, node_after_start_m)
    ahead = LookAhead(road_map)("a_0", APPROACH_M - 100.0, 90.0, "M1", ["a", "b"])
    assert len(ahead.cpois) >= 1
    assert ahead.cpoi_distance_m[0] == pytest.approx(100.0, abs=1.0)
    assert min(ahead.cpoi_radius_m) == pytest.approx(CURVE_RADIUS_M, rel=0.03)


@pytest.mark.parametrize("route", [["a", "b"], None], ids=["route", "predicted"])
def test_a_side_road_inside_a_curve_leaves_the_road_curve_whole(tmp_path: Path, route) -> None:
    road_map = _split_curve_map(tmp_path, 9.5, side_road=True)
    ahead = LookAhead(road_map)("a_0", APPROACH_M - 100.0, 90.0, "M1", route)
    assert ahead.cpoi_distance_m[0] == pytest.approx(100.0, abs=1.0)
    assert min(ahead.cpoi_radius_m) == pytest.approx(CURVE_RADIUS_M, rel=0.03)


def test_the_short_split_curve_warns_on_time(tmp_path: Path) -> None:
    """The reported case: M1 at V_w1 + 30 km/h, node 9.5 m into the curve. Level 1 must come on
    where formula (1) requires it (within one update's travel), never inside the curve, and
    level 2 never before level 1."""
    road_map = _split_curve_map(tmp_path, 9.5)
    settings = WarningSettings()
    level_1_speed_kmh = warning_speed(CURVE_RADIUS_M, "M1", 1)
    speed_kmh = level_1_speed_kmh + 30.0
    required_m = warning_distance(speed_kmh, level_1_speed_kmh)
    allowance_m = kmh_to_mps(speed_kmh) * settings.latency_s
    engine = Engine(road_map)
    step_m = kmh_to_mps(speed_kmh) * settings.update_period_s
    first_level: dict[int, float] = {}
    for road_s_m in np.arange(0.0, APPROACH_M, step_m):
        answer = engine.evaluate(VehicleInput("truck", "M1", speed_kmh, "a_0", float(road_s_m), ["a", "b"]))
        for level in range(1, int(answer.level) + 1):
            first_level.setdefault(level, APPROACH_M - road_s_m)
    assert 1 in first_level, "level 1 never came before the curve"
    assert required_m - step_m - 0.5 <= first_level[1] <= required_m + allowance_m + step_m + 1.0
    assert first_level.get(2, 0.0) <= first_level[1]


def _crossroads(folder: Path) -> sumolib.net.Net:
    """A crossroads of two straight roads, one with a higher priority."""
    arms = {"W": (-200.0, 0.0), "E": (200.0, 0.0), "S": (0.0, -200.0), "N": (0.0, 200.0)}
    nodes = [_node("C", (0.0, 0.0))] + [_node(name, xy) for name, xy in arms.items()]
    edges = []
    for name, xy in arms.items():
        priority = 3 if name in "WE" else 1
        edges.append(_edge(f"{name}in", name, "C", np.array([xy, (0.0, 0.0)]), priority))
        edges.append(_edge(f"{name}out", "C", name, np.array([(0.0, 0.0), xy]), priority))
    path = netconvert(
        "<nodes>" + "".join(nodes) + "</nodes>", "<edges>" + "".join(edges) + "</edges>", folder / "cross.net.xml"
    )
    return sumolib.net.readNet(str(path), withInternal=True)


def test_at_a_crossroads_only_straight_ahead_continues_the_road(tmp_path: Path) -> None:
    continuations = road_continuations(_crossroads(tmp_path))
    assert continuations == {("Win", "Eout"), ("Ein", "Wout"), ("Sin", "Nout"), ("Nin", "Sout")}


def test_turns_at_a_crossroads_are_junction_lanes_and_straight_ahead_is_road(tmp_path: Path) -> None:
    _crossroads(tmp_path)
    road_map = RoadMap.load(tmp_path / "cross.net.xml")
    internal = [road_map.lane(lane_id) for lane_id in road_map.lane_ids if road_map.lane(lane_id).is_internal]
    straight_ahead = {lane.lane_id for lane in internal if lane.continues_road}
    assert straight_ahead and all(not road_map.lane(lane_id).is_junction for lane_id in straight_ahead)
    turns = [lane for lane in internal if not lane.continues_road]
    assert turns and all(lane.is_junction for lane in turns)
    # A straight-ahead lane leads on in its own direction; a turn leads onto a perpendicular edge.
    for lane in internal:
        shape = road_map.lane_shape(lane.lane_id)
        (target,) = road_map.successors(lane.lane_id)
        target_shape = road_map.lane_shape(target)
        turning_rad = _heading_rad(target_shape[1] - target_shape[0]) - _heading_rad(shape[1] - shape[0])
        assert (abs(math.remainder(turning_rad, 2 * math.pi)) < math.radians(5.0)) == lane.continues_road


def _heading_rad(direction: np.ndarray) -> float:
    return math.atan2(direction[1], direction[0])


@functools.cache
def _fleet_chains() -> RoadChains:
    return RoadMap.load(networks_dir() / "fleet_scenario" / "fleet.net.xml").chains


@settings(max_examples=200, deadline=None)
@given(chain_fraction=st.floats(0.0, 1.0, exclude_max=True), start=st.floats(-0.1, 1.1), length=st.floats(0.0, 0.5))
def test_the_profile_parts_between_two_arc_lengths_are_those_that_overlap_the_stretch(
    chain_fraction: float, start: float, length: float
) -> None:
    """A path reads a chain's parts that overlap its run, found by bisection: the same parts, in order, as a scan of
    every part of the chain for overlap with the open stretch."""
    chains = _fleet_chains()
    chain = int(chain_fraction * len(chains.profiles))
    parts = chains.profiles[chain].parts
    chain_length_m = parts[-1].end_s if parts else 0.0
    start_s = start * chain_length_m
    end_s = start_s + length * chain_length_m
    overlapping = [part for part in parts if not (part.end_s <= start_s or part.start_s >= end_s)]
    assert list(chains.profile_parts_between(chain, start_s, end_s)) == overlapping
