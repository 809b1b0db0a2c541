"""Map artefacts are no curves, corners and hairpins are: constructed polylines through the road chains' fit.

Every polyline is built here from headings and lengths or points on a circle, so its net
turn is known exactly; the curves are those the curve index reads (:func:`fit_road_chains`).
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st

from csws.curvature import Curve, find_curves
from csws.curvature.artefacts import polyline_turns
from csws.curvature.corners import ANGLE_TOLERANCE_DEG, FLOOR_RADIUS_M
from csws.road.chains import fit_road_chains
from csws.standard import DEFAULT_POLICY

#: The warning curvature radius the curves are found with, m.
WARNING_RADIUS_M = 300.0


def _curves(*lanes: np.ndarray) -> list[Curve]:
    """The curves of one road chain made of ``lanes`` in driving order."""
    count = len(lanes)
    chains = fit_road_chains(
        np.append(np.arange(1, count), -1),
        list(lanes),
        np.array([np.hypot(*np.diff(lane, axis=0).T).sum() for lane in lanes]),
        np.zeros(count, dtype=bool),
    )
    assert len(chains.lanes) == 1
    return chains.curves(0, WARNING_RADIUS_M, DEFAULT_POLICY)


def _way(headings_deg: list[float], lengths_m: list[float]) -> np.ndarray:
    """A polyline from the origin along segments of the given headings and lengths."""
    steps = [
        length * np.array([math.cos(math.radians(h)), math.sin(math.radians(h))])
        for h, length in zip(headings_deg, lengths_m, strict=True)
    ]
    return np.concatenate(([[0.0, 0.0]], np.cumsum(steps, axis=0)))


def _dense(xy: np.ndarray, step_m: float = 1.0) -> np.ndarray:
    """The polyline resampled every ``step_m`` along its segments, its vertices kept, coordinates to the centimetre."""
    points = [xy[0]]
    for a, b in zip(xy[:-1], xy[1:], strict=True):
        count = max(int(np.hypot(*(b - a)) / step_m), 1)
        points += [a + (b - a) * k / count for k in range(1, count + 1)]
    return np.round(np.array(points), 2)


def test_a_spike_of_a_decimetre_on_a_straight_is_no_curve_and_one_artefact() -> None:
    for xy in (
        np.array([[0.0, 0.0], [60.0, 0.0], [60.1, 0.0], [60.0, 0.0], [130.0, 0.0]]),
        _dense(np.array([[0.0, 0.0], [60.0, 0.0], [60.1, 0.0], [60.0, 0.0], [130.0, 0.0]])),
        np.array([[0.0, 0.0], [30.0, 0.0], [60.0, 0.0], [59.9, 0.02], [60.0, 0.0], [95.0, 0.0], [130.0, 0.0]]),
    ):
        assert _curves(xy) == []
        (artefact,) = polyline_turns(xy).artefacts
        assert artefact.kind == "spike"
        assert abs(artefact.start_s - 60.0) <= 0.2


def test_a_junction_lane_that_folds_back_gives_no_floor_curve() -> None:
    # A lane ends; the junction shape runs 3 m back beside it and forward again onto the next road.
    lane = _dense(np.array([[0.0, 0.0], [80.0, 0.0]]))
    junction = np.array([[80.0, 0.0], [77.0, 0.2], [82.0, 0.4], [90.0, 0.4]])
    following = _dense(np.array([[90.0, 0.4], [170.0, 0.4]]))
    curves = _curves(lane, junction, following)
    assert [curve for curve in curves if curve.min_radius_m <= FLOOR_RADIUS_M + 1.0] == []
    assert all(curve.angle_deg < 20.0 for curve in curves)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(8, 20), st.floats(8.0, 25.0))
def test_a_zig_zag_netting_five_degrees_gives_no_curve_of_twenty(seed: int, count: int, segment_m: float) -> None:
    # Headings alternating about the road's by 1-10 degrees (turns of 2-20 degrees), from 0 to a last one of +5.
    rng = np.random.default_rng(seed)
    swings_deg = rng.uniform(1.0, 10.0, count) * np.where(np.arange(count) % 2 == 0, 1.0, -1.0)
    headings = np.concatenate(([0.0], swings_deg, [5.0]))
    xy = _way(list(headings), [60.0] + [segment_m] * (len(headings) - 2) + [60.0])
    assert [curve.angle_deg for curve in _curves(xy) if curve.angle_deg >= 20.0] == []


def _hairpin(radius_m: float, angle_deg: float, nodes: int) -> tuple[np.ndarray, float, float]:
    """Straight, a hairpin arc drawn by ``nodes`` nodes on it (its two tangent points among them), straight;
    and the arc's start and end along the polyline, m."""
    centre_angle = np.radians(np.linspace(0.0, angle_deg, nodes))
    arc_xy = np.column_stack((radius_m * np.sin(centre_angle), radius_m * (1.0 - np.cos(centre_angle))))
    out = np.array([math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))])
    xy = np.vstack(([[-80.0, 0.0]], arc_xy, [arc_xy[-1] + 80.0 * out]))
    s = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))))
    return xy, float(s[1]), float(s[nodes])


@settings(max_examples=60, deadline=None)
@given(st.integers(2, 4), st.floats(8.0, 25.0), st.floats(150.0, 180.0))
def test_a_hairpin_mapped_by_two_to_four_nodes_is_one_curve_of_its_turn(nodes, radius_m, angle_deg) -> None:
    xy, first_node_s, last_node_s = _hairpin(radius_m, angle_deg, nodes)
    turn_deg = math.degrees(float(polyline_turns(xy).turn_rad.sum()))
    (curve,) = [curve for curve in _curves(xy) if curve.angle_deg >= 20.0]
    assert abs(curve.angle_deg - abs(turn_deg)) <= ANGLE_TOLERANCE_DEG
    assert curve.direction == "left"
    # Its real extent: from about the first node on the arc to about the last, not a piece at the apex.
    assert curve.start_s <= first_node_s + radius_m / 2.0
    assert curve.end_s >= last_node_s - radius_m / 2.0


@settings(max_examples=60, deadline=None)
@given(st.floats(30.0, 150.0), st.sampled_from([-1.0, 1.0]), st.floats(0.0, 48.0), st.booleans())
def test_a_corner_of_thirty_degrees_or_more_is_never_a_straight(turn_deg, side, at_m, dense) -> None:
    # A corner of one node at ``at_m`` (up to 48 m) after a chain's start, long straights either side.
    xy = _way([0.0, side * turn_deg], [at_m + 2.5, 150.0])
    xy = _dense(xy) if dense else xy
    direction = "left" if side > 0 else "right"
    corner_s = at_m + 2.5
    covering = [c for c in _curves(xy) if c.direction == direction and c.start_s - 1.0 <= corner_s <= c.end_s + 1.0]
    assert len(covering) == 1
    assert abs(covering[0].angle_deg - turn_deg) <= ANGLE_TOLERANCE_DEG


def _spiked_way(turns_deg: list[float], lengths_m: list[float], spikes_m: list[float], seed: int) -> np.ndarray:
    """A way of the given vertex turns and segment lengths with a back-and-forth spike of each of ``spikes_m`` put
    on a node drawn with ``seed``: the polyline runs back towards the node before it by that much and forward again.
    """
    headings = np.concatenate(([0.0], np.cumsum(turns_deg)))
    way = _way(list(headings), lengths_m[: len(headings)])
    rng = np.random.default_rng(seed)
    spiked = list(way)
    for node, spike_m in zip(rng.choice(np.arange(1, len(way) - 1), 3), spikes_m, strict=True):
        at = way[node]
        back = at + spike_m * (way[node - 1] - at) / np.hypot(*(way[node - 1] - at))
        spiked[node] = np.vstack((at, back, at))
    return np.vstack([np.atleast_2d(point) for point in spiked])


def _excess_turn_deg(curves: list[Curve], turns_deg: list[float], lengths_m: list[float]) -> list[float]:
    """How much each curve turns its way beyond what the way's own vertices turn that way about its stretch (two
    vertices beyond either end), degrees. The spikes lengthen the polyline by at most 2 m each before a node, so
    the stretch is compared on the way's own nodes."""
    node_s = np.cumsum(lengths_m[: len(turns_deg) + 1])[:-1]
    excess = []
    for curve in curves:
        side = 1.0 if curve.direction == "left" else -1.0
        first = max(int(np.searchsorted(node_s, curve.start_s - 6.0)) - 2, 0)
        stop = int(np.searchsorted(node_s, curve.end_s, side="right")) + 2
        excess.append(curve.angle_deg - float(np.clip(side * np.array(turns_deg[first:stop]), 0.0, None).sum()))
    return excess


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.floats(-100.0, 100.0), min_size=3, max_size=10),
    st.lists(st.floats(8.0, 40.0), min_size=11, max_size=11),
    st.lists(st.floats(0.1, 1.0), min_size=3, max_size=3),
    st.integers(0, 2**32 - 1),
)
@example(  # reported with a curve of 361 degrees where the way turns 113
    turns_deg=[51.634796030572744, -6.802961966539886e-204, 51.12700442981492, 10.0],
    lengths_m=[14.704159298654178, 8.0, 10.0, 25.915275914790296, 14.704159298654178, 9.8, 28.479959128234366]
    + [20.0, 10.0, 38.34259597019939, 23.491765020400127],
    spikes_m=[0.1, 0.1, 0.1],
    seed=0,
)
def test_spikes_on_a_way_add_no_turn_to_its_curves(turns_deg, lengths_m, spikes_m, seed) -> None:
    # A way of known vertex turns with back-and-forth spikes of 0.1-1 m put on some of its nodes:
    # no curve turns its way by more than the way's own vertices turn that way about its stretch,
    # plus the tolerance; so none claims 360 degrees unless the way itself turns that much one way.
    curves = _curves(_spiked_way(turns_deg, lengths_m, spikes_m, seed))
    excess_deg = _excess_turn_deg(curves, turns_deg, lengths_m)
    assert all(excess <= ANGLE_TOLERANCE_DEG for excess in excess_deg), (turns_deg, lengths_m, spikes_m, seed)


def test_spikes_on_a_way_make_no_loop_of_its_plain_fit() -> None:
    # Spikes of 0.5-1 m on a way turning 44 degrees right then 41-53 degrees left at each node: their
    # reversals of 180 degrees each are no turning of the road, and no curve of the fit of the
    # polyline alone (no road chain) turns more than the way's vertices about it, plus the tolerance
    # (it gave an R 5 m curve of 404 degrees).
    turns_deg = [19.465768600614453, -44.20610210300332, 41.40891850494636, 53.39378053739755, 48.470014583511215]
    turns_deg += [8.366297743113265]
    lengths_m = [12.654718520349661, 14.158831838986636, 37.69298191182478, 25.67444760535244, 13.777679950365172]
    lengths_m += [36.28982061428704, 28.530294567119384, 26.230216783161854, 20.041210756157444, 21.150569029028155]
    lengths_m += [15.663654805819036]
    xy = _spiked_way(turns_deg, lengths_m, [0.5, 0.5, 1.0], 2008885983)
    curves = find_curves(xy, WARNING_RADIUS_M, policy=DEFAULT_POLICY)
    assert curves
    assert all(excess <= ANGLE_TOLERANCE_DEG for excess in _excess_turn_deg(curves, turns_deg, lengths_m))
