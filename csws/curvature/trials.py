"""Builds the trial roads of the sparse polish side by side: straights added, curves stretched, compound curves.

The polish (:mod:`csws.curvature.polish`) starts from the road the heading fit found
and from these variations of it, ``(polylines, trials)`` at once, and keeps the one that
lies closest to the nodes for what it costs in parameters.
"""

from __future__ import annotations

from dataclasses import fields

import numpy as np

from .road import MIN_POLISHED_PART_M, _Nodes, _repeated, _Road, _split_part

#: How much of a curved end part a straight tried there first takes, as fractions of the
#: part counted in nodes from the polyline's end (the polish then moves its knot).
END_STRAIGHT_FRACTIONS = (0.25, 0.5, 0.75)
#: Where a straight is first put into the middle of a curved part, and where a curved part
#: is first narrowed to between two straights, as fractions of the part (counted in nodes).
MIDDLE_STRAIGHT_SPANS = ((0.25, 0.5), (0.25, 0.75), (0.5, 0.75))
ARC_SPANS = MIDDLE_STRAIGHT_SPANS
#: Where the longest curved part is first cut into the two arcs of a compound curve, as
#: fractions of it (counted in nodes), and how much sharper the one arc is than the other.
COMPOUND_FRACTIONS = (0.25, 0.5, 0.75)
COMPOUND_RATIO = 1.5


def _among_nodes(nodes: _Nodes, first: np.ndarray, stop: np.ndarray, fraction: np.ndarray) -> np.ndarray:
    """Positions ``(polylines, trials)`` between ``first`` and ``stop`` at ``fraction`` of the
    way counted in nodes: the nodes between them and the two ends are spaced evenly in
    rank, and linearly between. Mappers put nodes close on a curve, so a curve short
    against a long part still gets trial knots on it."""
    s = nodes.s[:, None, :]
    inside = nodes.real[:, None, :] & (s > first[..., None]) & (s < stop[..., None])
    ranked = np.sort(np.where(inside, s, np.inf), axis=-1)
    count = inside.sum(axis=-1)
    ends = np.concatenate((first[..., None], ranked, np.full(first.shape + (1,), np.inf)), axis=-1)
    np.put_along_axis(ends, (count + 1)[..., None], stop[..., None], axis=-1)
    rank = fraction * (count + 1)
    below = np.minimum(np.floor(rank).astype(np.int64), count)
    low, high = (np.take_along_axis(ends, (below + k)[..., None], axis=-1)[..., 0] for k in (0, 1))
    return low + (rank - below) * (high - low)


def _part_trials(road: _Road, part: np.ndarray, trials: int) -> tuple[_Road, np.ndarray, np.ndarray, np.ndarray]:
    """``road`` (one trial per polyline) repeated ``trials`` times, with its part ``part``
    ``(polylines,)`` and that part's first and last bound, each ``(polylines, trials)``."""
    road = _repeated(road, trials)
    part = np.repeat(part[:, None], trials, axis=1)
    first, stop = (np.take_along_axis(road.bounds, (part + k)[..., None], axis=-1)[..., 0] for k in (0, 1))
    return road, part, first, stop


def _straight_trials(road: _Road, nodes: _Nodes, part: np.ndarray, low: np.ndarray, high: np.ndarray) -> _Road:
    """Trial roads ``(polylines, fractions)`` from ``road`` (one trial per polyline), each
    with a straight over the fractions ``low[f]`` to ``high[f]`` of its part ``part``,
    counted in nodes (:func:`_among_nodes`; from the part's start when ``low`` is 0,
    which must then be the first part; to its end when ``high`` is 1).

    The trial stays close to the road: the straight takes the road's mean heading over
    it, and the arcs beside it turn from the road's heading at the part's ends to that
    (or the start is turned to it), so that the polish starts near its goal.
    """
    road, part, first, stop = _part_trials(road, part, np.shape(low)[-1])
    start, end = _among_nodes(nodes, first, stop, low), _among_nodes(nodes, first, stop, high)
    start = np.where(low > 0.0, np.clip(start, first + MIN_POLISHED_PART_M, stop - 2.0 * MIN_POLISHED_PART_M), first)
    end = np.where(high < 1.0, np.clip(end, start + MIN_POLISHED_PART_M, stop - MIN_POLISHED_PART_M), stop)
    curvature = np.take_along_axis(road.curvature, part[..., None], axis=-1)[..., 0]
    half_turn = 0.5 * curvature * (end - start)
    before = curvature + half_turn / np.fmax(start - first, MIN_POLISHED_PART_M)
    after = curvature + half_turn / np.fmax(stop - end, MIN_POLISHED_PART_M)
    zero = np.zeros_like(curvature)
    if np.all(low == 0.0):
        road = _Road(
            road.base_heading, road.offset, road.turn + half_turn, *(getattr(road, f.name) for f in fields(_Road)[3:])
        )
        return _split_part(road, part, end, zero, after)
    if np.all(high == 1.0):
        return _split_part(road, part, start, before, zero)
    return _split_part(_split_part(road, part, start, before, after), part + 1, end, zero, after)


def _stretched_trials(road: _Road, factors: np.ndarray) -> _Road:
    """Trial roads ``(polylines, 1 + factors)``: ``road`` (one trial per polyline) and, for
    each factor, its longest curved part stretched by that factor about its middle (as far
    as its neighbours leave room), turning the same angle.

    A few nodes on a curve often fit a short sharp arc about as well as a long gentle
    one; the heading fit picks one, and the polish stays near what it is given. Polishing
    both from the start lets the nodes decide (3.4, 3.5: where the curve starts and ends).
    """
    trials = len(factors)
    stretched = _repeated(road, trials)
    parts = road.curvature.shape[-1]
    part = np.argmax(np.where(road.free, np.diff(road.bounds, axis=-1), -1.0), axis=-1)
    bounds = stretched.bounds
    first, stop = (
        np.take_along_axis(bounds, np.repeat(part + k, trials, axis=1)[..., None], axis=-1)[..., 0] for k in (0, 1)
    )
    below = np.take_along_axis(bounds, np.repeat(np.maximum(part - 1, 0), trials, axis=1)[..., None], axis=-1)[..., 0]
    above = np.take_along_axis(bounds, np.repeat(np.minimum(part + 2, parts), trials, axis=1)[..., None], axis=-1)[
        ..., 0
    ]
    middle, half = 0.5 * (first + stop), 0.5 * (stop - first) * factors
    is_first, is_last = part == 0, part == road.last
    start = np.where(is_first, first, np.clip(middle - half, below + MIN_POLISHED_PART_M, stop))
    end = np.where(is_last, stop, np.clip(middle + half, start + MIN_POLISHED_PART_M, above - MIN_POLISHED_PART_M))
    index = np.repeat(part, trials, axis=1)[..., None]
    np.put_along_axis(bounds, index, start[..., None], axis=-1)
    np.put_along_axis(bounds, index + 1, end[..., None], axis=-1)
    curvature = stretched.curvature
    angle = np.take_along_axis(curvature, index, axis=-1)[..., 0] * (stop - first)
    np.put_along_axis(curvature, index, (angle / np.fmax(end - start, MIN_POLISHED_PART_M))[..., None], axis=-1)
    return _joined_trials([road, stretched])


def _padded_road(road: _Road) -> _Road:
    """``road`` with a part of no length more at its end (padding)."""
    return _Road(
        road.base_heading,
        road.offset,
        road.turn,
        np.concatenate((road.bounds, road.bounds[..., -1:]), axis=-1),
        np.concatenate((road.curvature, np.zeros_like(road.curvature[..., :1])), axis=-1),
        np.concatenate((road.free, np.zeros_like(road.free[..., :1])), axis=-1),
        road.last,
    )


def _one_trial_each(road: _Road) -> _Road:
    """The trial roads ``(polylines, trials)`` as ``(polylines * trials, 1)``."""
    return _Road(*(getattr(road, f.name).reshape((-1, 1) + getattr(road, f.name).shape[2:]) for f in fields(_Road)))


def _trials_of(road: _Road, polylines: int) -> _Road:
    """Trial roads ``(polylines * k, 1)`` back as ``(polylines, k)``."""
    return _Road(
        *(getattr(road, f.name).reshape((polylines, -1) + getattr(road, f.name).shape[2:]) for f in fields(_Road))
    )


def _joined_trials(roads: list[_Road]) -> _Road:
    """The trial roads of ``roads`` (of equal part counts) side by side."""
    return _Road(*(np.concatenate([getattr(r, f.name) for r in roads], axis=1) for f in fields(_Road)))


def _straight_trial_roads(road: _Road, nodes: _Nodes, last: np.ndarray, longest: np.ndarray) -> tuple[_Road, list[int]]:
    """The trial roads of the four kinds :func:`_with_added_straights` tries, side by side
    ``(polylines, trials)``: a straight at the start, at the end, at both (an arc between
    them) and in the middle of the ``longest`` curved part; also returns how many of each."""
    fraction = np.array(END_STRAIGHT_FRACTIONS)
    first_part = np.zeros(len(last), dtype=np.int64)
    start_trials = _straight_trials(road, nodes, first_part, np.zeros_like(fraction), fraction)
    end_trials = _straight_trials(road, nodes, last, 1.0 - fraction, np.ones_like(fraction))
    # An arc between two straights: the straight before it first, then the one after it.
    arc_low, arc_high = (np.array(ARC_SPANS)[:, k] for k in (0, 1))
    before_arcs = _one_trial_each(_straight_trials(road, nodes, first_part, np.zeros_like(arc_low), arc_low))
    after_share = np.tile((1.0 - arc_high) / (1.0 - arc_low), len(last))[:, None]
    each_nodes = _Nodes(*(np.repeat(getattr(nodes, f.name), len(arc_low), axis=0) for f in fields(_Nodes)))
    both_trials = _trials_of(
        _straight_trials(before_arcs, each_nodes, before_arcs.last[:, 0], 1.0 - after_share, np.ones_like(after_share)),
        len(last),
    )
    low, high = (np.array(MIDDLE_STRAIGHT_SPANS)[:, k] for k in (0, 1))
    middle_trials = _straight_trials(road, nodes, longest, low, high)
    compound_trials = _compound_trials(road, nodes, longest)
    trials = _joined_trials(
        [
            _padded_road(start_trials),
            _padded_road(end_trials),
            both_trials,
            middle_trials,
            _padded_road(compound_trials),
        ]
    )
    return trials, [len(fraction), len(fraction), len(arc_low), len(low), compound_trials.last.shape[1]]


def _compound_trials(road: _Road, nodes: _Nodes, part: np.ndarray) -> _Road:
    """Trial roads ``(polylines, 2 * fractions)`` from ``road`` (one trial per polyline), each
    with its part ``part`` cut into two arcs at :data:`COMPOUND_FRACTIONS` of it (counted
    in nodes), the first sharper or gentler by :data:`COMPOUND_RATIO`: a compound curve
    (3.8) that the heading fit took for one arc of a mean radius."""
    fraction = np.array(COMPOUND_FRACTIONS)
    road, part, first, stop = _part_trials(road, part, 2 * len(fraction))
    knot = np.clip(
        _among_nodes(nodes, first, stop, np.tile(fraction, 2)), first + MIN_POLISHED_PART_M, stop - MIN_POLISHED_PART_M
    )
    curvature = np.take_along_axis(road.curvature, part[..., None], axis=-1)[..., 0]
    ratio = np.repeat([COMPOUND_RATIO, 1.0 / COMPOUND_RATIO], len(fraction))
    return _split_part(road, part, knot, curvature * ratio, curvature / ratio)
