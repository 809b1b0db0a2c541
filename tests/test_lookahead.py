"""The path ahead (3.9) and its CPOIs (3.11) on networks built from constructed geometry."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from markers import marks_its_tests

from csws.ahead.horizon import is_cpoi
from csws.ahead.lookahead import LookAhead, LookAheadSettings, lookahead_distances_m
from csws.geometry import arc, sample_pieces, straight
from csws.road.roadmap import RoadMap
from csws.standard import warning_distance, warning_speed
from csws.sumo.netbuild import netconvert, shape_text
from csws.warning.rules import PathKind

#: A road "Main" runs east into junction J and on through a left curve; a side road
#: "Side" leaves J to the south-east and turns sharply right. Both curves are exact.
MAIN_PIECES = (straight(80.0), arc(100.0, 60.0, "left"), straight(100.0))
SIDE_HEADING_RAD = math.radians(-30.0)
SIDE_PIECES = (straight(60.0), arc(50.0, 90.0, "right"), straight(100.0))
JUNCTION_XY = (300.0, 0.0)


def _edge(edge_id: str, from_id: str, to_id: str, xy: np.ndarray, name: str) -> str:
    return (
        f'<edge id="{edge_id}" from="{from_id}" to="{to_id}" numLanes="1" speed="27.8" name="{name}" '
        f'type="highway.primary" spreadType="center" shape="{shape_text(xy)}"/>'
    )


@pytest.fixture(scope="module")
@marks_its_tests("sumo")
def junction_map(tmp_path_factory) -> RoadMap:
    main_xy, _ = sample_pieces(MAIN_PIECES, 1.0, JUNCTION_XY, 0.0)
    side_xy, _ = sample_pieces(SIDE_PIECES, 1.0, JUNCTION_XY, SIDE_HEADING_RAD)
    in_xy = np.array([[0.0, 0.0], JUNCTION_XY])
    nodes = [
        '<node id="A" x="0" y="0"/>',
        f'<node id="J" x="{JUNCTION_XY[0]}" y="{JUNCTION_XY[1]}" type="priority"/>',
        f'<node id="B" x="{main_xy[-1][0]:.6f}" y="{main_xy[-1][1]:.6f}"/>',
        f'<node id="C" x="{side_xy[-1][0]:.6f}" y="{side_xy[-1][1]:.6f}"/>',
    ]
    edges = [
        _edge("in", "A", "J", in_xy, "Main"),
        _edge("main", "J", "B", main_xy, "Main"),
        _edge("side", "J", "C", side_xy, "Side"),
    ]
    folder = tmp_path_factory.mktemp("junction")
    net = netconvert(
        "<nodes>" + "".join(nodes) + "</nodes>", "<edges>" + "".join(edges) + "</edges>", folder / "junction.net.xml"
    )
    return RoadMap.load(net)


def _junction_offset_m(road_map: RoadMap, edge_id: str) -> float:
    """How far the lane of ``edge_id`` starts after J: netconvert trims edges at a junction."""
    start = road_map.lane_shape(f"{edge_id}_0")[0]
    return float(np.hypot(*(start - np.array(JUNCTION_XY))))


def _truth_distance_m(vehicle_pos_m: float, curve_start_m: float) -> float:
    """Constructed distance from a vehicle on ``in`` to a curve ``curve_start_m`` along a branch, via J.

    The path runs along the authored shapes: to J, then along the branch; netconvert's
    trimming replaces a few metres around J by the internal lane, which changes the
    length by well under the 1.5 m the tests allow.
    """
    return (300.0 - vehicle_pos_m) + curve_start_m


def test_without_a_route_the_path_keeps_the_road(junction_map: RoadMap) -> None:
    ahead = LookAhead(junction_map)("in_0", 250.0, 80.0, "N")
    assert ahead.kind is PathKind.PREDICTED
    assert ahead.path.lane_ids[0] == "in_0" and "main_0" in ahead.path.lane_ids
    assert "side_0" not in ahead.path.lane_ids
    assert ahead.cpoi_radius_m == pytest.approx([100.0], rel=0.01)
    assert ahead.cpoi_distance_m[0] == pytest.approx(_truth_distance_m(250.0, 80.0), abs=1.5)


def test_with_a_route_the_path_follows_it_through_the_junction(junction_map: RoadMap) -> None:
    ahead = LookAhead(junction_map)("in_0", 250.0, 80.0, "N", route_edges=["in", "side"])
    assert ahead.kind is PathKind.ROUTE
    assert ahead.path.lane_ids[-1] == "side_0"
    assert any(lane.startswith(":J") for lane in ahead.path.lane_ids)
    side_curves = ahead.cpoi_radius_m[np.isclose(ahead.cpoi_radius_m, 50.0, rtol=0.02)]
    assert side_curves.size == 1
    distance = ahead.cpoi_distance_m[np.isclose(ahead.cpoi_radius_m, 50.0, rtol=0.02)][0]
    assert distance == pytest.approx(_truth_distance_m(250.0, 60.0), abs=1.5)


def test_a_route_that_leaves_the_network_ends_the_path(junction_map: RoadMap) -> None:
    ahead = LookAhead(junction_map)("in_0", 250.0, 80.0, "N", route_edges=["in", "nowhere"])
    assert ahead.kind is PathKind.ROUTE
    assert ahead.path.lane_ids == ("in_0",)
    assert ahead.cpoi_distance_m.size == 0


def test_a_vehicle_off_its_route_gets_the_predicted_path(junction_map: RoadMap) -> None:
    ahead = LookAhead(junction_map)("in_0", 250.0, 80.0, "N", route_edges=["side"])
    assert ahead.kind is PathKind.PREDICTED
    assert "main_0" in ahead.path.lane_ids


def test_the_end_of_a_dead_end_lane_has_nothing_ahead(junction_map: RoadMap) -> None:
    lane = junction_map.lane("main_0")
    ahead = LookAhead(junction_map)("main_0", lane.length_m, 60.0, "M1")
    assert ahead.cpoi_distance_m.size == 0
    beyond = LookAhead(junction_map)("main_0", lane.length_m + 50.0, 60.0, "M1")
    assert beyond.vehicle_s == pytest.approx(ahead.vehicle_s)


def test_inside_a_curve_the_cpoi_is_at_distance_zero(junction_map: RoadMap) -> None:
    inside_pos_m = 80.0 + 30.0 - _junction_offset_m(junction_map, "main")
    ahead = LookAhead(junction_map)("main_0", inside_pos_m, 60.0, "M1")
    assert ahead.cpoi_distance_m[0] == 0.0
    assert ahead.cpoi_radius_m[0] == pytest.approx(100.0, rel=0.01)


def test_cpois_beyond_the_lookahead_distance_are_not_of_interest(junction_map: RoadMap) -> None:
    short = LookAhead(junction_map, LookAheadSettings(fixed_distance_m=100.0))
    assert short("in_0", 250.0, 80.0, "N").cpoi_distance_m.size == 0  # the curve starts ~130 m ahead
    near = short("in_0", 290.0, 80.0, "N")  # ~90 m ahead
    assert near.cpoi_distance_m.size == 1 and near.cpoi_distance_m[0] <= 100.0


def test_lookahead_distance_covers_the_largest_warning_distance():
    assert lookahead_distances_m(np.array([50.0]))[0] == 250.0
    v = 250 / 3.6
    assert lookahead_distances_m(np.array([250.0]))[0] == pytest.approx(0.8 * v + v**2 / 9.8 + v * 0.2)
    with pytest.raises(ValueError, match="fixed_distance_m must be a positive number"):
        LookAheadSettings(fixed_distance_m=0.0)


@pytest.mark.parametrize("update_period_s, age_s", [(1.0, 0.0), (5.0, 0.0), (2.0, 1.5)])
@pytest.mark.parametrize("speed_kmh", [60.0, 90.0, 130.0])
def test_a_slowly_reporting_vehicle_looks_as_far_as_its_own_latency_needs(speed_kmh, update_period_s, age_s):
    """A vehicle learnt to report every few seconds is warned that much earlier (formula (1) plus
    its latency), so S_LAD must reach the curve that warning is for, with V_w near 0 (3.9)."""
    v = speed_kmh / 3.6
    needed_m = 0.8 * v + v**2 / 9.8 + v * (update_period_s + 0.1 + age_s)  # the system delay is 0.1 s
    speeds = np.array([speed_kmh])
    assert lookahead_distances_m(speeds, update_period_s=np.array([update_period_s]), age_s=age_s)[0] == pytest.approx(
        max(250.0, needed_m)
    )
    assert lookahead_distances_m(speed_kmh, update_period_s=update_period_s, age_s=age_s) == pytest.approx(
        max(250.0, needed_m)
    )


@pytest.mark.parametrize("speed_kmh", [60.0, 130.0, 180.0, 250.0])
@pytest.mark.parametrize("radius_m", [5.0, 10.0, 25.0, 40.0, 200.0])
def test_the_lookahead_distance_reaches_every_warning_distance(speed_kmh, radius_m):
    """Below the table radii the warning speed keeps falling: S_LAD must still cover S_w (3.9, 3.11)."""
    allowance_m = speed_kmh / 3.6 * 0.2
    for category in ("M1", "M2", "N"):
        needed_m = warning_distance(speed_kmh, warning_speed(radius_m, category, 1)) + allowance_m
        assert lookahead_distances_m(np.array([speed_kmh]))[0] >= needed_m


def test_paths_are_cached(junction_map: RoadMap) -> None:
    lookahead = LookAhead(junction_map)
    first = lookahead("in_0", 250.0, 80.0, "N")
    again = lookahead("in_0", 251.0, 80.0, "N")
    assert again.path is first.path
    assert again.cpoi_distance_m[0] == pytest.approx(first.cpoi_distance_m[0] - 1.0, abs=1e-9)


def test_unknown_lanes_raise_key_error(junction_map: RoadMap) -> None:
    with pytest.raises(KeyError):
        LookAhead(junction_map)("nope_0", 0.0, 50.0, "N")


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    lane_pos_m=st.floats(min_value=-5.0, max_value=300.0),
    speed_kmh=st.floats(min_value=0.0, max_value=220.0),
    fixed_distance_m=st.one_of(st.none(), st.floats(min_value=1.0, max_value=600.0)),
)
def test_one_vehicles_cpois_in_plain_floats_are_the_batchs_to_the_bit(
    junction_map: RoadMap, lane_pos_m: float, speed_kmh: float, fixed_distance_m: float | None
) -> None:
    """One vehicle's CPOIs, found in plain floats, are those the array rule (3.11) picks from its horizon, and
    those of the same vehicle in a batch: same horizon, rows, distances, radii and passed flags."""
    lookahead = LookAhead(junction_map, LookAheadSettings(fixed_distance_m=fixed_distance_m))
    for lane_id in ("in_0", "main_0", "side_0"):
        ahead = lookahead(lane_id, lane_pos_m, speed_kmh, "M1")
        batch = lookahead.many([lane_id], np.array([lane_pos_m]), np.array([speed_kmh]), [None])
        assert ahead.horizon is batch.horizons[0]
        assert ahead.vehicle_s == batch.vehicle_s[0] and ahead.lookahead_m == batch.lookahead_m[0]
        h = ahead.horizon
        rows = np.flatnonzero(is_cpoi(h.part_start_s, h.part_end_s, ahead.vehicle_s, ahead.lookahead_m))
        points = ahead.cpoi_points()
        assert [(curve_id, part) for curve_id, part, *_ in points] == list(
            zip(h.part_curve_id[rows].tolist(), h.part_index[rows].tolist(), strict=True)
        )
        assert [point[2] for point in points] == np.maximum(h.part_start_s[rows] - ahead.vehicle_s, 0.0).tolist()
        assert [point[2] for point in points] == batch.cpoi_distance_m.tolist() == ahead.cpoi_distance_m.tolist()
        assert [point[3] for point in points] == batch.cpoi_radius_m.tolist() == ahead.cpoi_radius_m.tolist()
        assert [point[4] for point in points] == batch.cpoi_passed.tolist() == ahead.cpoi_passed.tolist()
