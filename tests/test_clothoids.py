"""The road model on roads with clothoids: curve ends inside spirals, and the spiral's
curvature points, judged against geometry constructed here (exact curvature at every s)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from builders import dense_shape as curvature_dense_shape
from hypothesis import example, given, settings
from hypothesis import strategies as st

from csws.curvature import find_curves, radius_profile
from csws.geometry import Piece, arc, clothoid, curvature_at, piece_starts_s, straight
from csws.standard import DEFAULT_POLICY, Category, warning_speed

ORIGIN = (1234.0, -567.0)

directions = st.sampled_from(["left", "right"])
headings_rad = st.floats(-math.pi, math.pi)


def dense_shape(pieces, heading_rad: float = 0.0) -> np.ndarray:
    """A SUMO-like shape (:func:`builders.dense_shape`): vertices 0.5 m apart, rounded to the centimetre."""
    return curvature_dense_shape(pieces, 0.5, ORIGIN, heading_rad)


def truth_crossings(pieces, warning_radius_m: float) -> tuple[float, float]:
    """Where the constructed road's radius first falls to R_c and last rises above it, m."""
    s = np.linspace(0.0, piece_starts_s(pieces)[-1], 200_001)
    inside = np.flatnonzero(np.abs(curvature_at(pieces, s)) >= 1.0 / warning_radius_m)
    return float(s[inside[0]]), float(s[inside[-1]])


@pytest.mark.slow
@settings(max_examples=40, deadline=None)
@given(
    st.floats(30.0, 450.0),
    st.floats(20.0, 80.0),
    st.floats(20.0, 80.0),
    st.floats(10.0, 60.0),
    st.floats(1.2, 3.0),
    directions,
    headings_rad,
)
# Short spirals into wide arcs: they move the road only centimetres from a step at their middle, and
# were once taken for that step, which starts the curve (R_c 1.5 R) about 4 m early.
@example(347.0, 20.0, 22.0, 10.0, 1.5, "left", 0.75)
@example(328.0, 20.0, 38.0, 11.0, 1.5, "right", 0.25)
def test_a_curve_between_spirals_starts_and_ends_inside_them(
    radius_m, entry_m, exit_m, arc_deg, warning_factor, direction, heading
) -> None:
    warning_radius_m = warning_factor * radius_m
    arc_deg = max(arc_deg, math.degrees(15.0 / radius_m))  # at least 15 m of arc, as on the arc-only roads
    pieces = [
        straight(150.0),
        clothoid(entry_m, math.inf, radius_m, direction),
        arc(radius_m, arc_deg, direction),
        clothoid(exit_m, radius_m, math.inf, direction),
        straight(150.0),
    ]
    (curve,) = find_curves(dense_shape(pieces, heading), warning_radius_m, policy=DEFAULT_POLICY)
    start_s, end_s = truth_crossings(pieces, warning_radius_m)
    assert abs(curve.start_s - start_s) <= 1.0
    assert abs(curve.end_s - end_s) <= 1.0
    assert curve.min_radius_m == pytest.approx(radius_m, rel=0.02)
    assert curve.direction == direction
    assert not curve.is_multi


@pytest.mark.slow
@settings(max_examples=25, deadline=None)
@given(st.floats(40.0, 250.0), st.floats(30.0, 80.0), directions)
def test_spiral_pieces_are_points_of_the_road_one_km_h_of_warning_speed_apart(radius_m, spiral_m, direction) -> None:
    pieces = [
        straight(100.0),
        clothoid(spiral_m, math.inf, radius_m, direction),
        arc(radius_m, 20.0, direction),
        straight(100.0),
    ]
    (curve,) = find_curves(dense_shape(pieces), 300.0, policy=DEFAULT_POLICY)
    spiral_parts = [part for part in curve.parts if part.spiral]
    assert len(spiral_parts) >= 2
    for part in spiral_parts:
        # The road's radius within a metre of the piece's start (the dense start tolerance).
        nearby_radius_m = 1.0 / np.abs(curvature_at(pieces, part.start_s + np.linspace(-1.0, 1.0, 41)))
        assert 0.98 * nearby_radius_m.min() <= part.radius_m <= 1.02 * nearby_radius_m.max()
    for category in Category:
        for level in (1, 2):
            speeds = [warning_speed(part.radius_m, category, level) for part in curve.parts]
            assert max(np.abs(np.diff(speeds))) <= 1.0 + 1e-6


def test_a_compound_curve_with_spirals_keeps_its_three_arcs() -> None:
    pieces = [
        straight(150.0),
        clothoid(50.0, math.inf, 250.0, "right"),
        arc(250.0, 12.0, "right"),
        clothoid(40.0, 250.0, 90.0, "right"),
        arc(90.0, 25.0, "right"),
        clothoid(30.0, 90.0, 35.0, "right"),
        arc(35.0, 60.0, "right"),
        clothoid(40.0, 35.0, math.inf, "right"),
        straight(150.0),
    ]
    (curve,) = find_curves(dense_shape(pieces), 300.0, policy=DEFAULT_POLICY)
    arcs = [part for part in curve.parts if not part.spiral]
    assert curve.is_multi
    assert [part.radius_m for part in arcs] == pytest.approx([250.0, 90.0, 35.0], rel=0.01)
    starts = piece_starts_s(pieces)
    for part, truth_start in zip(arcs, starts[[2, 4, 6]], strict=False):
        assert abs(part.start_s - truth_start) <= 1.0


def test_an_s_bend_through_one_spiral_is_two_curves_meeting_nowhere() -> None:
    pieces = [
        straight(100.0),
        clothoid(40.0, math.inf, 60.0, "left"),
        arc(60.0, 30.0, "left"),
        Piece(120.0, 1.0 / 60.0, -1.0 / 80.0),  # one clothoid through the inflection
        arc(80.0, 30.0, "right"),
        clothoid(40.0, 80.0, math.inf, "right"),
        straight(100.0),
    ]
    left, right = find_curves(dense_shape(pieces), 300.0, policy=DEFAULT_POLICY)
    assert (left.direction, right.direction) == ("left", "right")
    s = np.linspace(0.0, piece_starts_s(pieces)[-1], 200_001)
    curvature = curvature_at(pieces, s)
    left_end = s[np.flatnonzero(curvature >= 1 / 300.0)[-1]]
    right_start = s[np.flatnonzero(curvature <= -1 / 300.0)[0]]
    assert abs(left.end_s - left_end) <= 1.0
    assert abs(right.start_s - right_start) <= 1.0


def test_the_profile_is_linear_on_a_spiral() -> None:
    pieces = [straight(120.0), clothoid(70.0, math.inf, 120.0, "left"), arc(120.0, 30.0, "left"), straight(120.0)]
    profile = radius_profile(dense_shape(pieces))
    inside = (profile.s > 125.0) & (profile.s < 185.0)
    np.testing.assert_allclose(profile.curvature[inside], curvature_at(pieces, profile.s[inside]), atol=2e-4)
