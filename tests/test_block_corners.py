"""The corners of a block one after another each get a curve of their direction.

A road round a block turns one way at corners tens of metres apart: a 90-degree corner, a corner
cut by two nodes of 44 degrees a few metres apart, another 90-degree corner, a node a few decimetres
before a corner where a junction piece begins. Every polyline here is built from its corners, so the
test knows where each corner vertex lies and which way it turns; the curves are those the curve
index reads (:func:`fit_road_chains`).
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from csws.curvature.artefacts import CORNER_SPAN_M, polyline_turns
from csws.curvature.corners import cut_at_straights
from csws.road.chains import RoadChains, fit_road_chains
from csws.standard import DEFAULT_POLICY

#: The warning curvature radius the curves are found with, m.
WARNING_RADIUS_M = 300.0
#: A curve covers a corner vertex reaching within this of it, or within half the segment beside it, m.
COVER_M = 2.0
#: Corner vertices of this much or more must be covered, degrees.
CORNER_DEG = 30.0


def _unit(heading_deg: float) -> np.ndarray:
    """The unit vector of a heading, degrees anticlockwise from east."""
    return np.array([math.cos(math.radians(heading_deg)), math.sin(math.radians(heading_deg))])


def _block_road(
    turns_deg: list[float], legs_m: list[float], cuts_m: list[float], piece_m: float
) -> tuple[list[np.ndarray], list[tuple[np.ndarray, float]]]:
    """A way along straights ``legs_m`` (one more than corners) joined by corners turning ``turns_deg``; a
    corner with a cut (``cuts_m`` > 0) is drawn by two nodes that far apart turning half of it each; where
    ``piece_m`` > 0, a node lies that far before each corner on its straight (where a junction piece of a
    network begins).

    Returns the way as the one lane of a chain and each corner vertex: its point and its turn, degrees."""
    heading, point = 0.0, np.zeros(2)
    points, corners = [point], []
    for turn_deg, leg_m, cut_m in zip(turns_deg, legs_m, cuts_m, strict=False):
        if piece_m > 0:
            points.append(point + (leg_m - piece_m) * _unit(heading))
        point = point + leg_m * _unit(heading)
        halves = [turn_deg / 2.0, turn_deg / 2.0] if cut_m > 0 else [turn_deg]
        for index, turn_part_deg in enumerate(halves):
            points.append(point)
            corners.append((point, turn_part_deg))
            heading += turn_part_deg
            if index + 1 < len(halves):
                point = point + cut_m * _unit(heading)
    points.append(point + legs_m[-1] * _unit(heading))
    return [np.array(points)], corners


def _chains(lanes: list[np.ndarray]) -> RoadChains:
    """The road chains of ``lanes`` continuing one into the next."""
    count = len(lanes)
    return fit_road_chains(
        np.append(np.arange(1, count), -1),
        lanes,
        np.array([np.hypot(*np.diff(lane, axis=0).T).sum() for lane in lanes]),
        np.zeros(count, dtype=bool),
    )


def _uncovered(lanes: list[np.ndarray], corners: list[tuple[np.ndarray, float]]) -> list[tuple[float, float]]:
    """The corner vertices of the lanes that turn by :data:`CORNER_DEG` or more and that no curve of their
    direction covers, as (x, y): a curve covers a vertex where it reaches within :data:`COVER_M` of it or within
    half the segment beside it (the road turns anywhere on the segments beside a node)."""
    chains = _chains(lanes)
    missed = []
    for point, turn_deg in corners:
        if abs(turn_deg) < CORNER_DEG:
            continue
        direction = "left" if turn_deg > 0 else "right"
        covered = False
        for chain, xy in enumerate(chains.xy):
            at = np.flatnonzero(np.hypot(*(xy - point).T) < 1e-6)
            if len(at) == 0 or at[0] in (0, len(xy) - 1):
                continue
            s = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))))
            vertex = int(at[0])
            before_m, after_m = (max(COVER_M, (s[vertex + k] - s[vertex + k - 1]) / 2.0) for k in (0, 1))
            curves = chains.curves(chain, WARNING_RADIUS_M, DEFAULT_POLICY)
            covered |= any(
                c.direction == direction and c.start_s - after_m <= s[vertex] <= c.end_s + before_m for c in curves
            )
        if not covered:
            missed.append((float(point[0]), float(point[1])))
    return missed


def test_each_corner_of_a_rectangular_loop_with_a_cut_corner_gets_a_curve() -> None:
    # Left round a block: 90 degrees, 60 m, a corner cut by two nodes of 44 degrees 7 m apart, 24 m, 90 degrees;
    # and the other way round; with and without a node 0.3 m before each corner.
    for side in (1.0, -1.0):
        for piece_m in (0.0, 0.3):
            turns = [side * 90.0, side * 88.0, side * 90.0]
            lanes, corners = _block_road(turns, [40.0, 60.0, 24.0, 30.0], [0.0, 7.0, 0.0], piece_m)
            assert _uncovered(lanes, corners) == []


def test_two_right_angles_far_apart_on_one_way_each_get_a_curve() -> None:
    # 7.5 m, 91.7 degrees, 139.5 m, 83.5 degrees, 11.4 m: the two corners turn one way 140 m apart.
    lanes, corners = _block_road([91.7, 83.5], [7.5, 139.5, 11.4], [0.0, 0.0], 0.0)
    assert _uncovered(lanes, corners) == []


def test_a_corner_two_metres_after_a_right_angle_cut_gets_a_curve() -> None:
    # 90 degrees, 71 m, then a corner of 90 cut by two nodes 2.3 m apart, the last 11 m before the end.
    lanes, corners = _block_road([89.2, 90.6], [13.0, 71.0, 11.2], [0.0, 2.3], 0.3)
    assert _uncovered(lanes, corners) == []


@settings(max_examples=30, deadline=None)
@given(st.integers(2, 5), st.sampled_from([-1.0, 1.0]), st.data(), st.sampled_from([0.0, 0.3, 1.0]))
def test_every_corner_of_a_block_road_gets_a_curve_of_its_direction(corners, side, data, piece_m) -> None:
    # Corners of 60-120 degrees one way, straights of more than a corner's span (CORNER_SPAN_M) up to 150 m
    # between them, some corners cut by two nodes 2.5-8 m apart, a node ``piece_m`` before each corner.
    turns = [side * data.draw(st.floats(60.0, 120.0)) for _ in range(corners)]
    between = [data.draw(st.floats(CORNER_SPAN_M + 1.0, 150.0)) for _ in range(corners - 1)]
    legs = [data.draw(st.floats(12.0, 150.0)), *between, data.draw(st.floats(12.0, 150.0))]
    cuts = [data.draw(st.sampled_from([0.0, 0.0, 1.0])) * data.draw(st.floats(2.5, 8.0)) for _ in range(corners)]
    lanes, vertices = _block_road(turns, legs, cuts, piece_m)
    assert _uncovered(lanes, vertices) == []


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(0.1, 120.0), min_size=1, max_size=12), st.floats(5.0, 80.0))
def test_a_run_of_vertices_is_cut_at_its_straights_only(segments_m, longest_m) -> None:
    vertex_s = np.concatenate(([0.0], np.cumsum(segments_m)))
    between_m = np.diff(vertex_s)
    pieces = cut_at_straights(0, len(vertex_s) - 1, vertex_s, longest_m)
    # The pieces cover the run in order; each cut is a segment longer than ``longest_m``, and no piece holds one.
    assert pieces[0][0] == 0 and pieces[-1][1] == len(vertex_s) - 1
    for (_, last), (first, _) in zip(pieces[:-1], pieces[1:], strict=True):
        assert first == last + 1 and between_m[last] > longest_m
    assert all(max(between_m[first:last], default=0.0) <= longest_m for first, last in pieces)
    assert len(pieces) == 1 + int(np.count_nonzero(between_m > longest_m))


def test_the_corners_of_a_block_are_found_apart() -> None:
    # The turns alone: three corners far apart turning one way are three corners, not none.
    lanes, corners = _block_road([90.0, 90.0, 90.0], [30.0, 80.0, 70.0, 30.0], [0.0, 0.0, 0.0], 0.0)
    found = polyline_turns(lanes[0]).corners()
    assert [round(math.degrees(c.turn_rad)) for c in found] == [90, 90, 90]
    assert all(c.end_s - c.start_s <= CORNER_SPAN_M for c in found)
