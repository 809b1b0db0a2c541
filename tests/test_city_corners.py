"""A city map's corners and borrowed curves against constructed truth: no phantom curve, no corner missed.

Every polyline is built here from headings and lengths, so each vertex's turn and each stretch's
net turn are known exactly; the curves are those the curve index reads (:func:`fit_road_chains`).
Two causes found on Bad Hersfeld's map are rebuilt:

* a corner mapped by one node at the joint of two edges, on the lane that leads through it, while
  the lane beside it on the second edge is entered from elsewhere and runs straight: the second
  lane borrows its road's curves (:mod:`csws.road.sharing`), but not the half of the corner's arc
  that lies past the joint, which its own polyline never turns;
* a corner mapped by one node on a way that otherwise bends gently, which the fit can run through
  with one long curve of a large radius: the corner still gets a curve of its own turn.
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from csws.curvature.artefacts import polyline_turns
from csws.curvature.corners import ANGLE_TOLERANCE_DEG
from csws.road.chains import RoadChains, fit_road_chains
from csws.standard import DEFAULT_POLICY

#: The warning curvature radius the curves are found with, m.
WARNING_RADIUS_M = 300.0
#: SUMO's default lane width, m.
LANE_WIDTH_M = 3.2


def _way(headings_deg: list[float], lengths_m: list[float], start: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """A polyline from ``start`` along segments of the given headings and lengths."""
    steps = [
        length * np.array([math.cos(math.radians(h)), math.sin(math.radians(h))])
        for h, length in zip(headings_deg, lengths_m, strict=True)
    ]
    return np.concatenate(([start], start + np.cumsum(steps, axis=0)))


def _densified(xy: np.ndarray, step_m: float) -> np.ndarray:
    """The polyline with a vertex every ``step_m`` or less along each segment, its own vertices kept."""
    points = [xy[:1]]
    for a, b in zip(xy[:-1], xy[1:], strict=True):
        count = max(math.ceil(float(np.hypot(*(b - a))) / step_m), 1)
        points.append(a + (b - a) * (np.arange(1, count + 1) / count)[:, None])
    return np.round(np.concatenate(points), 2)


def _chains(shapes: list[np.ndarray], continues_into: list[int], edge_ids: list[str], index: list[int]) -> RoadChains:
    """The road chains of lanes of the given shapes, continuations, edges and lane indices."""
    return fit_road_chains(
        np.array(continues_into),
        shapes,
        np.array([np.hypot(*np.diff(shape, axis=0).T).sum() for shape in shapes]),
        np.zeros(len(shapes), dtype=bool),
        edge_ids=edge_ids,
        lane_index=index,
    )


@settings(max_examples=30, deadline=None)
@given(st.floats(25.0, 120.0), st.sampled_from([-1.0, 1.0]), st.floats(40.0, 150.0), st.sampled_from([1.0, 10.0]))
def test_the_lane_beside_a_corner_at_an_edge_joint_borrows_no_curve_it_does_not_turn(
    turn_deg: float, side: float, approach_m: float, step_m: float
) -> None:
    # Lane p_0 heads into the joint at the origin, turning there by ``turn_deg`` onto lane e_0 (+x); lane e_1 lies
    # one lane width left of e_0 and continues no lane: its chain starts at the joint, straight. Vertices every
    # ``step_m`` or less (a node every metre of a SUMO shape, or every 10 m).
    approach = _way([-side * turn_deg], [approach_m])
    approach = approach - approach[-1]
    lane_0 = _way([0.0], [250.0])
    lane_1 = _way([0.0], [250.0], (0.0, LANE_WIDTH_M))
    shapes = [_densified(xy, step_m) for xy in (approach, lane_0, lane_1)]
    chains = _chains(shapes, [1, -1, -1], ["p", "e", "e"], [0, 0, 1])
    through, beside = int(chains.lane_chain[1]), int(chains.lane_chain[2])
    assert through != beside and not chains.runs[beside][0].is_own  # e_1 reads e_0's fit
    # The lane through the joint turns the corner by its turn.
    direction = "left" if side > 0 else "right"
    (corner,) = [c for c in chains.curves(through, WARNING_RADIUS_M, DEFAULT_POLICY) if c.direction == direction]
    assert corner.start_s < approach_m < corner.end_s
    assert abs(corner.angle_deg - turn_deg) <= ANGLE_TOLERANCE_DEG
    # The lane beside it is straight from its start: no curve, and a profile of no curvature.
    assert chains.curves(beside, WARNING_RADIUS_M, DEFAULT_POLICY) == []
    assert all(part.curvature == 0.0 and part.final_curvature == 0.0 for part in chains.profiles[beside].parts)


@settings(max_examples=30, deadline=None)
@given(st.floats(25.0, 120.0), st.sampled_from([-1.0, 1.0]), st.floats(40.0, 120.0))
def test_a_lane_beside_one_that_turns_alike_keeps_the_roads_curve(
    turn_deg: float, side: float, approach_m: float
) -> None:
    # As above, but e_1 is entered by a lane of its own that turns alike, beside p_0: both lanes turn the corner.
    approach = _way([-side * turn_deg], [approach_m])
    approach = approach - approach[-1]
    heading = math.radians(-side * turn_deg)
    left = LANE_WIDTH_M * np.array([-math.sin(heading), math.cos(heading)])
    # The left lane's joint lies where its two lines meet, on the corner's bisector: x = -W tan(heading / 2).
    joint = np.array([-LANE_WIDTH_M * math.tan(heading / 2.0), LANE_WIDTH_M])
    approach_1 = approach + left + (joint - (approach[-1] + left))
    lane_0 = _way([0.0], [250.0])
    lane_1 = _way([0.0], [250.0 - float(joint[0])], (float(joint[0]), LANE_WIDTH_M))
    shapes = [_densified(xy, 10.0) for xy in (approach, approach_1, lane_0, lane_1)]
    chains = _chains(shapes, [2, 3, -1, -1], ["p", "p", "e", "e"], [0, 1, 0, 1])
    direction = "left" if side > 0 else "right"
    for lane in (2, 3):
        chain = int(chains.lane_chain[lane])
        turning = [c for c in chains.curves(chain, WARNING_RADIUS_M, DEFAULT_POLICY) if c.direction == direction]
        assert abs(sum(c.angle_deg for c in turning) - turn_deg) <= ANGLE_TOLERANCE_DEG, lane


def _gentle_way_with_a_corner(
    gentle_deg: float, corner_deg: float, segments: int, segment_m: float, corner_at: int
) -> np.ndarray:
    """A way of ``segments`` segments of ``segment_m``, each node turning ``gentle_deg`` one way, but the node
    after segment ``corner_at``, which turns ``corner_deg`` (signed degrees, left positive)."""
    turns = [corner_deg if node == corner_at else gentle_deg for node in range(1, segments)]
    headings = np.concatenate(([0.0], np.cumsum(turns)))
    return _way(list(headings), [segment_m] * segments)


@settings(max_examples=40, deadline=None)
@given(
    st.floats(0.5, 2.0),
    st.floats(30.0, 70.0),
    st.sampled_from([-1.0, 1.0]),
    st.sampled_from([-1.0, 1.0]),
    st.integers(8, 16),
    st.floats(25.0, 60.0),
    st.data(),
)
def test_a_corner_on_a_gently_bending_way_gets_a_curve_of_its_turn(
    gentle_deg: float, corner_deg: float, gentle_side: float, corner_side: float, segments: int, segment_m: float, data
) -> None:
    # Nodes every 25-60 m turning 0.5-2 degrees one way (a radius of 700 m or more), one of them a corner of
    # 30-70 degrees either way: a curve of the corner's direction reaches within half a segment of its node
    # (the road through the nodes turns there), and the curves there turn its turn within the tolerance.
    corner_at = data.draw(st.integers(2, segments - 3))
    xy = _gentle_way_with_a_corner(gentle_side * gentle_deg, corner_side * corner_deg, segments, segment_m, corner_at)
    chains = _chains([xy], [-1], ["w"], [0])
    corner_s = corner_at * segment_m
    direction = "left" if corner_side > 0 else "right"
    near = [
        c
        for c in chains.curves(0, WARNING_RADIUS_M, DEFAULT_POLICY)
        if c.direction == direction and c.start_s - segment_m / 2.0 <= corner_s <= c.end_s + segment_m / 2.0
    ]
    assert near
    turned_deg = sum(c.angle_deg for c in near)
    # Their stretch's turning that way: the corner and the gentle nodes of that side they reach (or the one beyond).
    turns = polyline_turns(xy)
    sign = 1.0 if direction == "left" else -1.0
    net_deg = math.degrees(turns.net_turn_rad(min(c.start_s for c in near), max(c.end_s for c in near), sign))
    assert corner_deg - ANGLE_TOLERANCE_DEG <= turned_deg <= net_deg + ANGLE_TOLERANCE_DEG


def test_a_vertex_on_the_end_of_a_stretch_counts_only_where_it_turns_the_stretchs_way() -> None:
    # Vertices at 10 m (10 degrees left) and 20 m (20 degrees right): a left curve from 20 m on turns onto the road
    # after the right-turning vertex, which takes nothing off its net turn; one ending at 20 m counts the vertex at
    # 10 m (left) and not the one at its end.
    turns = polyline_turns(_way([0.0, 10.0, -10.0], [10.0, 10.0, 30.0]))
    assert math.isclose(turns.net_turn_rad(20.0, 30.0, 1.0), 0.0, abs_tol=1e-12)
    assert math.isclose(turns.net_turn_rad(12.0, 20.0, 1.0), math.radians(10.0), rel_tol=1e-9)
    assert math.isclose(turns.net_turn_rad(20.0, 30.0, -1.0), math.radians(20.0), rel_tol=1e-9)
    assert math.isclose(turns.net_turn_rad(5.0, 25.0, -1.0), math.radians(10.0), rel_tol=1e-9)
