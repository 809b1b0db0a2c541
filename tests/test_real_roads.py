"""Warnings on roads shaped like real ones, judged against geometry constructed here.

A curve between clothoids: level 1 comes on where the first curvature point ahead
requires it (formula (1) with the V_w of that point's radius), holds while the road
under and ahead of the vehicle requires it, and goes off within the release rule's
margin after that. A curve with a node and a side road inside
it: the curve index, the horizon from any lane and the warning name the same curve.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from builders import APPROACH_M, CURVE_RADIUS_M
from builders import edge_xml as _edge
from builders import node_xml as _node
from builders import split_curve_map as _split_curve_map

from csws.ahead.lookahead import LookAhead
from csws.engine import Engine, VehicleInput
from csws.geometry import arc, clothoid, curvature_at, piece_starts_s, sample_pieces, straight
from csws.road.roadmap import RoadMap
from csws.standard import DEFAULT_WARNING_RADIUS_M, kmh_to_mps, warning_distance, warning_speed
from csws.sumo.netbuild import netconvert
from csws.warning.rules import WarningSettings

pytestmark = pytest.mark.sumo  # every test here builds its network with netconvert

#: A curve of R 150 m between two 60 m clothoids, on one edge.
ARC_RADIUS_M = 150.0
SPIRAL_PIECES = (
    straight(400.0),
    clothoid(60.0, math.inf, ARC_RADIUS_M, "right"),
    arc(ARC_RADIUS_M, 25.0, "right"),
    clothoid(60.0, ARC_RADIUS_M, math.inf, "right"),
    straight(300.0),
)


@pytest.fixture(scope="module")
def spiral_map(tmp_path_factory) -> RoadMap:
    xy, _ = sample_pieces(SPIRAL_PIECES, 1.0, (0.0, 0.0), 0.0)
    nodes = _node("A", xy[0]) + _node("B", xy[-1])
    net = netconvert(
        f"<nodes>{nodes}</nodes>",
        f"<edges>{_edge('road', 'A', 'B', xy)}</edges>",
        tmp_path_factory.mktemp("spiral") / "spiral.net.xml",
    )
    return RoadMap.load(net)


def _level_1_truth(speed_kmh: float, category: str, allowance_m: float) -> tuple[float, float, float, float]:
    """From the constructed curvature: where level 1 may come on at the earliest (formula (1)
    plus the latency allowance) and must be on at the latest, the last position whose own
    point still requires it, and where the road's V_w has risen 1 km/h above the speed
    (a spiral piece is taken at the radius of its start: at most 1 km/h of V_w), m."""
    s = np.arange(0.0, piece_starts_s(SPIRAL_PIECES)[-1], 0.05)
    radius_m = 1.0 / np.maximum(np.abs(curvature_at(SPIRAL_PIECES, s)), 1e-12)
    in_curve = radius_m <= DEFAULT_WARNING_RADIUS_M
    speeds_kmh = np.full(len(s), np.inf)
    speeds_kmh[in_curve] = [warning_speed(r, category, 1) for r in radius_m[in_curve]]
    requiring = np.flatnonzero(speeds_kmh <= speed_kmh)
    onset = min(s[p] - warning_distance(speed_kmh, speeds_kmh[p]) for p in requiring)
    last = s[requiring[-1]]
    beyond = s[(s > last) & (speeds_kmh >= speed_kmh + 1.0)][0]
    return onset - allowance_m, onset, last, beyond


@pytest.mark.parametrize("category, over_kmh", [("M1", 10.0), ("M1", 25.0), ("N", 15.0)])
def test_level_1_over_a_curve_between_clothoids_comes_on_time_and_holds(spiral_map, category, over_kmh) -> None:
    settings = WarningSettings()
    speed_kmh = warning_speed(ARC_RADIUS_M, category, 1) + over_kmh
    allowance_m = kmh_to_mps(speed_kmh) * settings.latency_s
    step_m = kmh_to_mps(speed_kmh) * settings.update_period_s
    earliest, latest, last, beyond = _level_1_truth(speed_kmh, category, allowance_m)
    engine = Engine(spiral_map)
    positions = np.arange(0.0, spiral_map.lane("road_0").length_m, step_m)
    on = np.array(
        [
            engine.evaluate(VehicleInput("truck", category, speed_kmh, "road_0", float(x), ["road"])).level >= 1
            for x in positions
        ]
    )
    first, final = positions[np.flatnonzero(on)[[0, -1]]]
    assert earliest - step_m - 0.5 <= first <= latest + 0.5, (earliest, first, latest)
    assert on[(positions >= first) & (positions <= last)].all(), "level 1 released while the road still requires it"
    # Released within the release margin of 1 km/h of V_w (csws.warning.release): inside the exit spiral
    # the road's radius under the vehicle counts, and the map's spiral, fitted from the lane,
    # puts a given radius within a metre of the constructed one.
    assert last - step_m <= final <= beyond + 1.0, (last, final, beyond)


def test_the_index_the_horizon_and_the_warning_name_one_curve(tmp_path: Path) -> None:
    # The short curve of R 71 m with a node 9.5 m into it and a side road leaving there.
    road_map = _split_curve_map(tmp_path, 9.5, side_road=True)
    (indexed,) = [c for c in road_map.curves() if c.curve.angle_deg > 5.0]
    assert (indexed.lane_id, indexed.end_lane_id) == ("a_0", "b_0")
    assert indexed.start_pos_m == pytest.approx(APPROACH_M, abs=1.0)
    assert indexed.curve.min_radius_m == pytest.approx(CURVE_RADIUS_M, rel=0.03)
    indexed_id = indexed.curve_id
    indexed_radii = [part.radius_m for part in indexed.curve.parts]
    look_ahead = LookAhead(road_map)
    (through,) = [lane for lane in road_map.successors("a_0") if road_map.lane(lane).continues_road]
    starts = [("a_0", 50.0), ("a_0", APPROACH_M - 20.0), ("a_0", APPROACH_M + 2.0), (through, 0.0), ("b_0", 1.0)]
    for lane_id, lane_pos_m in starts:
        for route in (["a", "b"], None):
            ahead = look_ahead(lane_id, lane_pos_m, 90.0, "M1", route)
            ids = {cpoi.curve_id for cpoi in ahead.cpois}
            assert ids == {indexed_id}, (lane_id, lane_pos_m, route, ids)
            assert set(ahead.cpoi_radius_m) <= set(indexed_radii)
    speed_kmh = warning_speed(CURVE_RADIUS_M, "M1", 1) + 20.0
    answer = Engine(road_map).evaluate(VehicleInput("car", "M1", speed_kmh, "a_0", APPROACH_M - 30.0, ["a", "b"]))
    assert answer.level >= 1 and answer.warning.target.curve_id == indexed_id
