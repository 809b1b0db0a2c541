"""Map matching against the side roads of tests/builders.py: a two-way main road, a one-way
frontage road beside it and a crossing road, each built exactly with csws.geometry."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import shapely
from builders import CROSSING_X_M, FRONTAGE_OFFSET_M, LANE_WIDTH_M, build_side_roads
from markers import marks_its_tests

from csws.road.match_settings import MatchSettings
from csws.road.matching import (
    MapMatcher,
    MapPosition,
    Probes,
    compass_to_math_rad,
    lane_point,
    points_along,
)
from csws.road.roadmap import RoadMap


@pytest.fixture(scope="module")
@marks_its_tests("sumo")
def side_map(tmp_path_factory) -> RoadMap:
    return RoadMap.load(build_side_roads(tmp_path_factory.mktemp("side")))


def _match(matcher: MapMatcher, xy, heading_deg=None, previous=None):
    xy = np.atleast_2d(np.asarray(xy, dtype=float))
    heading = None if heading_deg is None else np.atleast_1d(np.asarray(heading_deg, dtype=float))
    return matcher.match(Probes.everywhere(xy), heading, previous)


def test_compass_headings_turn_into_math_angles() -> None:
    assert compass_to_math_rad(np.array([0.0, 90.0, 180.0, 270.0])) == pytest.approx(
        [np.pi / 2, 0.0, -np.pi / 2, -np.pi]
    )


def test_points_along_a_polyline_follow_its_arc_length() -> None:
    xy = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 5.0]])
    assert points_along(xy, np.array([0.0, 4.0, 12.0, 99.0])) == pytest.approx(
        np.array([[0.0, 0.0], [4.0, 0.0], [10.0, 2.0], [10.0, 5.0]])
    )


def test_the_heading_picks_the_direction_of_a_two_way_road(side_map: RoadMap) -> None:
    matcher = MapMatcher([side_map])
    y = -LANE_WIDTH_M / 2 + 0.4  # on the eastbound lane, nearer the axis than the westbound one is
    east = _match(matcher, [[200.0, y]], 90.0)
    west = _match(matcher, [[200.0, y]], 270.0)
    assert east.lane_id == ["AB_0"]
    assert west.lane_id == ["BA_0"]
    assert east.lane_pos_m[0] == pytest.approx(200.0, abs=0.01)
    assert west.lane_pos_m[0] == pytest.approx(600.0, abs=0.01)
    assert west.distance_m[0] == pytest.approx(LANE_WIDTH_M - 0.4, abs=0.01)


def test_a_crossing_road_is_rejected_by_the_heading(side_map: RoadMap) -> None:
    matcher = MapMatcher([side_map])
    over_the_bridge = [[CROSSING_X_M + 0.5, -LANE_WIDTH_M / 2 - 1.0]]  # 0.5 m from the crossing, 1 m from AB
    assert _match(matcher, over_the_bridge).lane_id == ["crossing_0"]  # nearest without a heading
    assert _match(matcher, over_the_bridge, 90.0).lane_id == ["AB_0"]
    assert _match(matcher, over_the_bridge, 0.0).lane_id == ["crossing_0"]


def test_the_previous_lane_keeps_a_vehicle_off_the_parallel_road(side_map: RoadMap) -> None:
    matcher = MapMatcher([side_map])
    between = [[300.0, 5.0]]  # 3.4 m from the frontage road's lane, 6.6 m from the eastbound main lane
    assert _match(matcher, between, 90.0).lane_id == ["frontage_0"]
    kept = _match(matcher, between, 90.0, [MapPosition(0, "AB_0")])
    assert kept.lane_id == ["AB_0"]
    assert bool(kept.continued[0]) is True
    assert kept.distance_m[0] == pytest.approx(5.0 + LANE_WIDTH_M / 2, abs=0.01)


def test_a_fix_matching_nothing_says_why(side_map: RoadMap) -> None:
    matcher = MapMatcher([side_map], MatchSettings(tolerance_m=5.0))
    result = _match(
        matcher, [[300.0, 200.0], [200.0, 0.0 - LANE_WIDTH_M / 2], [100.0, FRONTAGE_OFFSET_M]], [90.0, 0.0, 180.0]
    )
    assert result.lane_id == [None, None, None]
    assert list(result.map_index) == [-1, -1, -1]
    assert np.isnan(result.distance_m).all()
    assert result.reason[0] == "no lane within 5 m"
    assert "heading 0 deg" in result.reason[1]
    assert "heading 180 deg" in result.reason[2]


def test_several_maps_are_matched_at_once(side_map: RoadMap, tmp_path: Path) -> None:
    shifted = RoadMap.load(build_side_roads(tmp_path, origin_x_m=5000.0))
    matcher = MapMatcher([side_map, shifted])
    result = _match(matcher, [[5200.0, FRONTAGE_OFFSET_M + 0.5], [200.0, FRONTAGE_OFFSET_M + 0.5]], [90.0, 90.0])
    assert list(result.map_index) == [1, 0]
    assert result.lane_id == ["frontage_0", "frontage_0"]
    assert result.lane_pos_m == pytest.approx([200.0, 200.0], abs=0.01)
    same_place = MapMatcher([side_map, side_map])
    assert list(_match(same_place, [[200.0, FRONTAGE_OFFSET_M]], 90.0).map_index) == [0]  # ties: the first map
    assert list(_match(same_place, [[200.0, FRONTAGE_OFFSET_M]], 90.0, [MapPosition(1, "frontage_0")]).map_index) == [1]


def test_a_fix_confined_to_one_map_is_matched_there_alone(side_map: RoadMap) -> None:
    matcher = MapMatcher([side_map, side_map])
    on_the_frontage = np.array([[200.0, FRONTAGE_OFFSET_M]])
    assert list(matcher.match(Probes(1, np.array([0]), on_the_frontage, np.array([1]))).map_index) == [1]
    # A vehicle last seen on the second map, now confined to the first: its previous lane counts for nothing.
    confined = matcher.match(
        Probes(1, np.array([0]), on_the_frontage, np.array([0])), None, [MapPosition(1, "frontage_0")]
    )
    assert (list(confined.map_index), bool(confined.continued[0])) == ([0], False)


def test_a_fix_placed_on_no_map_matches_nothing(side_map: RoadMap) -> None:
    result = MapMatcher([side_map]).match(Probes.everywhere(np.array([[np.nan, np.nan]])))
    assert result.lane_id == [None] and result.reason == ["no lane within 10 m"]


def test_a_fix_placed_on_each_map_in_its_own_coordinates_is_matched_on_the_best(
    side_map: RoadMap, tmp_path: Path
) -> None:
    # As lon/lat is placed on each geo-referenced network: one probe per map, in that map's coordinates.
    shifted = RoadMap.load(build_side_roads(tmp_path, origin_x_m=5000.0))
    matcher = MapMatcher([side_map, shifted])
    xy = np.array([[200.0, FRONTAGE_OFFSET_M + 2.0], [5200.0, FRONTAGE_OFFSET_M + 1.0]])
    probes = Probes(1, np.array([0, 0]), xy, np.array([0, 1]))
    result = matcher.match(probes, np.array([90.0]))
    assert (list(result.map_index), result.lane_id) == ([1], ["frontage_0"])
    assert result.distance_m[0] == pytest.approx(1.0)


def test_lane_point_is_the_inverse_of_matching(side_map: RoadMap) -> None:
    x, y = lane_point(side_map, "BA_0", 250.0)
    assert (x, y) == pytest.approx((550.0, LANE_WIDTH_M / 2), abs=0.01)
    assert _match(MapMatcher([side_map]), [[x, y]], 270.0).lane_pos_m[0] == pytest.approx(250.0, abs=1e-6)


def test_settings_are_checked() -> None:
    with pytest.raises(ValueError, match="tolerance_m"):
        MatchSettings(tolerance_m=0.0)
    with pytest.raises(ValueError, match="heading_tolerance_deg"):
        MatchSettings(heading_tolerance_deg=200.0)


def test_nearby_finds_every_lane_within_each_fixs_own_radius(side_map: RoadMap) -> None:
    # The lanes near each fix, its radius its own: against each lane's distance from the fix measured on its
    # full shape (the index holds the shapes simplified within 0.01 m, so lanes that close to the edge of the
    # radius are left out of the comparison).
    rng = np.random.default_rng(5)
    shapes = {lane_id: shapely.LineString(side_map.lane_shape(lane_id)) for lane_id in side_map.lane_ids}
    xy = np.column_stack((rng.uniform(-50.0, 1300.0, 300), rng.uniform(-60.0, 260.0, 300)))
    radius_m = rng.uniform(1.0, 30.0, 300)
    matcher = MapMatcher([side_map])
    found = matcher.nearby(Probes.everywhere(xy), radius_m)
    for fix, point in enumerate(shapely.points(xy)):
        distance_m = {lane_id: shape.distance(point) for lane_id, shape in shapes.items()}
        rows = np.flatnonzero(found.point_index == fix)
        pairs = zip(found.lane_index[rows].tolist(), found.distance_m[rows].tolist(), strict=True)
        got = {matcher.lane_name(lane)[1]: d for lane, d in pairs}
        clear = {lane_id for lane_id, d in distance_m.items() if abs(d - radius_m[fix]) > 0.02}
        assert {lane_id for lane_id in clear if distance_m[lane_id] <= radius_m[fix]} == set(got) & clear
        assert all(
            d <= radius_m[fix] and d == pytest.approx(distance_m[lane_id], abs=0.02) for lane_id, d in got.items()
        )
    assert 0 < len(found) and len(set(found.point_index.tolist())) < 300
