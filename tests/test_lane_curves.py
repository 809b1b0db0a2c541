"""The lanes of one road share its curves: the same start and end, radii apart by the lanes' offsets.

Truth is constructed here: a three-lane road of a straight, a clothoid, an arc of radius R, a
clothoid and a straight, cut by a node inside the bend, built with netconvert. SUMO lays
the lanes to the right of the edge's shape, lane 0 outermost on the right, each
:data:`LANE_WIDTH_M` wide: lane i runs (n - i - 1/2) lane widths right of the shape, so its
radius is R + that on a left turn and R - that on a right turn.

The lanes of a road name its curve alike (its edge and lane position), so that a vehicle that
changes lane inside a curve keeps its warning: at a speed between the inner lane's V_w and the
outer lane's (Tables 1-2 at the radii the map gives each lane), 6.1 warns on the inner lane and
not on the outer one, and only the release rule, which remembers the curve and part that warned,
keeps the warning on after the change.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from builders import node_xml
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from csws.curvature import ConstantRadiusPart, Curve, RadiusProfile, straight_profile
from csws.engine import Engine, VehicleInput
from csws.geometry import arc, clothoid, sample_pieces, straight
from csws.road.roadmap import RoadMap
from csws.road.sharing import Run, kept_to_own_turn, lateral_offsets_m, moved_curve, reference_lanes
from csws.standard import warning_speed
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


def _moved_left(xy: np.ndarray, distance_m: float) -> np.ndarray:
    """A polyline moved ``distance_m`` to its left, each vertex square to its neighbours' chord."""
    tangent = np.gradient(xy, axis=0)
    tangent /= np.hypot(tangent[:, 0], tangent[:, 1])[:, None]
    return xy + distance_m * np.column_stack((-tangent[:, 1], tangent[:, 0]))


def _road(folder: Path, direction: str, lanes_after_node: int = LANES, node_into_arc_m: float = 20.0) -> RoadMap:
    """The three-lane road turning ``direction``, two edges meeting at a node ``node_into_arc_m`` beyond the
    arc's start; the second edge has ``lanes_after_node`` lanes, those it has more added on the left (its
    shape moved left by them, so that its first lanes go on where the first edge's do)."""
    pieces = (
        straight(APPROACH_M),
        clothoid(SPIRAL_M, math.inf, RADIUS_M, direction),
        arc(RADIUS_M, 35.0, direction),
        clothoid(SPIRAL_M, RADIUS_M, math.inf, direction),
        straight(300.0),
    )
    xy = np.round(sample_pieces(pieces, 2.0, (0.0, 0.0), 0.0)[0], 2)
    s = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))))
    middle = int(np.searchsorted(s, APPROACH_M + SPIRAL_M + node_into_arc_m))
    nodes = node_xml("A", xy[0]) + node_xml("M", xy[middle]) + node_xml("B", xy[-1])
    edges = "".join(
        f'<edge id="{edge}" from="{a}" to="{b}" numLanes="{lanes}" speed="30" shape="{shape_text(part)}"/>'
        for edge, a, b, lanes, part in (
            ("a", "A", "M", LANES, xy[: middle + 1]),
            ("b", "M", "B", lanes_after_node, _moved_left(xy[middle:], (lanes_after_node - LANES) * LANE_WIDTH_M)),
        )
    )
    net = netconvert(
        f"<nodes>{nodes}</nodes>", f"<edges>{edges}</edges>", folder / f"{direction}{lanes_after_node}.net.xml"
    )
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


def test_a_curve_borrowed_inside_a_parallel_run_keeps_its_radius_where_the_lane_turns_a_little_less():
    """A reference fit may turn as far as its own polyline and the angle tolerance allow; a lane beside it whose
    vertices turn a fraction of a degree less (a joint's vertex placed otherwise) still lies parallel to it, and
    keeps the curve at R - d. Where the reference goes on before the run, the curve cut at the run's start carries
    a turn the lane need not make, and is turned back to the lane's own turn as before."""
    xy, _ = sample_pieces([straight(200.0), arc(100.0, 20.0, "left"), straight(200.0)], 5.0)
    arc_m = 100.0 * math.radians(20.0)
    angle_deg = 20.0 + 5.5  # the reference's fit: its own 20.5 degree turn and the 5 degree tolerance
    radius_m = arc_m / math.radians(angle_deg)
    curve = Curve(
        200.0, 200.0 + arc_m, angle_deg, "left", radius_m, (ConstantRadiusPart(200.0, 200.0 + arc_m, radius_m, False),)
    )
    length_m = float(np.hypot(*np.diff(xy, axis=0).T).sum())

    def source(source_length_m: float) -> RadiusProfile:
        """The fit of the lane read (chain 1): only its length counts here."""
        return straight_profile(np.array([0.0, source_length_m]))

    whole = Run(1, np.array([0.0, length_m]), np.array([0.0, length_m]), np.array([3.2]))
    [kept] = kept_to_own_turn([curve], xy, 1000.0, [whole], [None, source(length_m)])
    assert kept == curve
    [turned_back] = kept_to_own_turn([curve], xy, 1000.0)  # without runs: the lane's own turn, 20 degrees
    assert turned_back.angle_deg == pytest.approx(20.0, abs=0.01)
    source_goes_on = Run(1, np.array([50.0, 50.0 + length_m - 200.0]), np.array([200.0, length_m]), np.array([3.2]))
    [cut] = kept_to_own_turn([curve], xy, 1000.0, [source_goes_on], [None, source(length_m + 100.0)])
    assert cut.angle_deg == pytest.approx(20.0, abs=0.01)


def test_the_lanes_of_a_road_name_its_curve_by_the_edge_and_lane_position_where_it_starts(road):
    road_map, _ = road
    (first,) = road_map.lane_curves("a_0")
    expected_id = f"a@{first.start_pos_m:.0f}"
    for i in range(LANES):
        for lane_id in (f"a_{i}", f"b_{i}"):
            (curve,) = road_map.lane_curves(lane_id)
            assert (curve.curve_id, curve.first_part_index) == (expected_id, 0), lane_id


def _inner_and_outer(direction: str) -> tuple[int, int]:
    """The innermost lane of the turn and its neighbour outside it."""
    return (LANES - 1, LANES - 2) if direction == "left" else (0, 1)


def _between_speeds_kmh(road_map: RoadMap, inner_lane: str, outer_lane: str) -> float:
    """A speed at which 6.1 warns (level 1, M1) inside the arc of ``inner_lane`` but not of ``outer_lane``, and
    which the release margin of 1 km/h keeps warned there: between the two lanes' V_w at their radii."""
    (inner,), (outer,) = road_map.lane_curves(inner_lane), road_map.lane_curves(outer_lane)
    inner_kmh = warning_speed(inner.curve.min_radius_m, "M1", 1)
    outer_kmh = warning_speed(outer.curve.min_radius_m, "M1", 1)
    assert outer.curve.min_radius_m > inner.curve.min_radius_m and 0.0 < outer_kmh - inner_kmh < 1.0
    return (inner_kmh + outer_kmh) / 2.0


def _drive(engine: Engine, steps: list[tuple[str, float]], speed_kmh: float, step_s: float) -> list:
    """One vehicle's answers at ``steps`` (lane, lane position), one every ``step_s``."""
    return [
        engine.evaluate(VehicleInput("truck", "M1", speed_kmh, lane_id, pos_m, timestamp_s=k * step_s))
        for k, (lane_id, pos_m) in enumerate(steps)
    ]


def test_a_lane_change_inside_the_curve_keeps_one_warning_of_one_curve(road):
    """Warned on the inner lane inside the arc, the vehicle moves to the outer lane, where 6.1 alone would not
    warn, and on across the node into the next edge: one warning, the same curve and part, no second onset."""
    road_map, direction = road
    inner, outer = _inner_and_outer(direction)
    speed_kmh = _between_speeds_kmh(road_map, f"a_{inner}", f"a_{outer}")
    step_s = 0.25
    step_m = speed_kmh / 3.6 * step_s
    end_of_a_m = road_map.lane(f"a_{inner}").length_m
    steps = [
        (f"a_{inner}", end_of_a_m - 10.0),
        (f"a_{outer}", end_of_a_m - 10.0 + step_m),
        (f"b_{outer}", 2.0 * step_m - 10.0),
        (f"b_{outer}", 3.0 * step_m - 10.0),
    ]
    assert steps[2][1] > 0.0  # the vehicle has crossed the node into edge b
    answers = _drive(Engine(road_map), steps, speed_kmh, step_s)
    targets = [answer.warning.target for answer in answers]
    assert [answer.warning.level for answer in answers] == [1] * len(steps)
    assert all(target is not None for target in targets)
    assert len({(target.curve_id, target.part_index) for target in targets}) == 1, targets
    assert not targets[0].held and all(target.held for target in targets[1:])
    # Without the memory of the curve that warned, 6.1 does not warn on the outer lane at that speed.
    for lane_id, pos_m in steps[1:]:
        (fresh,) = _drive(Engine(road_map), [(lane_id, pos_m)], speed_kmh, step_s)
        assert fresh.warning.level == 0, (lane_id, pos_m)


def test_a_lane_that_begins_inside_the_curve_names_it_and_its_parts_as_the_road_does(tmp_path: Path) -> None:
    """The second edge has one lane more, beginning at a node in the exit clothoid: its copy of the curve starts
    there (where the radius is still below R_c), yet is the road's curve, its parts counted from its first part."""
    arc_m = RADIUS_M * math.radians(35.0)
    road_map = _road(tmp_path, "left", lanes_after_node=LANES + 1, node_into_arc_m=arc_m + SPIRAL_M / 5)
    (road_curve,) = road_map.lane_curves("a_0")
    for i in range(LANES + 1):
        (curve,) = road_map.lane_curves(f"b_{i}")
        assert curve.curve_id == road_curve.curve_id, i
        # Both end where the road's curve ends: the copy's parts are the road's last ones.
        assert curve.first_part_index + len(curve.curve.parts) == len(road_curve.curve.parts), i
    added = f"b_{LANES}"
    (added_curve,) = road_map.lane_curves(added)
    assert added_curve.lane_id == added and added_curve.first_part_index > 0
    # A vehicle matched from the added lane onto the one beside it at one lane position is warned of one part.
    speed_kmh = warning_speed(added_curve.curve.min_radius_m, "M1", 1) + 10.0
    steps = [(added, 2.0), (f"b_{LANES - 1}", 2.0)]
    answers = _drive(Engine(road_map), steps, speed_kmh, 0.25)
    targets = [answer.warning.target for answer in answers]
    assert [answer.warning.level for answer in answers] == [1, 1] and None not in targets
    assert targets[0].curve_id == targets[1].curve_id == road_curve.curve_id
    assert targets[0].part_index == targets[1].part_index >= added_curve.first_part_index


@settings(max_examples=40, deadline=None)
@given(
    radius_m=st.floats(30.0, 500.0),
    offset_m=st.floats(-6.0, 6.0),
    points=st.integers(70, 400),
    turn_deg=st.floats(20.0, 170.0),
)
def test_a_long_lane_beside_a_bend_is_offset_by_its_distance_from_it(
    radius_m: float, offset_m: float, points: int, turn_deg: float
):
    """A lane of many points (measured through the spatial index, not against every segment) sampled on an arc
    ``offset_m`` left of its reference's arc lies that far across it, within the reference's chord sagitta."""
    assume(abs(offset_m) >= 0.1)
    turn_rad = math.radians(turn_deg)
    angles = np.linspace(-math.pi / 2, -math.pi / 2 + turn_rad, points)
    inside = np.linspace(angles[0], angles[-1], points + 7)[2:-2]  # the lane's points lie within the reference's span
    reference = radius_m * np.column_stack((np.cos(angles), np.sin(angles)))
    lane = (radius_m - offset_m) * np.column_stack((np.cos(inside), np.sin(inside)))  # a left turn: left is inward
    sagitta_m = radius_m * (1.0 - math.cos(turn_rad / (points - 1) / 2.0))
    assume(sagitta_m < 0.05)
    offsets = lateral_offsets_m([lane, reference], np.array([1, 1]))
    assert abs(offsets[0] - offset_m) <= sagitta_m + 1e-9
    assert offsets[1] == 0.0


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), points=st.integers(70, 200), vertices=st.integers(70, 200))
def test_a_lanes_offset_is_measured_to_its_nearest_segment_as_against_every_segment(
    seed: int, points: int, vertices: int
):
    """Against a wiggly reference, the offset of a lane of many points (the spatial index's path) is the median of
    each point's signed distance square to its nearest segment (the first of equals), found here against every
    segment, to the last bit."""
    rng = np.random.default_rng(seed)
    reference = np.column_stack((np.linspace(0.0, 300.0, vertices), np.cumsum(rng.normal(0.0, 0.05, vertices))))
    lane_x = np.sort(rng.uniform(0.0, 300.0, points))
    lane = np.column_stack((lane_x, np.interp(lane_x, *reference.T) + rng.normal(3.0, 0.05, points)))
    start, direction = reference[:-1], np.diff(reference, axis=0)
    length = np.hypot(direction[:, 0], direction[:, 1])
    relative = lane[:, None, :] - start[None, :, :]
    dot = relative[..., 0] * direction[None, :, 0] + relative[..., 1] * direction[None, :, 1]
    along = np.clip(dot / length[None, :] ** 2, 0.0, 1.0)
    away = lane[:, None, :] - (start[None, :, :] + along[..., None] * direction[None, :, :])
    nearest = np.argmin(np.hypot(away[..., 0], away[..., 1]), axis=1)
    rows = np.arange(points)
    across = (
        direction[nearest, 0] * relative[rows, nearest, 1] - direction[nearest, 1] * relative[rows, nearest, 0]
    ) / length[nearest]
    assert np.ptp(across) <= 0.5  # parallel: the lane has an offset
    assert lateral_offsets_m([lane, reference], np.array([1, 1]))[0] == float(np.median(across))


def test_a_long_lane_with_a_point_that_is_not_a_number_has_no_offset():
    """A lane of many points, one of them not a number, is not parallel to its reference: it has no offset
    (the spatial index leaves such a point out; it is measured as a short lane is, and its distance is NaN)."""
    reference = np.column_stack((np.linspace(0.0, 300.0, 100), np.zeros(100)))
    lane = reference + [0.0, 3.0]
    lane[40, 0] = math.nan
    offsets = lateral_offsets_m([lane, reference], np.array([1, 1]))
    assert math.isnan(offsets[0]) and offsets[1] == 0.0
