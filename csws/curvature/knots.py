"""Places the knots of the heading fit of sparse polylines (map ways), for a batch at once: the first step."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Positions tried around the best vertex or chord middle when placing a sparse knot.
FINE_KNOT_STEPS = 4
#: Passes moving each knot of a sparse polyline to its best place.
SPARSE_REFINE_PASSES = 2
#: A pair of knots added together must pass this many times the threshold of one.
PAIR_THRESHOLD_FACTOR = 2.0
#: Parts of a polyline tried straight (with knots moved) in each round: those cheapest to straighten with knots held.
STRAIGHT_SCREEN = 2
#: Most array elements (polylines x trials x chords x parts) fitted in one go.
MAX_FIT_ELEMENTS = 2_000_000


# --------------------------------------------------------------------------- sparse polylines
#
# Sparse polylines are fitted in batches: the polylines of one batch have the same
# number of chords, and every step below is done for all of them (and for all their
# trial knot positions) in one set of array operations. Knot lists differ in length, so
# each polyline's bounds are padded with its end: a part of no length adds a column of
# zeros to the fit, which the regularised normal equations give a coefficient of 0.


@dataclass(frozen=True)
class _SparseBatch:
    """Chords of sparse polylines of similar chord counts, in an arc-length coordinate
    ``u``: chord i of polyline p spans ``[a[p, i], b[p, i]]``.

    ``heading`` is each chord's (unwrapped) heading, ``root_weight`` the square root of
    its fit weight (its chord length: a long chord's heading is the more precise), ``end``
    each polyline's length in ``u`` and ``count`` its number of chords. The rows are
    padded to a common length with chords of no weight beyond ``end``.
    """

    a: np.ndarray
    b: np.ndarray
    heading: np.ndarray
    root_weight: np.ndarray
    end: np.ndarray
    count: np.ndarray

    def rows(self, index: np.ndarray | slice) -> _SparseBatch:
        """The batch of the polylines ``index``."""
        return _SparseBatch(
            *(getattr(self, field)[index] for field in ("a", "b", "heading", "root_weight", "end", "count"))
        )

    def coarse_candidates(self) -> np.ndarray:
        """Each polyline's vertices and chord middles in order, ``(polylines, 2 chords)``."""
        coarse = np.empty((len(self.a), 2 * self.a.shape[1]))
        coarse[:, 0::2] = self.a
        coarse[:, 1::2] = 0.5 * (self.a + self.b)
        return coarse


def _chord_means_of_ramps(batch: _SparseBatch, ramp_start: np.ndarray, ramp_length: np.ndarray) -> np.ndarray:
    """Mean over each chord of each ramp ``clip(u - start, 0, length)``.

    ``ramp_start`` and ``ramp_length`` are ``(polylines, trials, ramps)``; the result is
    ``(polylines, trials, chords, ramps)``. A chord's direction is the mean of the road's
    heading over the arc it spans (exact on a circle), so a heading that is continuous
    and piecewise linear in ``u`` (a sum of ramps) predicts every chord's heading
    linearly, including chords across a knot.
    """
    start, length = ramp_start[:, :, None, :], ramp_length[:, :, None, :]

    def integral(u: np.ndarray) -> np.ndarray:
        past = np.fmax(u[:, None, :, None] - start, 0.0)
        within = np.minimum(past, length)
        return within * (past - 0.5 * within)

    return (integral(batch.b) - integral(batch.a)) / (batch.b - batch.a)[:, None, :, None]


def _design(batch: _SparseBatch, bounds: np.ndarray, free: np.ndarray | bool) -> tuple[np.ndarray, np.ndarray]:
    """Weighted design matrices of a continuous heading with knots at ``bounds[..., 1:-1]``.

    ``bounds`` is ``(polylines, trials, parts + 1)``; each matrix has a level column and
    one slope (curvature) column per part, zero for the parts not ``free`` (straights).
    Ramps are scaled by their length (at least 1 m) to keep the equations well
    conditioned; also returns that scale, ``(polylines, trials, parts)``.
    """
    ramp_length = np.diff(bounds, axis=-1)
    scale = np.fmax(ramp_length, 1.0)
    ramps = _chord_means_of_ramps(batch, bounds[..., :-1], ramp_length) * (free / scale)[:, :, None, :]
    design = np.concatenate((np.ones(ramps.shape[:-1] + (1,)), ramps), axis=-1)
    return design * batch.root_weight[:, None, :, None], scale


def _least_squares(design: np.ndarray, columns: np.ndarray) -> np.ndarray:
    """Coefficients ``(..., terms, k)`` of the least-squares fit of ``columns`` ``(..., chords, k)``
    on ``design`` ``(..., chords, terms)``, by normal equations regularised so that a
    zero column gets a coefficient of 0."""
    transposed = np.swapaxes(design, -1, -2)
    normal = transposed @ design
    normal += 1e-12 * np.trace(normal, axis1=-2, axis2=-1)[..., None, None] * np.eye(normal.shape[-1])
    return np.linalg.solve(normal, transposed @ columns)


def _fitted_rows(design: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """The least-squares fits ``(polylines, k, chords)`` of the vectors ``rows`` on the columns of ``design``."""
    return np.swapaxes(design @ _least_squares(design, np.swapaxes(rows, 1, 2)), 1, 2)


def _fits(batch: _SparseBatch, bounds: np.ndarray, free: np.ndarray | bool) -> tuple[np.ndarray, np.ndarray]:
    """Weighted residual sum of squares ``(polylines, trials)`` and curvature of each part
    ``(polylines, trials, parts)`` (0 where not ``free``) of the continuous fit for every
    trial ``bounds[p, t]``."""
    free = np.broadcast_to(free, bounds.shape[:2] + (bounds.shape[2] - 1,))
    rows_per_chunk = max(1, MAX_FIT_ELEMENTS // max(1, bounds.shape[1] * batch.a.shape[1] * bounds.shape[2]))
    if len(bounds) > rows_per_chunk:
        chunks = [
            _fits(
                batch.rows(slice(first, first + rows_per_chunk)),
                bounds[first : first + rows_per_chunk],
                free[first : first + rows_per_chunk],
            )
            for first in range(0, len(bounds), rows_per_chunk)
        ]
        return np.concatenate([c[0] for c in chunks]), np.concatenate([c[1] for c in chunks])
    design, scale = _design(batch, bounds, free)
    target = np.broadcast_to((batch.heading * batch.root_weight)[:, None, :, None], design.shape[:-1] + (1,))
    coefficients = _least_squares(design, target)
    residual = (target - design @ coefficients)[..., 0]
    return np.einsum("ptn,ptn->pt", residual, residual), coefficients[..., 1:, 0] / scale * free


def _projected_hinges(
    batch: _SparseBatch, bounds: np.ndarray, candidates: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The residual of the continuous fit with knots ``bounds[:, 1:-1]`` (all parts free),
    ``(polylines, chords)``, and the hinge column of a knot at each candidate with that
    fit's columns projected out, ``(polylines, chords, candidates)``.

    Also returns whether each projected column is far enough from 0 to be a new knot.
    """
    design, _ = _design(batch, bounds[:, None, :], True)
    hinge_length = np.fmax(batch.end[:, None] + 1.0 - candidates, 1.0)
    hinge = _chord_means_of_ramps(batch, candidates[:, None, :], hinge_length[:, None, :])[:, 0]
    hinge *= batch.root_weight[:, :, None]
    columns = np.concatenate(((batch.heading * batch.root_weight)[:, :, None], hinge), axis=2)[:, None]
    projected = (columns - design @ _least_squares(design, columns))[:, 0]
    scale = np.einsum("pnc,pnc->pc", hinge, hinge)
    hinge = projected[:, :, 1:]
    usable = np.einsum("pnc,pnc->pc", hinge, hinge) > 1e-9 * scale
    return projected[:, :, 0], hinge, usable


def _knot_gains(batch: _SparseBatch, bounds: np.ndarray, candidates: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Reduction of the weighted residual from adding a knot at each candidate to the
    continuous fit with knots ``bounds[:, 1:-1]``; ``-inf`` where not ``valid``."""
    residual, hinge, usable = _projected_hinges(batch, bounds, candidates)
    with np.errstate(divide="ignore", invalid="ignore"):
        gain = np.einsum("pn,pnc->pc", residual, hinge) ** 2 / np.einsum("pnc,pnc->pc", hinge, hinge)
    return np.where(valid, np.where(usable, gain, 0.0), -np.inf)


def _coarse_between(batch: _SparseBatch, low: np.ndarray, high: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per polyline, its vertices and chord middles strictly between ``low`` and ``high``,
    in order, ``(polylines, most)``, padded, and which of them are such candidates."""
    coarse = batch.coarse_candidates()
    first = (coarse <= low[:, None]).sum(axis=1)
    count = (coarse < high[:, None]).sum(axis=1) - first
    window = np.arange(max(int(count.max(initial=0)), 1))
    index = np.minimum(first[:, None] + window, coarse.shape[1] - 1)
    return coarse[np.arange(len(coarse))[:, None], index], window < count[:, None]


def _fine_positions(low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """:data:`FINE_KNOT_STEPS` evenly spaced positions strictly between ``low`` and ``high``."""
    fraction = np.arange(1, FINE_KNOT_STEPS + 1) / (FINE_KNOT_STEPS + 1)
    return low[:, None] + (high - low)[:, None] * fraction


def _best_knots(
    batch: _SparseBatch, bounds: np.ndarray, low: np.ndarray, high: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Per polyline, the knot strictly between ``low`` and ``high`` that reduces the
    residual most, and that reduction: searched at the vertices and chord middles, then
    finely around the best (``low`` and 0 where there is no candidate)."""
    rows = np.arange(len(bounds))
    coarse, valid = _coarse_between(batch, low, high)
    gain = _knot_gains(batch, bounds, coarse, valid)
    best = np.argmax(gain, axis=1)
    best_gain = gain[rows, best]
    before, after = best - 1, np.minimum(best + 1, coarse.shape[1] - 1)
    fine_low = np.where((best > 0) & valid[rows, before], coarse[rows, before], low)
    fine_high = np.where((best + 1 < coarse.shape[1]) & valid[rows, after], coarse[rows, after], high)
    fine = _fine_positions(fine_low, fine_high)
    fine_gain = _knot_gains(batch, bounds, fine, np.ones(fine.shape, dtype=bool))
    fine_best = np.argmax(fine_gain, axis=1)
    use_fine = fine_gain[rows, fine_best] > best_gain
    knot = np.where(use_fine, fine[rows, fine_best], coarse[rows, best])
    knot_gain = np.where(use_fine, fine_gain[rows, fine_best], best_gain)
    found = valid.any(axis=1)
    return np.where(found, knot, low), np.where(found, knot_gain, 0.0)


def _best_knot_pairs(batch: _SparseBatch, bounds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per polyline, the two knots at vertices or chord middles that together reduce the
    residual most, ``(polylines, 2)``, and that reduction. A curve between straights, or
    one shorter than the chords around it, needs both its knots before either pays off
    on its own."""
    coarse, valid = _coarse_between(batch, np.zeros(len(bounds)), batch.end)
    residual, hinge, usable = _projected_hinges(batch, bounds, coarse)
    gram = np.einsum("pnc,pnd->pcd", hinge, hinge)
    along = np.einsum("pn,pnc->pc", residual, hinge)
    diagonal = np.einsum("pcc->pc", gram)
    outer_diagonal = diagonal[:, :, None] * diagonal[:, None, :]
    determinant = outer_diagonal - gram**2
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        gain = (
            along[:, :, None] ** 2 * diagonal[:, None, :]
            - 2.0 * along[:, :, None] * along[:, None, :] * gram
            + diagonal[:, :, None] * along[:, None, :] ** 2
        ) / determinant
    gain = np.where(determinant > 1e-6 * outer_diagonal, gain, 0.0)
    candidate = valid & usable
    pair = candidate[:, :, None] & candidate[:, None, :] & np.triu(np.ones(gram.shape[1:], dtype=bool), 1)
    gain = np.where(pair, gain, -np.inf).reshape(len(bounds), -1)
    best = np.argmax(gain, axis=1)
    first, second = np.unravel_index(best, gram.shape[1:])
    rows = np.arange(len(bounds))
    return np.column_stack((coarse[rows, first], coarse[rows, second])), np.fmax(gain[rows, best], 0.0)


def _trimmed(bounds: np.ndarray, knots: np.ndarray) -> np.ndarray:
    """``bounds`` without the padding columns that no polyline needs."""
    return bounds[:, : int(knots.max(initial=0)) + 2]


def _with_knots(bounds: np.ndarray, knots: np.ndarray) -> np.ndarray:
    """Each row's bounds with its new ``knots`` ``(polylines, new)`` put in order (into the padding)."""
    bounds = np.concatenate((bounds, np.repeat(bounds[:, -1:], knots.shape[1], axis=1)), axis=1)
    bounds[:, -knots.shape[1] :] = knots
    return np.sort(bounds, axis=1)


def _without_knot(bounds: np.ndarray, knot: np.ndarray) -> np.ndarray:
    """Each row's bounds with its knot ``knot[p]`` (a column index) made padding."""
    bounds = bounds.copy()
    bounds[np.arange(len(bounds)), knot] = bounds[:, -1]
    return np.sort(bounds, axis=1)


def _refined_knots(
    batch: _SparseBatch, bounds: np.ndarray, knots: np.ndarray, near: np.ndarray | None = None
) -> np.ndarray:
    """Each knot in turn moved to where it fits best between its neighbours (only the
    knots marked ``near``, ``(polylines, columns)``, if given)."""
    bounds = bounds.copy()
    for _ in range(SPARSE_REFINE_PASSES):
        for column in range(1, int(knots.max(initial=0)) + 1):
            rows = np.flatnonzero((knots >= column) & (True if near is None else near[:, column]))
            if rows.size == 0:
                continue
            others = _trimmed(bounds[rows], knots[rows]).copy()
            low, high = others[:, column - 1].copy(), others[:, column + 1].copy()
            others[:, column] = low  # a part of no length: the knot is gone
            bounds[rows, column] = _best_knots(batch.rows(rows), others, low, high)[0]
    return bounds


def _knot_fit(batch: _SparseBatch, limit: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Knots of the continuous heading: added one at a time while the best one reduces
    the residual by more than ``limit``, then the least significant dropped while it
    does not.

    Returns the bounds, padded with each polyline's end, and the number of knots.
    """
    most_knots = batch.count // 2
    # Room for one knot more than most_knots: a pair may be added to most_knots - 1.
    bounds = np.column_stack((np.zeros(len(batch.a)), np.repeat(batch.end[:, None], int(most_knots.max()) + 2, axis=1)))
    knots = np.zeros(len(bounds), dtype=np.int64)
    adding = np.ones(len(bounds), dtype=bool)
    while (active := np.flatnonzero(adding & (knots < most_knots))).size:
        knot, gain = _best_knots(
            batch.rows(active), _trimmed(bounds[active], knots[active]), np.zeros(len(active)), batch.end[active]
        )
        single = gain > limit[active]
        rest = active[~single]
        pair, pair_gain = np.empty((0, 2)), np.empty(0)
        if rest.size:
            pair, pair_gain = _best_knot_pairs(batch.rows(rest), _trimmed(bounds[rest], knots[rest]))
        paired = pair_gain > PAIR_THRESHOLD_FACTOR * limit[rest]
        adding[rest[~paired]] = False
        changed = np.concatenate((active[single], rest[paired]))
        new = np.concatenate((np.column_stack((knot[single], knot[single])), pair[paired]))
        new[: single.sum(), 1] = bounds[active[single], -1]  # one knot: the other is padding
        knots[changed] += np.concatenate((np.ones(single.sum(), dtype=np.int64), np.full(paired.sum(), 2)))
        bounds[changed] = _with_knots(bounds[changed], new)[:, : bounds.shape[1]]
        # A new knot moves its neighbours' best places; the knots further away keep theirs.
        is_new = (bounds[changed][:, :, None] == new[:, None, :]).any(axis=2)
        near = is_new | np.roll(is_new, 1, axis=1) | np.roll(is_new, -1, axis=1)
        bounds[changed] = _refined_knots(batch.rows(changed), bounds[changed], knots[changed], near)
    dropping = knots > 0
    while (active := np.flatnonzero(dropping & (knots > 0))).size:
        rows = batch.rows(active)
        trial_bounds = _trimmed(bounds[active], knots[active])
        full = _fits(rows, trial_bounds[:, None, :], True)[0][:, 0]
        trials = np.repeat(trial_bounds[:, None, :], trial_bounds.shape[1] - 2, axis=1)
        column = np.arange(1, trial_bounds.shape[1] - 1)
        trials[:, np.arange(len(column)), column] = trials[:, np.arange(len(column)), column - 1]
        loss = _fits(rows, trials, True)[0] - full[:, None]
        loss[column[None, :] > knots[active][:, None]] = np.inf
        weakest = np.argmin(loss, axis=1)
        drop = loss[np.arange(len(active)), weakest] <= limit[active]
        dropping[active[~drop]] = False
        changed = active[drop]
        knots[changed] -= 1
        bounds[changed] = _without_knot(bounds[changed], weakest[drop] + 1)
        bounds[changed] = _refined_knots(batch.rows(changed), bounds[changed], knots[changed])
    return bounds, knots


def _moved_knot_residuals(
    batch: _SparseBatch, bounds: np.ndarray, free: np.ndarray, column: int, positions: np.ndarray
) -> np.ndarray:
    """Weighted residual sum of squares ``(polylines, trials)`` of the continuous fit (only
    the ``free`` parts curved) with the knot ``bounds[:, column]`` moved to each of
    ``positions`` ``(polylines, trials)``.

    Only the slopes of the two parts beside the knot change with it, so the fit of the
    other columns is made once per polyline and each trial adds two projected columns.
    """
    fixed_free = free.copy()
    fixed_free[:, column - 1 : column + 1] = False
    fixed = _design(batch, bounds[:, None, :], fixed_free[:, None, :])[0][:, 0]
    low, high = bounds[:, column - 1 : column], bounds[:, column + 1 : column + 2]
    before_m, after_m = positions - low, high - positions
    # The ramps of the two parts add up to one ramp from low to high, wherever the knot is.
    before = _chord_means_of_ramps(batch, np.broadcast_to(low, positions.shape)[:, :, None], before_m[:, :, None])[
        ..., 0
    ]
    both = _chord_means_of_ramps(batch, low[:, :, None], (high - low)[:, :, None])[..., 0]
    root_weight = batch.root_weight[:, None, :]
    after = (both - before) * (root_weight * (free[:, column, None] / np.fmax(after_m, 1.0))[:, :, None])
    before *= root_weight * (free[:, column - 1, None] / np.fmax(before_m, 1.0))[:, :, None]
    trials = positions.shape[1]
    rows = np.concatenate(((batch.heading * batch.root_weight)[:, None, :], before, after), axis=1)
    projected = rows - _fitted_rows(fixed, rows)
    residual, added = projected[:, :1], projected[:, 1:]
    # A column the fixed ones (nearly) contain adds nothing; its rounding noise must not either.
    added *= (np.einsum("ptn,ptn->pt", added, added) > 1e-9 * np.einsum("ptn,ptn->pt", rows[:, 1:], rows[:, 1:]))[
        ..., None
    ]
    added_before, added_after = added[:, :trials], added[:, trials:]
    g00 = np.einsum("ptn,ptn->pt", added_before, added_before)
    g11 = np.einsum("ptn,ptn->pt", added_after, added_after)
    g01 = np.einsum("ptn,ptn->pt", added_before, added_after)
    b0, b1 = (np.einsum("pn,ptn->pt", residual[:, 0], added_part) for added_part in (added_before, added_after))
    determinant = g00 * g11 - g01**2
    with np.errstate(divide="ignore", invalid="ignore"):
        both_explained = (g11 * b0**2 - 2.0 * g01 * b0 * b1 + g00 * b1**2) / determinant
        one_explained = np.fmax(np.where(g00 > 0, b0**2 / g00, 0.0), np.where(g11 > 0, b1**2 / g11, 0.0))
    explained = np.where(determinant > 1e-12 * g00 * g11, both_explained, one_explained)
    return np.einsum("pn,pn->p", residual[:, 0], residual[:, 0])[:, None] - explained


def _refined_constrained(
    batch: _SparseBatch, bounds: np.ndarray, knots: np.ndarray, free: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Each knot in turn moved to where the fit with only the ``free`` parts curved is
    best, between its neighbours; returns the knots and the residual."""
    bounds = bounds.copy()
    residual = _fits(batch, bounds[:, None, :], free[:, None, :])[0][:, 0]
    for column in range(1, int(knots.max(initial=0)) + 1):
        # A knot between two straights changes nothing wherever it is.
        rows = np.flatnonzero((knots >= column) & (free[:, column - 1] | free[:, column]))
        if rows.size == 0:
            continue
        low, high = bounds[rows, column - 1], bounds[rows, column + 1]
        coarse, coarse_valid = _coarse_between(batch.rows(rows), low, high)
        # The knot's present place last: moves must beat it as computed the same way.
        positions = np.concatenate((coarse, _fine_positions(low, high), bounds[rows, column : column + 1]), axis=1)
        valid = np.concatenate((coarse_valid, np.ones((len(rows), FINE_KNOT_STEPS + 1), dtype=bool)), axis=1)
        trial_residual = np.where(
            valid, _moved_knot_residuals(batch.rows(rows), bounds[rows], free[rows], column, positions), np.inf
        )
        best = np.argmin(trial_residual[:, :-1], axis=1)
        best_residual = trial_residual[np.arange(len(rows)), best]
        better = best_residual < trial_residual[:, -1]
        bounds[rows[better], column] = positions[better, best[better]]
        residual[rows] = np.where(better, best_residual, trial_residual[:, -1])
    return bounds, residual


def _with_straights(
    batch: _SparseBatch, bounds: np.ndarray, knots: np.ndarray, limit: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Parts made straight (curvature 0) one at a time, the knots moved to fit, while the
    residual grows by less than ``limit``: a curvature must earn its place.

    Returns the bounds and which parts stay curved.
    """
    bounds = bounds.copy()
    free = np.arange(bounds.shape[1] - 1)[None, :] <= knots[:, None]
    residual = _fits(batch, bounds[:, None, :], free[:, None, :])[0][:, 0]
    going = np.array(free.any(axis=1), dtype=bool)
    while (active := np.flatnonzero(going)).size:
        polyline, part = np.nonzero(free[active])
        polyline = active[polyline]
        trial_free = free[polyline]
        trial_free[np.arange(len(part)), part] = False
        # Only the parts whose straightening costs least with the knots held are tried with them moved.
        held = _fits(batch.rows(polyline), bounds[polyline][:, None, :], trial_free[:, None, :])[0][:, 0]
        order = np.lexsort((held, polyline))
        rank = np.arange(len(order)) - np.searchsorted(polyline[order], polyline[order])
        screened = np.sort(order[rank < STRAIGHT_SCREEN])
        polyline, trial_free = polyline[screened], trial_free[screened]
        trial_bounds, trial_residual = _refined_constrained(
            batch.rows(polyline), bounds[polyline], knots[polyline], trial_free
        )
        # The best trial of each polyline (trials are grouped by polyline, in order).
        order = np.lexsort((trial_residual, polyline))
        best = order[np.searchsorted(polyline[order], active)]
        accept = trial_residual[best] - residual[active] <= limit[active]
        going[active[~accept]] = False
        best, changed = best[accept], active[accept]
        bounds[changed, : trial_bounds.shape[1]] = trial_bounds[best]
        residual[changed] = trial_residual[best]
        free[changed] = trial_free[best]
        going[changed] = free[changed].any(axis=1)
    return bounds, free


# The polish: the road model fitted to the nodes themselves. A chord's heading is a poor
# measurement on a map way: two neighbouring chords share a noisy node, and a short chord's
# heading is mostly noise. The maximum-likelihood road is the one whose distance to the
# nodes is least, so the heading fit's parts are finally fitted in the plane: the road
# starts near the first node with a heading and runs through its parts (straights and
# arcs joined without kinks, 3.4-3.8); every node is projected onto it, and knots,
# curvatures and the start are moved by Levenberg-Marquardt steps on the nodes' sideways
# distances. Points are complex numbers x + iy.
