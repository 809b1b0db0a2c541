"""Map ways kept to what their nodes can say: a physical radius floor, no angle beyond the
polyline's turning, and a radius for a corner mapped by one node. Ways are built here."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from csws.curvature import find_curves
from csws.curvature.corners import ANGLE_TOLERANCE_DEG, CORNER_DEVIATION_M, FLOOR_RADIUS_M
from csws.geometry import arc, pose_at, straight
from csws.standard import DEFAULT_POLICY


def _way(headings_deg: list[float], lengths_m: list[float]) -> np.ndarray:
    """A polyline from the origin along segments of the given headings and lengths."""
    steps = [
        length * np.array([math.cos(math.radians(h)), math.sin(math.radians(h))])
        for h, length in zip(headings_deg, lengths_m, strict=False)
    ]
    return np.concatenate(([[0.0, 0.0]], np.cumsum(steps, axis=0)))


def _turning_deg(xy: np.ndarray) -> np.ndarray:
    step = np.diff(xy, axis=0)
    heading = np.arctan2(step[:, 1], step[:, 0])
    return np.degrees(np.remainder(np.diff(heading) + math.pi, 2 * math.pi) - math.pi)


def test_a_right_angle_corner_of_one_node_is_one_curve_at_or_above_the_floor() -> None:
    xy = _way([0.0, 90.0], [100.0, 100.0])
    (curve,) = find_curves(xy, 300.0, policy=DEFAULT_POLICY)
    assert curve.min_radius_m >= FLOOR_RADIUS_M
    # The largest arc through the node leaving the segments by the mapping tolerance at most.
    assert curve.min_radius_m <= max(FLOOR_RADIUS_M, CORNER_DEVIATION_M / (1 - math.cos(math.radians(45.0)))) + 1e-9
    assert abs(curve.angle_deg - 90.0) <= ANGLE_TOLERANCE_DEG
    assert curve.direction == "left"
    assert curve.start_s < 100.0 < curve.end_s


def test_a_corner_on_a_mapped_way_with_nodes_on_its_straights() -> None:
    xy = _way([0.0] * 4 + [-60.0] * 4, [25.0] * 8)
    (curve,) = find_curves(xy, 300.0, policy=DEFAULT_POLICY)
    assert curve.direction == "right"
    assert FLOOR_RADIUS_M <= curve.min_radius_m
    assert curve.angle_deg <= 60.0 + ANGLE_TOLERANCE_DEG
    assert curve.start_s < 100.0 < curve.end_s


def test_a_junction_stub_of_a_few_metres_is_given_the_floor() -> None:
    xy = _way([0.0, 73.0], [0.8, 1.8])  # netconvert's stubs at junctions: 2.6 m turning 73 degrees
    curves = find_curves(xy, 300.0, policy=DEFAULT_POLICY)
    assert all(curve.min_radius_m >= FLOOR_RADIUS_M for curve in curves)


@pytest.mark.slow
@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(-120.0, 120.0), min_size=3, max_size=12),
    st.lists(st.floats(5.0, 40.0), min_size=13, max_size=13),
    st.integers(0, 2**32 - 1),
)
def test_no_way_gets_a_radius_below_the_floor_or_a_curve_beyond_its_turning(turns_deg, lengths_m, seed) -> None:
    headings = np.concatenate(([0.0], np.cumsum(turns_deg)))
    xy = _way(list(headings), lengths_m[: len(headings)])
    xy = xy + np.random.default_rng(seed).normal(0.0, 0.3, xy.shape)
    turning_deg = _turning_deg(xy)
    for curve in find_curves(xy, 300.0, policy=DEFAULT_POLICY):
        assert curve.min_radius_m >= FLOOR_RADIUS_M - 1e-9
        # No curve turns its way by more than all the polyline's turns that way together.
        same_way_deg = np.clip(turning_deg if curve.direction == "left" else -turning_deg, 0.0, None).sum()
        assert curve.angle_deg <= same_way_deg + ANGLE_TOLERANCE_DEG


def _mapped_arc_way(seed: int) -> tuple[np.ndarray, float]:
    """A mapped way of a straight-arc-straight road (R 80-200 m turning 60-110 degrees, nodes
    15-25 m apart, one a few metres past the arc's end, 0.5 m RMS node noise) and where its
    arc starts, m."""
    rng = np.random.default_rng(seed)
    pieces = [straight(120.0), arc(float(rng.uniform(80, 200)), float(rng.uniform(60, 110)), "right"), straight(150.0)]
    arc_start_m, arc_end_m = 120.0, 120.0 + pieces[1].length_m
    s = list(np.arange(0.0, arc_end_m, 1.0)[:: int(rng.integers(15, 26))]) + [arc_end_m + float(rng.uniform(3, 8))]
    s += list(np.arange(s[-1] + 20.0, arc_end_m + 150.0, 20.0))
    x, y, _ = pose_at(pieces, np.array(s))
    return np.column_stack((x, y)) + rng.normal(0.0, 0.5 / math.sqrt(2.0), (len(s), 2)), arc_start_m


def test_node_noise_at_a_curve_s_end_segments_does_not_move_its_start() -> None:
    # The nodes' turning, measured between two noisy segments, may fall a few degrees short
    # of the arc's: the curve keeps where the fit put it rather than being redrawn from the
    # vertices' turns.
    for seed in range(20):
        xy, arc_start_m = _mapped_arc_way(seed)
        curves = [curve for curve in find_curves(xy, 300.0, policy=DEFAULT_POLICY) if curve.angle_deg >= 20.0]
        assert len(curves) == 1, seed
        assert abs(curves[0].start_s - arc_start_m) <= 6.0, (seed, curves[0].start_s, arc_start_m)


@given(st.integers(0, 2**32 - 1), st.floats(0.3, 1.0))
def test_a_short_last_segment_on_a_straight_way_is_no_corner(seed, last_m) -> None:
    # A segment not much longer than its ends' noise has no heading: the turn onto it is noise.
    rng = np.random.default_rng(seed)
    s = np.append(np.cumsum(rng.uniform(5.0, 30.0, 30)), 0.0)
    s[-1] = s[-2] + last_m
    xy = np.column_stack((s, np.zeros(len(s)))) + rng.normal(0.0, 0.5 / math.sqrt(2.0), (len(s), 2))
    assert [curve for curve in find_curves(xy, 300.0, policy=DEFAULT_POLICY) if curve.angle_deg >= 20.0] == []
