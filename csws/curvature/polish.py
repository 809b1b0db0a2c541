"""Polishes trial roads of sparse polylines and chooses among them: the third step."""

from __future__ import annotations

from dataclasses import fields

import numpy as np

from .chords import _Chords
from .dense import SPARSE_MIN_NOISE_M, SPLIT_OFFSET, _split_threshold
from .knots import _fits, _knot_fit, _SparseBatch, _trimmed, _with_straights
from .road import (
    PROJECTION_STEPS,
    _base_road,
    _chosen,
    _Nodes,
    _nodes_rows,
    _padded_nodes,
    _polished,
    _projected,
    _put_rows,
    _Road,
    _road_rows,
)
from .trials import _joined_trials, _padded_road, _straight_trial_roads, _stretched_trials

#: Sparse chords shorter than this many times the coordinate noise are joined with the next.
SHORT_CHORD_NOISE_FACTOR = 5.0
#: A knot of a sparse polyline must reduce the normalised residual by SPLIT_PENALTY * ln(chords) + this.
SPARSE_KNOT_OFFSET = 10.0
#: A part of a sparse polyline is curved only if making it straight grows the normalised residual by more.
SPARSE_STRAIGHT_THRESHOLD = 20.0
#: A straight tried in a curved part of a sparse polyline's road is kept when the nodes' sum
#: of squared sideways distances falls by more than this many times their noise variance
#: for each parameter it adds (a straight at an end adds a knot but no curvature).
STRAIGHT_TRIAL_THRESHOLD = 10.0
#: Steps every trial road is polished with (plain steps, :data:`STEP_SCALES` not tried)
#: before only the closest of each kind is polished on.
FIRST_POLISH_ITERATIONS = 3
#: How far the polish's other starting roads stretch the longest curved part (shrinking below 1).
STRETCH_FACTORS = (0.5, 2.0)
#: Straights are tried only on roads whose nodes' sum of squared sideways distances exceeds
#: this many times what the noise (the polyline's own estimate) leaves on the right road.
STRAIGHT_TRIAL_MISFIT = 1.0
#: Fewest nodes more than parameters a road with added straights must have to be tried.
MIN_TRIAL_FREEDOM = 1
#: Fewest nodes more than parameters a road's residual must have to estimate the noise from.
MIN_VARIANCE_FREEDOM = 2
#: Chord counts sparse polylines are padded to, so that few batches are fitted (each in one set of array operations).
SPARSE_BATCH_CHORDS = np.array([4, 5, 6, 8, 10, 12, 16, 20, 24, 32, 40, 48, 64, 80])


def _residual_variance(squares: np.ndarray, roads: _Road, real: np.ndarray, estimate: np.ndarray) -> np.ndarray:
    """Each polyline's sideways noise variance, m²: the smaller of its own ``estimate`` and
    what the trial road closest to its nodes leaves (its sum of squares over the nodes less
    the road's parameters, at least :data:`MIN_VARIANCE_FREEDOM` of them), at least
    :data:`SPARSE_MIN_NOISE_M` squared. The estimate from the chords errs on the large
    side where the curvature changes; a fit's residual needs a few nodes to spare."""
    freedom = real.sum(axis=1)[:, None] - roads.movable().sum(axis=-1)
    usable = freedom >= MIN_VARIANCE_FREEDOM
    best = np.argmin(np.where(usable, squares, np.inf), axis=1)
    rows = np.arange(len(squares))
    fitted = np.where(usable[rows, best], squares[rows, best] / np.fmax(freedom[rows, best], 1), np.inf)
    return np.fmax(np.fmin(fitted, estimate), SPARSE_MIN_NOISE_M**2)


def _with_added_straights(
    road: _Road, squares: np.ndarray, nodes: _Nodes, noise_variance: np.ndarray
) -> tuple[_Road, np.ndarray]:
    """Straights added into curved parts where the polished road then lies closer to the
    nodes by more than :data:`STRAIGHT_TRIAL_THRESHOLD` times their noise variance
    per parameter added.

    A curve's first (or last) knot is missed when the straight before it has only a few
    nodes: the straight and the curve are then fitted as one curved part that starts at
    the polyline's start (3.4), however clearly its first nodes lie on a line. A curve
    in the middle of a way may need both straights before either pays off, and two
    curves with a straight between them may have been fitted as one. So a straight at
    the start, at the end, at both and in the middle of the longest curved part are tried
    together, each from several places (:data:`csws.curvature.trials.END_STRAIGHT_FRACTIONS`,
    :data:`csws.curvature.trials.MIDDLE_STRAIGHT_SPANS`), and the road that costs least is
    kept. The noise variance is the smaller of the polyline's own estimate and what the
    closest road leaves (:func:`_residual_variance`); the estimate alone decides which roads
    are tried.

    Returns the roads (two parts more, padding where no straight was added) and their sums of squares.
    """
    result, squares = _padded_road(_padded_road(road)), squares.copy()
    last = road.last[:, 0]
    longest = np.argmax(np.where(road.free[:, 0], np.diff(road.bounds[:, 0], axis=-1), -1.0), axis=-1)
    rows, kind_allowed = _straight_trial_kinds(road, squares, nodes, noise_variance, longest)
    if rows.size == 0:
        return result, squares
    tried = _road_rows(road, rows)
    trials, counts = _straight_trial_roads(tried, _nodes_rows(nodes, rows), last[rows], longest[rows])
    # Parameters each kind adds: one knot, two, two and a curvature, a knot and a curvature.
    added = np.repeat([1, 1, 2, 3, 2], counts)
    allowed = np.column_stack(
        [np.repeat(ok[rows, None], count, axis=1) for count, ok in zip(counts, kind_allowed, strict=False)]
    )
    allowed &= trials.is_ordered()
    trials, leading = _leading_trials(trials, _nodes_rows(nodes, rows), allowed, counts)
    added, allowed = added[leading], np.take_along_axis(allowed, leading, axis=1)
    trials, trial_squares = _polished(trials, _nodes_rows(nodes, rows), wanted=allowed)
    trial_squares = np.where(allowed, trial_squares, np.inf)
    variance = _residual_variance(
        np.concatenate((trial_squares, squares[rows]), axis=1),
        _joined_trials([trials, _padded_road(_padded_road(tried))]),
        nodes.real[rows],
        noise_variance[rows],
    )
    cost = np.where(allowed, trial_squares + added * (STRAIGHT_TRIAL_THRESHOLD * variance)[:, None], np.inf)
    best = np.argmin(cost, axis=1)
    accept = cost[np.arange(len(rows)), best] < squares[rows, 0]
    changed, best = rows[accept], best[accept]
    _put_rows(result, (changed, 0), trials, (np.flatnonzero(accept), best))
    squares[changed, 0] = trial_squares[np.flatnonzero(accept), best]
    return result, squares


def _straight_trial_kinds(
    road: _Road, squares: np.ndarray, nodes: _Nodes, noise_variance: np.ndarray, longest: np.ndarray
) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
    """The polylines whose roads straights are tried on, and for every polyline which of the
    five kinds of trial it allows (:func:`csws.curvature.trials._straight_trial_roads`): each
    must leave the nodes enough freedom to be judged by."""
    polylines = np.arange(len(road.last))
    last = road.last[:, 0]
    freedom = nodes.real.sum(axis=1) - road.movable()[:, 0].sum(axis=1)
    at_start = road.free[polylines, 0, 0] & (freedom - 1 >= MIN_TRIAL_FREEDOM)
    at_end = road.free[polylines, 0, last] & (freedom - 1 >= MIN_TRIAL_FREEDOM)
    at_both = at_start & at_end & (freedom - 2 >= MIN_TRIAL_FREEDOM)
    in_middle = road.free[polylines, 0, longest] & (freedom - 3 >= MIN_TRIAL_FREEDOM)
    # A road as close to the nodes as their noise lets it be leaves nothing for a straight to explain.
    rows = np.flatnonzero(
        (at_start | at_end | in_middle) & (squares[:, 0] > STRAIGHT_TRIAL_MISFIT * freedom * noise_variance)
    )
    return rows, (at_start, at_end, at_both, in_middle, in_middle)


def _leading_trials(trials: _Road, nodes: _Nodes, allowed: np.ndarray, counts: list[int]) -> tuple[_Road, np.ndarray]:
    """The trial of each kind (``counts`` of them side by side) that leads after a few steps of
    the polish, and where it stood: only those are polished to the end."""
    trials, trial_squares = _polished(trials, nodes, FIRST_POLISH_ITERATIONS, allowed, scales=())
    trial_squares = np.where(allowed, trial_squares, np.inf)
    kind_start = np.cumsum([0, *counts])
    leading = np.column_stack(
        [
            first + np.argmin(trial_squares[:, first:stop], axis=1)
            for first, stop in zip(kind_start[:-1], kind_start[1:], strict=True)
        ]
    )
    return _chosen(trials, leading), leading


def _with_unseen_ends_straight(
    road: _Road, squares: np.ndarray, nodes: _Nodes, noise_variance: np.ndarray
) -> tuple[_Road, np.ndarray]:
    """The roads ``(polylines, 1)`` whose first or last part is curved but holds no node
    (it lies within the way's first or last segment) tried with that part straight, and
    kept so where the polished road lies no further from the nodes than
    :data:`STRAIGHT_TRIAL_THRESHOLD` times their noise variance (one parameter fewer).

    A segment tells only its own direction: an arc within it that overshoots and turns
    back fits as well as a straight, and the curve before it, taken past the last node,
    then turns more than the way does and is dropped by rule 2 (a 56 degree curve of R
    127 m was lost so).
    """
    node_s = np.where(nodes.real, nodes.s, np.nan)
    first_stop = road.bounds[:, 0, 1]
    last = road.last[:, 0]
    last_start = np.take_along_axis(road.bounds[:, 0], last[:, None], axis=1)[:, 0]
    rows = np.arange(len(last))
    inner = nodes.real & (nodes.s > 0.0) & (nodes.s < np.nanmax(node_s, axis=1)[:, None])
    unseen_first = road.free[rows, 0, 0] & ~np.any(inner & (nodes.s < first_stop[:, None]), axis=1) & (last > 0)
    unseen_last = road.free[rows, 0, last] & ~np.any(inner & (nodes.s > last_start[:, None]), axis=1) & (last > 0)
    changed = np.flatnonzero(unseen_first | unseen_last)
    if changed.size == 0:
        return road, squares
    trial = _road_rows(road, changed)
    free, curvature = trial.free.copy(), trial.curvature.copy()
    free[unseen_first[changed], 0, 0] = False
    free[np.flatnonzero(unseen_last[changed]), 0, last[changed][unseen_last[changed]]] = False
    trial = _Road(trial.base_heading, trial.offset, trial.turn, trial.bounds, curvature * free, free, trial.last)
    trial, trial_squares = _polished(trial, _nodes_rows(nodes, changed))
    variance = _residual_variance(
        np.concatenate((trial_squares, squares[changed]), axis=1),
        _joined_trials([trial, _road_rows(road, changed)]),
        nodes.real[changed],
        noise_variance[changed],
    )
    accept = trial_squares[:, 0] <= squares[changed, 0] + STRAIGHT_TRIAL_THRESHOLD * variance
    result, squares = _Road(*(np.array(getattr(road, f.name)) for f in fields(_Road))), squares.copy()
    _put_rows(result, (changed[accept], 0), trial, (np.flatnonzero(accept), 0))
    squares[changed[accept], 0] = trial_squares[accept, 0]
    return result, squares


def _along_polyline(t: np.ndarray, nodes: _Nodes, node_t: np.ndarray) -> np.ndarray:
    """Arc lengths ``t`` ``(polylines, k)`` on the road converted to arc lengths along the
    polyline, linearly between the nodes' projections ``node_t`` (beyond them, one to one)."""
    count = nodes.real.sum(axis=1)
    node_t = np.maximum.accumulate(np.where(nodes.real, node_t, np.inf), axis=1)
    after = np.clip((node_t[:, None, :] <= t[:, :, None]).sum(axis=2), 1, count[:, None] - 1)
    rows = np.arange(len(t))[:, None]
    t0, t1 = node_t[rows, after - 1], node_t[rows, after]
    s0, s1 = nodes.s[rows, after - 1], nodes.s[rows, after]
    fraction = (t - t0) / np.fmax(t1 - t0, 1e-9)
    inside = s0 + np.clip(fraction, 0.0, 1.0) * (s1 - s0)
    return inside + np.fmax(t - t1, 0.0) * (after == count[:, None] - 1) + np.fmin(t - t0, 0.0) * (after == 1)


def _polished_parts(
    batch: _SparseBatch,
    nodes: _Nodes,
    bounds: np.ndarray,
    curvature: np.ndarray,
    free: np.ndarray,
    knots: np.ndarray,
    noise_variance: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The heading fit's parts polished in the plane (:func:`_polished`), from it and from
    its longest curve stretched and shrunk (:func:`_stretched_trials`), with straights
    added where they fit (:func:`_with_added_straights`); returns bounds along the polyline,
    curvatures and the number of knots, as :func:`_sparse_batch_parts`."""
    trials = _stretched_trials(_base_road(batch, bounds, curvature, free, knots), np.array(STRETCH_FACTORS))
    ordered = trials.is_ordered()
    trials, squares = _polished(trials, nodes, FIRST_POLISH_ITERATIONS, ordered, scales=())
    leading = np.argmin(np.where(ordered, squares, np.inf), axis=1)[:, None]
    road, squares = _polished(_chosen(trials, leading), nodes)
    road, squares = _with_added_straights(road, squares, nodes, noise_variance)
    road, squares = _with_unseen_ends_straight(road, squares, nodes, noise_variance)
    t = np.broadcast_to(nodes.s[:, None, :], nodes.s.shape[:1] + (1,) + nodes.s.shape[1:]).copy()
    node_t = _projected(road, nodes, t, PROJECTION_STEPS)[0][:, 0]
    polished = _along_polyline(road.bounds[:, 0], nodes, node_t)
    knots = road.last[:, 0]
    polished[:, 0] = 0.0
    polished = np.where(np.arange(polished.shape[1])[None, :] > knots[:, None], batch.end[:, None], polished)
    return np.maximum.accumulate(np.clip(polished, 0.0, batch.end[:, None]), axis=1), road.curvature[:, 0], knots


def _sparse_batch_parts(
    batch: _SparseBatch, nodes: _Nodes, noise_m: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Parts of the sparse polylines of a batch: a continuous piecewise-linear fit of their
    heading, polished in the plane.

    Returns the part bounds in each polyline's arc length (``[0, ..., end]``, padded with
    the end), each part's curvature, 1/m, and the number of knots of each polyline.

    A map way has few nodes per curve, so the independent line per part of the dense
    method has too few chords to fit; here the heading is one continuous function
    (the road has no kinks, 3.4-3.8) with free knots, every chord predicted by the
    mean heading over the arc it spans, chords across a knot included. Knots are
    added and dropped by the same significance as the dense method's splits, and a
    part whose curvature is not significant is a straight. The road these parts
    describe is then fitted to the nodes themselves (:func:`_polished_parts`).
    """
    sideways_variance = np.fmax(noise_m, SPARSE_MIN_NOISE_M) ** 2
    noise_variance = 2.0 * sideways_variance
    knot_threshold = _split_threshold(batch.count) - SPLIT_OFFSET + SPARSE_KNOT_OFFSET
    bounds, knots = _knot_fit(batch, knot_threshold * noise_variance)
    bounds, free = _with_straights(batch, _trimmed(bounds, knots), knots, SPARSE_STRAIGHT_THRESHOLD * noise_variance)
    curvature = _fits(batch, bounds[:, None, :], free[:, None, :])[1][:, 0]
    # The polish adds two parts (end straights) to every curved polyline's road; it is
    # done in groups of similar node counts, so that little of its work is padding.
    curved = free.any(axis=1)
    node_count = nodes.real.sum(axis=1)
    group = np.searchsorted(SPARSE_BATCH_CHORDS, node_count - 1)
    bounds = np.concatenate((bounds, np.repeat(bounds[:, -1:], 2, axis=1)), axis=1)
    curvature = np.concatenate((curvature, np.zeros((len(curvature), 2))), axis=1)
    knots = knots.copy()
    for size in np.unique(group[curved]):
        rows = np.flatnonzero(curved & (group == size))
        bounds[rows], curvature[rows], knots[rows] = _polished_parts(
            batch.rows(rows),
            _nodes_rows(nodes, rows, int(node_count[rows].max())),
            bounds[rows, :-2],
            curvature[rows, :-2],
            free[rows],
            knots[rows],
            sideways_variance[rows],
        )
    return bounds, curvature, knots


def _merged_straights(bounds: np.ndarray, curvature: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Parts of no length, and knots between two parts of equal curvature (two straights), removed."""
    keep = np.diff(bounds) > 0  # a part of no length at the start leaves its start, 0, to the next
    bounds, curvature = np.append(bounds[:-1][keep], bounds[-1]), curvature[keep]
    keep = np.concatenate(([True], curvature[1:] != curvature[:-1]))
    return np.append(bounds[:-1][keep], bounds[-1]), curvature[keep]


def _without_short_chords(
    start_s: np.ndarray, length_m: np.ndarray, heading: np.ndarray, shortest_m: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Chords of one polyline with the vertices that leave a chord shorter than
    ``shortest_m`` dropped (the first and last vertex are kept): the heading of a chord
    not much longer than the coordinate noise is noise.

    Returns each remaining chord's start arc length, arc length along the polyline and heading.
    """
    if length_m.min() >= shortest_m:
        return start_s, length_m, heading
    step = np.column_stack((length_m * np.cos(heading), length_m * np.sin(heading)))
    vertex_xy = np.concatenate((np.zeros((1, 2)), np.cumsum(step, axis=0)))
    vertex_s = np.append(start_s, start_s[-1] + length_m[-1])
    kept = [0]
    for vertex in range(1, len(vertex_s)):
        if np.hypot(*(vertex_xy[vertex] - vertex_xy[kept[-1]])) >= shortest_m:
            kept.append(vertex)
    if kept[-1] != len(vertex_s) - 1:
        kept[-1 if len(kept) > 1 else len(kept) :] = [len(vertex_s) - 1]
    if len(kept) == len(vertex_s):
        return start_s, length_m, heading
    kept_xy, kept_s = vertex_xy[kept], vertex_s[kept]
    kept_step = np.diff(kept_xy, axis=0)
    kept_heading = np.arctan2(kept_step[:, 1], kept_step[:, 0])
    kept_heading = np.unwrap(np.append(heading[0], kept_heading))[1:]
    return kept_s[:-1], np.diff(kept_s), kept_heading


def _padded_batch(polylines: list[tuple[np.ndarray, np.ndarray, np.ndarray]], size: int) -> _SparseBatch:
    """The batch of polylines given by their chords' start arc lengths, lengths and
    headings, padded to ``size`` chords with chords of no weight, 1 m long, beyond the end."""
    count = np.array([len(start_s) for start_s, _, _ in polylines])
    end = np.array([start_s[-1] + length_m[-1] for start_s, length_m, _ in polylines])
    a = end[:, None] + np.arange(size)[None, :] - count[:, None] + 1.0
    length_m, heading = np.ones((len(polylines), size)), np.zeros((len(polylines), size))
    real = np.arange(size)[None, :] < count[:, None]
    a[real] = np.concatenate([start_s for start_s, _, _ in polylines])
    length_m[real] = np.concatenate([length for _, length, _ in polylines])
    heading[real] = np.concatenate([h for _, _, h in polylines])
    return _SparseBatch(a, a + length_m, heading, np.where(real, length_m, 0.0), end, count)


def _sparse_parts(
    chords: _Chords, noise_m: np.ndarray, polylines: np.ndarray
) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """Part bounds (``[0, ..., end]``) and curvatures of the sparse ``polylines``, fitted
    in batches of equal chord count (:func:`_sparse_batch_parts`)."""
    kept, every = {}, {}
    for polyline in polylines:
        first, stop = chords.polyline_first_chord[polyline : polyline + 2]
        every[int(polyline)] = (chords.start_s[first:stop], chords.length_m[first:stop], chords.heading[first:stop])
        kept[int(polyline)] = _without_short_chords(
            *every[int(polyline)], SHORT_CHORD_NOISE_FACTOR * float(noise_m[polyline])
        )
    by_size: dict[int, list[int]] = {}
    for polyline, (start_s, _, _) in kept.items():
        size = SPARSE_BATCH_CHORDS[np.searchsorted(SPARSE_BATCH_CHORDS, len(start_s))]
        by_size.setdefault(size, []).append(polyline)
    parts = {}
    for size, members in by_size.items():
        batch, nodes = _padded_batch([kept[p] for p in members], size), _padded_nodes([every[p] for p in members])
        bounds, curvature, knots = _sparse_batch_parts(batch, nodes, noise_m[members])
        for row, polyline in enumerate(members):
            parts[polyline] = _merged_straights(bounds[row, : knots[row] + 2], curvature[row, : knots[row] + 1])
    return parts
