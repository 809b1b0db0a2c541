"""Radius profiles and curves (3.4-3.8) against geometry built exactly with csws.geometry."""

from __future__ import annotations

import math

import numpy as np
import pytest
from builders import dense_shape
from hypothesis import given, settings
from hypothesis import strategies as st

from csws.curvature import (
    curves_from_profile,
    find_curves,
    radius_profile,
    radius_profiles,
    three_point_radius,
)
from csws.geometry import arc, piece_starts_s, pose_at, sample_pieces, straight
from csws.standard import DEFAULT_POLICY

#: Warning radius used on arcs up to 500 m, so that every one of them is a curve, m.
WIDE_WARNING_RADIUS_M = 1000.0

radii_m = st.floats(25.0, 500.0)
headings_rad = st.floats(-math.pi, math.pi)
origins_m = st.tuples(st.floats(-5000.0, 5000.0), st.floats(-5000.0, 5000.0))
directions = st.sampled_from(["left", "right"])
seeds = st.integers(0, 2**32 - 1)


def sparse_way(pieces, seed, origin, heading_rad, noise_rms_m):
    """A map-like way: nodes 5-30 m apart at irregular arc lengths, with isotropic noise."""
    rng = np.random.default_rng(seed)
    length_m = piece_starts_s(pieces)[-1]
    s = np.concatenate(([0.0], np.cumsum(rng.uniform(5.0, 30.0, size=int(length_m / 5.0) + 2))))
    s = np.append(s[s < length_m], length_m)
    x, y, _ = pose_at(pieces, s, origin, heading_rad)
    return np.column_stack((x, y)) + rng.normal(0.0, noise_rms_m / math.sqrt(2.0), size=(len(s), 2))


def only_curve(xy, warning_radius_m=WIDE_WARNING_RADIUS_M):
    curves = find_curves(xy, warning_radius_m, policy=DEFAULT_POLICY)
    assert len(curves) == 1, curves
    return curves[0]


@settings(max_examples=50, deadline=None)
@given(radii_m, st.floats(20.0, 120.0), directions, st.floats(0.5, 1.0), origins_m, headings_rad)
def test_dense_arc_is_one_curve_with_its_radius_start_and_end(
    radius_m, angle_deg, direction, spacing_m, origin, heading
):
    angle_deg = max(angle_deg, math.degrees(15.0 / radius_m))  # at least 15 m of arc
    pieces = [straight(80.0), arc(radius_m, angle_deg, direction), straight(60.0)]
    curve = only_curve(dense_shape(pieces, spacing_m, origin, heading))
    start_s, end_s = piece_starts_s(pieces)[1:3]
    assert curve.min_radius_m == pytest.approx(radius_m, rel=0.02)
    assert abs(curve.start_s - start_s) <= 1.0
    assert abs(curve.end_s - end_s) <= 1.0
    assert curve.angle_deg == pytest.approx(angle_deg, abs=1.0)
    assert curve.direction == direction
    assert not curve.is_multi


@settings(max_examples=40, deadline=None)
@given(st.floats(60.0, 250.0), directions, seeds, origins_m, headings_rad)
def test_sparse_exact_arc_is_found_within_sparse_tolerances(radius_m, direction, seed, origin, heading):
    angle_deg = max(40.0, math.degrees(150.0 / radius_m))  # at least 150 m of arc: several nodes on it
    pieces = [straight(120.0), arc(radius_m, min(angle_deg, 150.0), direction), straight(120.0)]
    curve = only_curve(sparse_way(pieces, seed, origin, heading, noise_rms_m=0.0), warning_radius_m=300.0)
    assert curve.min_radius_m == pytest.approx(radius_m, rel=0.03)
    assert abs(curve.start_s - 120.0) <= 4.0
    assert curve.direction == direction


def mapped_way(pieces, seed, origin, heading_rad, noise_rms_m):
    """A sparse way drawn as mappers draw one: nodes 5-30 m apart, but closer on an arc,
    so that no node gap on it exceeds a third of its length nor half its radius."""
    rng = np.random.default_rng(seed)
    starts = piece_starts_s(pieces)
    s = [0.0]
    while s[-1] < starts[-1]:
        gap = float(rng.uniform(5.0, 30.0))
        for first, end, piece in zip(starts[:-1], starts[1:], pieces, strict=False):
            if piece.curvature and s[-1] < end and s[-1] + gap > first:
                gap *= min(30.0, piece.length_m / 3.0, piece.radius_m / 2.0) / 30.0
        s.append(s[-1] + gap)
    s = np.append(s[:-1], starts[-1])
    x, y, _ = pose_at(pieces, s, origin, heading_rad)
    return np.column_stack((x, y)) + rng.normal(0.0, noise_rms_m / math.sqrt(2.0), size=(len(s), 2))


def test_mapped_noisy_arcs_meet_the_sparse_targets():
    """0.5 m noise on nodes 5-30 m apart: every arc is found turning its way and starts
    within 5 m (the target); the median radius error is well within 5 %."""
    rng = np.random.default_rng(91)
    radius_errors, start_errors = [], []
    for _ in range(60):
        radius_m = float(np.exp(rng.uniform(np.log(25.0), np.log(500.0))))
        direction = str(rng.choice(["left", "right"]))
        pieces = [straight(150.0), arc(radius_m, float(rng.uniform(20.0, 120.0)), direction), straight(150.0)]
        origin = (float(rng.uniform(-5000, 5000)), float(rng.uniform(-5000, 5000)))
        xy = mapped_way(pieces, int(rng.integers(2**32)), origin, float(rng.uniform(-3, 3)), 0.5)
        curves = find_curves(xy, WIDE_WARNING_RADIUS_M, policy=DEFAULT_POLICY)
        end_s = 150.0 + pieces[1].length_m
        overlap = [min(c.end_s, end_s) - max(c.start_s, 150.0) for c in curves]
        assert curves and max(overlap) > 0
        curve = curves[int(np.argmax(overlap))]
        assert curve.direction == direction
        radius_errors.append(abs(curve.min_radius_m / radius_m - 1.0))
        start_errors.append(abs(curve.start_s - 150.0))
    assert np.median(radius_errors) <= 0.02
    assert np.percentile(radius_errors, 80) <= 0.05
    assert np.median(start_errors) <= 1.5
    assert np.percentile(start_errors, 80) <= 3.0
    assert max(start_errors) <= 5.0


@pytest.mark.slow
def test_exact_map_ways_give_their_arcs_exactly():
    """Without noise, the road fitted to a map way's nodes is the road: the model (straights
    and arcs joined without kinks) is exact, so start and radius come out exact but for
    gentle arcs, whose start the nodes pin down least and where the fit stops within
    centimetres of it (longer steps carry it along the valley their start and end make)."""
    rng = np.random.default_rng(93)
    start_errors, radius_errors = [], []
    for _ in range(80):
        radius_m = float(np.exp(rng.uniform(np.log(25.0), np.log(500.0))))
        pieces = [
            straight(120.0),
            arc(radius_m, float(rng.uniform(20.0, 120.0)), str(rng.choice(["left", "right"]))),
            straight(120.0),
        ]
        xy = mapped_way(pieces, int(rng.integers(2**32)), (1000.0, -2000.0), float(rng.uniform(-3, 3)), 0.0)
        curve = only_curve(xy)
        start_errors.append(abs(curve.start_s - 120.0))
        radius_errors.append(abs(curve.min_radius_m / radius_m - 1.0))
    assert np.median(start_errors) <= 0.01
    assert np.percentile(start_errors, 95) <= 0.05
    assert max(start_errors) <= 0.1
    assert np.median(radius_errors) <= 1e-9
    assert np.percentile(radius_errors, 95) <= 1e-6
    assert max(radius_errors) <= 1e-4


@pytest.mark.parametrize(("radius_m", "angle_deg", "seed"), [(53.4, 32.7, 17), (73.4, 22.7, 88)])
def test_a_short_noisy_arc_is_not_taken_for_a_sharper_shorter_one(radius_m, angle_deg, seed):
    """The few noisy nodes on a 30 m arc (0.5 m noise) can fit a sharp arc of half its
    length nearly as well; the heading fit may pick that one, so the polish also starts
    from the curve stretched and shrunk and keeps the road closest to the nodes, which
    here is the one that starts near the arc (each was found 6-14 m off before)."""
    pieces = [straight(80.0), arc(radius_m, angle_deg, "left"), straight(120.0)]
    curve = only_curve(mapped_way(pieces, seed, (300.0, 700.0), 0.4, 0.5))
    assert abs(curve.start_s - 80.0) <= 5.0
    assert curve.min_radius_m == pytest.approx(radius_m, rel=0.3)


@pytest.mark.parametrize("seed", range(12))
def test_a_sharp_short_arc_between_closely_mapped_nodes_is_found_where_it_starts(seed):
    """A map way with nodes 1-3 m apart around a 9 m arc of R = 26 m (0.5 m noise): chords
    that short have headings that are mostly noise, so the way is fitted as a map way,
    and the curve starts near the arc, not at the way's start."""
    pieces = [straight(60.0), arc(26.0, 20.0, "left"), straight(120.0)]
    curves = find_curves(mapped_way(pieces, seed, (300.0, 700.0), 0.4, 0.5), policy=DEFAULT_POLICY)
    assert len(curves) == 1
    assert abs(curves[0].start_s - 60.0) <= 15.0
    assert curves[0].direction == "left"


@pytest.mark.parametrize(
    "gentle_m, gentle_deg, sharp_m, sharp_deg", [(120.0, 30.0, 40.0, 25.0), (180.0, 20.0, 35.0, 30.0)]
)
def test_a_compound_curve_on_noisy_mapped_nodes_keeps_its_sharper_arc(gentle_m, gentle_deg, sharp_m, sharp_deg):
    """A compound curve (3.8) whose sharper arc is short, mapped with 0.3 m noise: its few
    nodes fit one arc of a mean radius nearly as well, so the polish also tries the
    longest curve cut into two arcs. In at least half of 40 ways the curve is one, with
    its smallest radius within 15 % of the sharper arc's (one arc of a mean radius made
    that 3-7 of 40; the Cramér-Rao bound of that radius is about 10 %)."""
    pieces = [straight(120.0), arc(gentle_m, gentle_deg, "left"), arc(sharp_m, sharp_deg, "left"), straight(120.0)]
    kept = 0
    for seed in range(40):
        curves = find_curves(
            mapped_way(pieces, seed, (100.0, -50.0), 0.7, 0.3), WIDE_WARNING_RADIUS_M, policy=DEFAULT_POLICY
        )
        kept += len(curves) == 1 and abs(curves[0].min_radius_m / sharp_m - 1.0) < 0.15
    assert kept >= 20


def test_a_curve_ending_inside_a_way_s_last_segment_is_kept():
    """The nodes of a sparse way (Douglas-Peucker at 1-2 m, 0.5 m noise) of 150 m straight,
    an arc of R 126.8 m turning 56.4 degrees (with a node inside it) and 150 m straight:
    the arc ends inside the last segment, which tells only its own direction. An arc
    taken past the last node that overshoots and a reverse arc within the segment fit it
    as well as the truth; that curve turned more than the way and was dropped whole."""
    pieces = [straight(150.0), arc(1.0 / 0.007886547676816897, 56.4, "left"), straight(150.0)]
    nodes = np.array(
        [
            [-0.14, 0.51],
            [158.94, 0.07],
            [185.72, 5.51],
            [210.07, 14.45],
            [231.73, 30.25],
            [232.25, 30.84],
            [249.86, 49.52],
            [338.38, 182.1],
        ]
    )
    curve = only_curve(nodes)
    assert abs(curve.start_s - piece_starts_s(pieces)[1]) <= 3.0
    assert curve.angle_deg == pytest.approx(56.4, abs=5.0)
    assert curve.min_radius_m == pytest.approx(pieces[1].radius_m, rel=0.05)


def test_sparse_noisy_straights_rarely_show_a_curve():
    rng = np.random.default_rng(92)
    ways = [
        sparse_way(
            [straight(float(rng.uniform(50.0, 1500.0)))],
            int(rng.integers(2**32)),
            (0.0, 0.0),
            float(rng.uniform(-3, 3)),
            0.5,
        )
        for _ in range(60)
    ]
    assert sum(len(find_curves(xy, policy=DEFAULT_POLICY)) for xy in ways) == 0


def _lane_of_reverse_curve_bump(lane_offset_m, reverse):
    """One lane of a two-way road over a reverse-curve bump (R = 250 m arcs turning
    20, 40 and 20 degrees between 430 m straights), half a lane right of the centreline,
    as netconvert lays lanes out: offsetting an arc to the right makes its radius larger
    on a left turn and smaller on a right turn, by the offset exactly. Returns the lane's
    pieces."""
    turns = [("left", 20.0), ("right", 40.0), ("left", 20.0)]
    flip = {"left": "right", "right": "left"}
    if reverse:
        turns = [(flip[direction], angle) for direction, angle in reversed(turns)]
    arcs = [arc(250.0 + (lane_offset_m if d == "left" else -lane_offset_m), a, d) for d, a in turns]
    return [straight(430.0), *arcs, straight(430.0)]


@pytest.mark.parametrize("reverse", [False, True])
@pytest.mark.parametrize("spacing_m", [2.0, 5.0, 10.0])
def test_offset_lanes_of_a_reverse_curve_are_three_curves_of_their_own_radii(reverse, spacing_m):
    pieces = _lane_of_reverse_curve_bump(1.6, reverse)
    xy = dense_shape(pieces, spacing_m, (3120.0, 870.0), 0.7)
    curves = find_curves(xy, policy=DEFAULT_POLICY)
    assert [len(c.parts) for c in curves] == [1, 1, 1]
    truth_s = piece_starts_s(pieces)
    for curve, piece, start_s in zip(curves, pieces[1:4], truth_s[1:4], strict=False):
        assert curve.min_radius_m == pytest.approx(piece.radius_m, rel=0.005)
        assert curve.direction == ("left" if piece.curvature > 0 else "right")
        assert abs(curve.start_s - start_s) <= 1.0


@settings(max_examples=30, deadline=None)
@given(st.floats(30.0, 250.0), st.floats(30.0, 90.0), directions, origins_m, headings_rad)
def test_s_bend_is_two_curves_turning_opposite_ways(radius_m, angle_deg, first_direction, origin, heading):
    second_direction = "right" if first_direction == "left" else "left"
    pieces = [
        straight(60.0),
        arc(radius_m, angle_deg, first_direction),
        arc(radius_m, angle_deg, second_direction),
        straight(60.0),
    ]
    first, second = find_curves(dense_shape(pieces, 0.8, origin, heading), policy=DEFAULT_POLICY)
    assert (first.direction, second.direction) == (first_direction, second_direction)
    assert abs(second.start_s - first.end_s) <= 1.0
    assert abs(first.end_s - piece_starts_s(pieces)[2]) <= 1.0
    assert first.min_radius_m == pytest.approx(radius_m, rel=0.01)
    assert second.min_radius_m == pytest.approx(radius_m, rel=0.01)


@settings(max_examples=30, deadline=None)
@given(
    st.sampled_from([(200.0, 40.0, 70.0), (120.0, 15.0, 35.0)]),
    st.floats(0.0, 1.0),
    st.floats(28.0, 60.0),
    directions,
    origins_m,
    headings_rad,
)
def test_standard_multi_curve_is_one_curve_with_a_sharp_step(first, where, length_2_m, direction, origin, heading):
    radius_1_m, shortest_m, longest_m = first
    length_1_m = shortest_m + where * (longest_m - shortest_m)
    pieces = [
        straight(100.0),
        arc(radius_1_m, math.degrees(length_1_m / radius_1_m), direction),
        arc(40.0, math.degrees(length_2_m / 40.0), direction),
        straight(80.0),
    ]
    curve = only_curve(dense_shape(pieces, 0.7, origin, heading), warning_radius_m=300.0)
    assert curve.is_multi and len(curve.parts) == 2
    assert curve.parts[0].radius_m == pytest.approx(radius_1_m, rel=0.05)
    assert curve.parts[1].radius_m == pytest.approx(40.0, rel=0.01)
    assert abs(curve.parts[1].start_s - piece_starts_s(pieces)[2]) <= 1.0
    assert curve.min_radius_m == curve.parts[1].radius_m


def test_profile_vertex_values_come_from_its_parts():
    pieces = [straight(50.0), arc(100.0, 45.0, "right"), straight(50.0)]
    xy, true_s = sample_pieces(pieces, 1.0)
    profile = radius_profile(np.round(xy, 2))
    assert profile.s[0] == 0.0 and profile.s == pytest.approx(true_s, abs=0.05)
    on_arc = (true_s > 55.0) & (true_s < 120.0)
    assert profile.curvature[on_arc] == pytest.approx(-0.01, rel=0.01)
    with np.errstate(divide="ignore"):
        assert profile.radius == pytest.approx(1.0 / np.abs(profile.curvature))
    assert profile.parts[0].start_s == 0.0 and profile.parts[-1].end_s == profile.s[-1]
    assert curves_from_profile(profile, policy=DEFAULT_POLICY)[0].direction == "right"


@pytest.mark.slow
@settings(max_examples=300, deadline=None)
@given(
    st.lists(st.tuples(st.floats(3.0, 60.0), st.floats(-1.6, 1.6)), min_size=4, max_size=14),
    st.floats(0.0, 2.0),
    seeds,
)
def test_sparse_profile_parts_tile_the_polyline(steps, noise_rms_m, seed):
    """Any map-like way, however short, bent or noisy (nodes 3-60 m apart turning up to
    90 degrees each): its parts run from 0 to its end without gaps, none without length."""
    heading = np.cumsum([turn for _, turn in steps])
    step = np.array([length for length, _ in steps]) * np.exp(1j * heading)
    xy = np.concatenate(([0.0], np.cumsum(step)))
    xy = np.column_stack((xy.real, xy.imag)) + np.random.default_rng(seed).normal(0.0, noise_rms_m / 2.0, (len(xy), 2))
    profile = radius_profile(xy)
    starts = np.array([p.start_s for p in profile.parts])
    ends = np.array([p.end_s for p in profile.parts])
    assert starts[0] == 0.0 and ends[-1] == pytest.approx(profile.s[-1])
    assert np.all(ends > starts) and np.array_equal(starts[1:], ends[:-1])
    assert np.all(np.isfinite([p.curvature for p in profile.parts]))


def test_many_polylines_give_the_profiles_of_each_alone():
    rng = np.random.default_rng(7)
    polylines = [
        dense_shape([straight(30.0), arc(60.0, 70.0, "left"), straight(30.0)], 0.6, (10.0, 20.0), 0.4),
        np.empty((0, 2)),
        sparse_way([straight(100.0), arc(150.0, 60.0, "right"), straight(100.0)], 3, (0.0, 0.0), 1.0, 0.5),
        np.array([[1.0, 1.0]]),
        rng.normal(size=(5, 2)),
    ]
    together = radius_profiles(polylines)
    for polyline, profile in zip(polylines, together, strict=False):
        alone = radius_profile(polyline)
        assert len(profile.parts) == len(alone.parts)
        for part, part_alone in zip(profile.parts, alone.parts, strict=False):
            assert (part.start_s, part.end_s, part.curvature) == pytest.approx(
                (part_alone.start_s, part_alone.end_s, part_alone.curvature), rel=1e-9, abs=1e-12
            )
        np.testing.assert_allclose(profile.curvature, alone.curvature, rtol=1e-9, atol=1e-12)


def test_sparse_ways_fitted_together_give_the_profiles_of_each_alone():
    """Sparse ways are fitted in batches (padded to a common chord count, knots padded to
    the batch's most): ways of different lengths, curves and noise must not affect each other."""
    rng = np.random.default_rng(11)
    ways = [
        mapped_way(
            [
                straight(float(rng.uniform(20.0, 120.0))),
                arc(float(rng.uniform(30.0, 300.0)), float(rng.uniform(20.0, 90.0)), direction),
                straight(float(rng.uniform(20.0, 120.0))),
            ],
            int(rng.integers(2**32)),
            (0.0, 0.0),
            float(rng.uniform(-3, 3)),
            float(rng.uniform(0.0, 0.5)),
        )
        for direction in ["left", "right"] * 8
    ]
    assert len({len(xy) for xy in ways}) > 4  # several chord counts, some sharing a batch
    for way, profile in zip(ways, radius_profiles(ways), strict=False):
        alone = radius_profile(way)
        assert len(profile.parts) == len(alone.parts)
        for part, part_alone in zip(profile.parts, alone.parts, strict=False):
            assert (part.start_s, part.end_s, part.curvature) == pytest.approx(
                (part_alone.start_s, part_alone.end_s, part_alone.curvature), rel=1e-6, abs=1e-9
            )


@pytest.mark.parametrize("xy", [np.empty((0, 2)), [], np.array([[3.0, 4.0]]), np.array([[3.0, 4.0]] * 5)])
def test_polylines_without_length_give_a_straight_profile(xy):
    profile = radius_profile(xy)
    count = len(np.asarray(xy))
    assert profile.parts == ()
    assert profile.s.shape == profile.curvature.shape == profile.radius.shape == (count,)
    assert np.all(profile.s == 0.0) and np.all(profile.curvature == 0.0) and np.all(np.isinf(profile.radius))
    assert find_curves(xy, policy=DEFAULT_POLICY) == []


def test_repeated_vertices_are_ignored():
    xy = dense_shape([straight(40.0), arc(50.0, 90.0, "left"), straight(40.0)], 0.8, (0.0, 0.0), 0.0)
    doubled = np.repeat(xy, 2, axis=0)
    profile, with_repeats = radius_profile(xy), radius_profile(doubled)
    assert with_repeats.parts == profile.parts
    np.testing.assert_array_equal(with_repeats.s[::2], profile.s)
    np.testing.assert_array_equal(with_repeats.s[1::2], profile.s)


def test_two_points_are_a_straight():
    profile = radius_profile(np.array([[0.0, 0.0], [10.0, 0.0]]))
    assert [(p.start_s, p.end_s, p.curvature) for p in profile.parts] == [(0.0, 10.0, 0.0)]


@pytest.mark.parametrize(
    "xy, message",
    [
        (np.array([[0.0, 0.0], [np.nan, 1.0]]), "NaN or infinite"),
        (np.array([[0.0, 0.0], [np.inf, 1.0]]), "NaN or infinite"),
        (np.zeros((4, 3)), "shape"),
        (np.zeros(4), "shape"),
        ([["a", "b"]], "array of numbers"),
    ],
)
def test_bad_input_raises_a_clear_value_error(xy, message):
    with pytest.raises(ValueError, match=message):
        radius_profile(xy)


def test_bad_polyline_in_a_batch_is_named():
    with pytest.raises(ValueError, match="polyline 1"):
        radius_profiles([np.zeros((2, 2)), np.array([[0.0, np.nan]])])


def test_warning_radius_must_be_positive():
    with pytest.raises(ValueError, match="warning radius"):
        find_curves(np.array([[0.0, 0.0], [1.0, 0.0]]), warning_radius_m=0.0, policy=DEFAULT_POLICY)


def test_three_point_radius_is_exact_on_a_circle_and_inf_at_ends():
    angle = np.linspace(0.0, 1.0, 9)
    xy = 80.0 * np.column_stack((np.cos(angle), np.sin(angle)))
    radius = three_point_radius(xy)
    assert np.isinf(radius[[0, -1]]).all()
    assert radius[1:-1] == pytest.approx(80.0)
    assert np.isinf(three_point_radius(np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]))[1])
