"""The lanes of one road share its curves: the same start and end, radii apart by the lanes' offsets.

Truth is constructed here: a three-lane road of a straight, a clothoid, an arc of radius R, a
clothoid and a straight, cut by a node inside the bend, built with netconvert. SUMO lays
the lanes to the right of the edge's shape, lane 0 outermost on the right, each
:data:`LANE_WIDTH_M` wide: lane i runs (n - i - 1/2) lane widths right of the shape, so its
radius is R + that on a left turn and R - that on a right turn.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from builders import node_xml
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from csws.curvature import ConstantRadiusPart, Curve
from csws.engine import Engine, VehicleInput
from csws.geometry import arc, clothoid, sample_pieces, straight
from csws.road.roadmap import RoadMap
from csws.road.sharing import Run, lateral_offsets_m, moved_curve, reference_lanes
from csws.sumo.netbuild import netconvert, shape_text

pytestmark = pytest.mark.sumo  # every network here is built with netconvert

RADIUS_M = 180.0
LANES = 3
#: SUMO's default lane width, m.
LANE_WIDTH_M = 3.2
APPROACH_M = 400.0
SPIRAL_M = 50.0
#: How far apart two lanes' curve ends may lie: the lane positions are shared, so to the millimetre, m.
SAME_POSITION_M = 0.01
#: How far a fitted radius may lie from the constructed one, as a share of it.
RADIUS_TOLERANCE = 0.03


def _road(folder: Path, direction: str) -> RoadMap:
    """The three-lane road turning ``direction``, two edges meeting at a node inside the arc."""
    pieces = (
        straight(APPROACH_M),
        clothoid(SPIRAL_M, math.inf, RADIUS_M, direction),
        arc(RADIUS_M, 35.0, direction),
        clothoid(SPIRAL_M, RADIUS_M, math.inf, direction),
        straight(300.0),
    )
    xy = np.round(sample_pieces(pieces, 2.0, (0.0, 0.0), 0.0)[0], 2)
    s = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))))
    middle = int(np.searchsorted(s, APPROACH_M + SPIRAL_M + 20.0))
    nodes = node_xml("A", xy[0]) + node_xml("M", xy[middle]) + node_xml("B", xy[-1])
    edges = "".join(
        f'<edge id="{edge}" from="{a}" to="{b}" numLanes="{LANES}" speed="30" shape="{shape_text(part)}"/>'
        for edge, a, b, part in (("a", "A", "M", xy[: middle + 1]), ("b", "M", "B", xy[middle:]))
    )
    net = netconvert(f"<nodes>{nodes}</nodes>", f"<edges>{edges}</edges>", folder / f"{direction}.net.xml")
    return RoadMap.load(net, cache=False)


@pytest.fixture(scope="module", params=["left", "right"])
def road(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> tuple[RoadMap, str]:
    return _road(tmp_path_factory.mktemp("lanes"), request.param), request.param


def _expected_radius_m(lane_index: int, direction: str) -> float:
    """The constructed radius of a lane's arc: R plus or minus its distance right of the edge's shape."""
    right_of_shape_m = (LANES - lane_index - 0.5) * LANE_WIDTH_M
    return RADIUS_M + right_of_shape_m if direction == "left" else RADIUS_M - right_of_shape_m


def test_every_lane_has_the_roads_curve_at_the_same_place(road):
    road_map, direction = road
    curves = [road_map.lane_curves(f"a_{i}") for i in range(LANES)]
    assert all(len(lane_curves) == 1 for lane_curves in curves)
    first = curves[0][0]
    for i, (curve,) in enumerate(curves):
        assert curve.lane_id == f"a_{i}" and curve.end_lane_id == f"b_{i}"
        assert abs(curve.start_pos_m - first.start_pos_m) <= SAME_POSITION_M
        assert abs(curve.end_pos_m - first.end_pos_m) <= SAME_POSITION_M
        assert curve.curve.direction == direction
        # The constructed curve starts inside the entry clothoid (where its radius falls to R_c).
        assert APPROACH_M <= curve.start_pos_m <= APPROACH_M + SPIRAL_M
        expected_m = _expected_radius_m(i, direction)
        assert abs(curve.curve.min_radius_m - expected_m) <= RADIUS_TOLERANCE * expected_m
    # Neighbouring lanes' radii differ by one lane width, the sign by the side of the turn.
    radii = [lane_curves[0].curve.min_radius_m for lane_curves in curves]
    step = -LANE_WIDTH_M if direction == "left" else LANE_WIDTH_M
    assert np.allclose(np.diff(radii), step, atol=0.02)


def test_a_vehicle_on_the_neighbouring_lane_sees_the_same_cpois_at_offset_radii(road):
    """The path ahead from each lane at one lane position: the same CPOI distances, radii apart by the offset."""
    road_map, direction = road
    engine = Engine(road_map)
    seen = []
    for i in range(LANES):
        answer = engine.evaluate(VehicleInput(f"car{i}", "M1", 90.0, f"a_{i}", APPROACH_M - 150.0))
        assert answer.path is not None
        seen.append([(point[2], point[3]) for point in answer.path.cpoi_points()])
    assert seen[0] and all(len(points) == len(seen[0]) for points in seen)
    # Inside the bend a lane d to the side is d * angle turned shorter or longer: at most the whole turn's.
    turn_rad = math.radians(35.0) + SPIRAL_M / RADIUS_M
    for i, points in enumerate(seen[1:], start=1):
        # The curve start in SUMO's lane positions (which lanes of an edge share) is the same.
        lane, first_lane = road_map.lane(f"a_{i}"), road_map.lane("a_0")
        in_lane_m = points[0][0] * lane.length_m / lane.shape_length_m
        first_in_lane_m = seen[0][0][0] * first_lane.length_m / first_lane.shape_length_m
        assert abs(in_lane_m - first_in_lane_m) <= SAME_POSITION_M
        for (distance_m, radius_m), (first_distance_m, first_radius_m) in zip(points, seen[0], strict=True):
            assert abs(distance_m - first_distance_m) <= i * LANE_WIDTH_M * turn_rad + SAME_POSITION_M
            moved_m = i * LANE_WIDTH_M
            expected_m = first_radius_m - moved_m if direction == "left" else first_radius_m + moved_m
            assert radius_m == pytest.approx(expected_m, rel=1e-6)


def test_the_reference_lane_is_the_longest_chains_and_offsets_are_signed():
    """Offsets left of the reference are positive; a lane that is not parallel is not given one."""
    reference = reference_lanes(["e", "e", "e", "f"], [0, 1, 2, 0], np.array([10.0, 30.0, 30.0, 5.0]))
    assert reference.tolist() == [1, 1, 1, 3]
    line = np.array([[0.0, 0.0], [100.0, 0.0]])
    shapes = [line + [0.0, -3.2], line, line + [0.0, 3.2], line]
    assert lateral_offsets_m(shapes, reference) == pytest.approx([-3.2, 0.0, 3.2, 0.0])
    skewed = [np.array([[0.0, -3.2], [100.0, -6.0]]), line, line + [0.0, 3.2], line]
    assert math.isnan(lateral_offsets_m(skewed, reference)[0])


@settings(max_examples=200, deadline=None)
@given(
    st.floats(min_value=20.0, max_value=2000.0),
    st.floats(min_value=-10.0, max_value=10.0),
    st.sampled_from(["left", "right"]),
    st.floats(min_value=0.9, max_value=1.1),
)
def test_a_moved_curve_keeps_its_place_and_angle_and_moves_its_radius_by_the_offset(
    radius_m, offset_m, direction, stretch
):
    """A lane ``offset_m`` to the left of the reference: R - d inside a left turn, R + d outside a right
    one; the curve's ends at the same share of the lane, its angle kept."""
    assume(abs(offset_m) < radius_m / 2)
    part = ConstantRadiusPart(100.0, 150.0, radius_m, False)
    curve = Curve(100.0, 150.0, math.degrees(50.0 / radius_m), direction, radius_m, (part,))
    run = Run(0, np.array([0.0, 400.0]), np.array([0.0, 400.0 * stretch]), np.array([offset_m]))
    moved = moved_curve(curve, run)
    assert moved is not None
    expected_m = radius_m - offset_m if direction == "left" else radius_m + offset_m
    assert moved.min_radius_m == pytest.approx(expected_m, rel=1e-9)
    assert (moved.start_s, moved.end_s) == pytest.approx((100.0 * stretch, 150.0 * stretch))
    assert moved.angle_deg == curve.angle_deg and moved.direction == direction
