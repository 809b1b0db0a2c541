"""Finds where the curvature of a dense polyline changes along a clothoid (transition curves).

The dense fit (:mod:`csws.curvature.dense`) cuts heading against arc length into parts
of constant curvature. Where the road has a clothoid (a spiral, curvature linear in arc
length) between two parts, that fit is a staircase: one or more short parts of
intermediate radius, or a single step somewhere inside the spiral. Either puts the
curve start (3.4) and end (3.5), where the radius crosses R_c, metres away from where
the road's radius does.

Here every such staircase is put to the data as a clothoid instead: between two constant
parts ``i`` and ``j`` and the stairs between them (parts whose curvatures lie between, in
order), the road whose curvature runs from ``k_i`` to ``k_j`` along a clothoid from ``s1`` to
``s2`` is fitted to the chords' headings for every ``(s1, s2)`` of a grid
(:mod:`csws.curvature.clothoid_fit`); this module decides which fits replace their stairs.

The clothoid replaces the staircase when its residual, plus :data:`PARAMETER_PENALTY` for
each parameter it has more than the staircase (or less, for two or more stairs), is
smaller, and when it beats the best single step of the same stretch (a clothoid of no
length) by more than :data:`PARAMETER_PENALTY` (by anything, when it is :data:`LONG_SPIRAL_M`
long or more) and is at least :data:`MIN_SPIRAL_M` long: so an arc that meets a straight at a
point, a compound curve of directly joined arcs (3.8), or one of true constant-radius
parts, keeps its steps.

Residuals are those of the chords' headings. A long clothoid that fails there is judged
once more on the road's sideways offsets (:func:`_kept_on_offsets`; the step must then be
beaten by more than :data:`PARAMETER_PENALTY`): a
chord's heading error is the difference of its two vertices' sideways errors, so a
deviation that lasts tens of metres, as a gentle clothoid's from a step does, hardly
shows in headings, while it moves every vertex it spans (a 20 m spiral into R 330 m moves
the road about 2 cm, seven times the noise of centimetre rounding, over forty vertices).
Short candidates are judged on headings alone: rounding regularly spaced vertices leaves
sideways errors that run together over metres, which false clothoids of a few metres fit.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial

import numpy as np

from .clothoid_fit import (
    COARSE_STEP_M,
    FINE_STEP_M,
    _best_spiral,
    _best_step,
    _Chords,
    _grid,
    _least_on_grid,
    _Moments,
    _part_residual,
    _sideways_residuals,
    _spiral_integrals,
    _staircase_integrals,
)

#: How far beyond the outermost step of a staircase a spiral may start or end, m: the
#: longest transition curves of road design (80-120 m at motorway radii) put a single
#: step up to about half their length inside them.
SPIRAL_REACH_M = 120.0
#: How far the second search of a clothoid's ends looks around where they are, m.
REPOLISH_REACH_M = 2.0
#: Shortest clothoid kept, m. Chords straddling a step between two arcs make a clothoid of
#: a few metres fit a little better than the step itself; road design's transitions are
#: longer (a clothoid parameter A of at least R / 3 makes one at least R / 9 long).
MIN_SPIRAL_M = 5.0
#: A clothoid at least this long need only fit better than a step, m: the false clothoids
#: that noise and chords straddling a step make are shorter (under 6 m on cm-rounded
#: shapes), and road design's transitions longer (R / 9 for R >= 135 m). A gentle
#: spiral fits little better than a step, yet the step puts the curve start metres off.
LONG_SPIRAL_M = 15.0
#: Passes searching every clothoid's ends again once all are placed.
REPOLISH_PASSES = 2
#: Least share of a constant part its neighbouring spiral leaves it (a spiral may not eat a part whole).
KEPT_PART_M = 0.5
#: What each parameter a model has more must gain in normalised residual (Akaike's 2): on
#: dense cm-rounded arcs the best false clothoid at a step gains under 1, while the
#: clothoids of real spirals gain from 1 to several hundred.
PARAMETER_PENALTY = 2.0
#: Parameters of the two models of one staircase: a clothoid has an offset, two
#: curvatures and two ends; each part of the staircase a line (offset and slope), and
#: a clothoid in it one more (a parabola).
SPIRAL_PARAMETERS = 5
PART_PARAMETERS = 2


def _staircases(start_k: np.ndarray, end_k: np.ndarray) -> list[tuple[int, int]]:
    """Pairs ``(i, j)`` of constant parts, ``j > i``, whose parts between (stairs, or clothoids
    placed earlier) take the curvature from one to the other in order: the staircases one
    clothoid may replace."""
    is_spiral = start_k != end_k
    pairs = []
    for i in np.flatnonzero(~is_spiral):
        for j in range(i + 1, len(start_k)):
            values = np.column_stack((start_k[i : j + 1], end_k[i : j + 1])).ravel()
            direction = np.sign(end_k[j] - start_k[i])
            if direction == 0 or np.any(np.diff(values) * direction < 0):
                break
            if not is_spiral[j] and not (j == i + 2 and is_spiral[i + 1]):  # one clothoid between is the target form
                pairs.append((int(i), j))
    return pairs


def with_transitions(
    mid_s: np.ndarray,
    heading: np.ndarray,
    weight: np.ndarray,
    noise_variance: float,
    length_m: np.ndarray,
    bounds: np.ndarray,
    curvature: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Replace the staircases of one dense polyline's constant-curvature parts by clothoids
    where the headings say so.

    Parameters
    ----------
    mid_s, heading, weight
        The polyline's chords: middle arc length (ascending), unwrapped heading and weight
        (their headings' inverse variance, up to ``noise_variance``).
    noise_variance
        The heading variance of a chord of weight 1.
    length_m
        The chords' lengths.
    bounds, curvature
        Its parts: ``len(curvature) + 1`` bounds from 0 to its length, one curvature each.

    Returns
    -------
    bounds, start_curvature, end_curvature
        The parts after: constant ones with equal start and end curvature, clothoids
        (spirals) with the curvature changing linearly from start to end.
    """
    chords = _Chords(mid_s, heading, weight, noise_variance, np.asarray(length_m, dtype=float))
    bounds = np.asarray(bounds, dtype=float)
    start_k = np.asarray(curvature, dtype=float).copy()
    end_k = start_k.copy()
    replaced = False
    for _ in range(len(start_k)):  # each replacement leaves fewer stairs
        improvement = _best_replacement(chords, bounds, start_k, end_k)
        if improvement is None:
            break
        bounds, start_k, end_k = improvement
        # Each clothoid was fitted with its two neighbours alone: one refit of the whole
        # polyline makes every part meet its neighbours before the next staircase is judged.
        start_k, end_k = _continuous_refit(chords, bounds, start_k != end_k, start_k)
        replaced = True
    if replaced:
        for _ in range(REPOLISH_PASSES):
            bounds = _repolished(chords, bounds, start_k != end_k)
        merged_bounds, start_k, is_spiral = _merged_steps(chords, bounds, start_k, start_k != end_k)
        if len(merged_bounds) < len(bounds):
            for _ in range(REPOLISH_PASSES):
                merged_bounds = _repolished(chords, merged_bounds, is_spiral)
        bounds = merged_bounds
        start_k, end_k = _continuous_refit(chords, bounds, is_spiral, start_k)
    return bounds, start_k, end_k


def _merged_steps(
    chords: _Chords, bounds: np.ndarray, start_k: np.ndarray, is_spiral: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Neighbouring constant parts joined where one line fits their headings as well as two.

    A clothoid placed beside a constant part can leave a sliver of it (down to
    :data:`KEPT_PART_M`), or split an arc where the stairs it replaced met, with a second
    curvature that only the noise supports. A step between two constant parts is kept
    when its two lines gain more than :data:`PARAMETER_PENALTY` for each of their two
    parameters more (a curvature and a knot).
    """
    bounds, start_k, is_spiral = bounds.copy(), start_k.copy(), is_spiral.copy()
    while True:
        costs = []
        for i in np.flatnonzero(~is_spiral[:-1] & ~is_spiral[1:]):
            rows = [slice(*np.searchsorted(chords.mid_s, (bounds[k], bounds[k + 1]))) for k in (i, i + 1, i)]
            rows[2] = slice(rows[0].start, rows[1].stop)
            two = _part_residual(chords, rows[0], False) + _part_residual(chords, rows[1], False)
            gain = (_part_residual(chords, rows[2], False) - two) / chords.noise_variance
            costs.append((gain, int(i)))
        if not costs or min(costs)[0] >= 2 * PARAMETER_PENALTY:
            return bounds, start_k, is_spiral
        _, i = min(costs)  # type: ignore[assignment]  # the loop's numpy index, here a plain int
        lengths = np.diff(bounds)[i : i + 2]
        start_k[i] = float(np.average(start_k[i : i + 2], weights=lengths + 1e-9))
        bounds = np.delete(bounds, i + 1)
        start_k = np.delete(start_k, i + 1)
        is_spiral = np.delete(is_spiral, i + 1)


def _repolished(chords: _Chords, bounds: np.ndarray, is_spiral: np.ndarray) -> np.ndarray:
    """``bounds`` with the ends of every clothoid searched again between its neighbours as they
    are now: a clothoid placed before its neighbour's other clothoid was lies where the
    neighbour's first, longer extent put it."""
    bounds = bounds.copy()
    for part in np.flatnonzero(is_spiral):
        low, high = bounds[part - 1] + KEPT_PART_M, bounds[part + 2] - KEPT_PART_M
        rows = slice(*np.searchsorted(chords.mid_s, (bounds[part - 1], bounds[part + 2])))
        if high <= low or rows.stop - rows.start < SPIRAL_PARAMETERS + 1:
            continue
        s1_values = _grid(
            max(low, bounds[part] - REPOLISH_REACH_M),
            min(bounds[part + 1], bounds[part] + REPOLISH_REACH_M),
            FINE_STEP_M,
        )
        s2_values = _grid(
            max(bounds[part], bounds[part + 1] - REPOLISH_REACH_M),
            min(high, bounds[part + 1] + REPOLISH_REACH_M),
            FINE_STEP_M,
        )
        _, s1, s2, _ = _least_on_grid(_Moments(chords, rows), s1_values, s2_values)
        bounds[part], bounds[part + 1] = s1, s2
    return bounds


def _continuous_refit(
    chords: _Chords, bounds: np.ndarray, is_spiral: np.ndarray, curvature: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Start and end curvature of every part refitted to all of the polyline's headings at once,
    with the heading continuous and each clothoid's curvature meeting its neighbours'.

    Each replacement fitted its clothoid with the two parts beside it alone; a part between
    two clothoids is refitted here with both, so the profile is one continuous road.
    Parts of constant curvature keep one value (steps between two of them stay steps).
    """
    # One curvature value per constant part; a clothoid starts at the value of the part
    # before it and ends at that of the part after it.
    start_level = np.cumsum(~is_spiral) - 1
    end_level = start_level + is_spiral
    start, length = bounds[:-1], np.diff(bounds)
    t = np.clip(chords.mid_s[:, None] - start, 0.0, length)
    with np.errstate(divide="ignore", invalid="ignore"):
        rising = np.where(length > 0, t * t / (2.0 * length), 0.0)
    design = np.zeros((len(chords.mid_s), int(end_level[-1]) + 2))
    design[:, 0] = 1.0
    np.add.at(design.T, start_level + 1, (t - rising).T)
    np.add.at(design.T, end_level + 1, rising.T)
    root_weight = np.sqrt(chords.weight)
    solution, *_ = np.linalg.lstsq(design * root_weight[:, None], chords.heading * root_weight, rcond=None)
    values = solution[1:]
    if not np.all(np.isfinite(values)):
        return curvature, curvature
    return values[start_level], values[end_level]


def _best_replacement(chords: _Chords, bounds: np.ndarray, start_k: np.ndarray, end_k: np.ndarray):
    """The parts with the one staircase replaced whose clothoid gains most, or None where none is kept."""
    is_spiral = start_k != end_k
    best_gain, best = -np.inf, None
    for i, j in _staircases(start_k, end_k):
        rows = slice(*np.searchsorted(chords.mid_s, (bounds[i], bounds[j + 1])))
        if rows.stop - rows.start < SPIRAL_PARAMETERS + 1:
            continue
        moments = _Moments(chords, rows)
        s1_range = (max(bounds[i] + KEPT_PART_M, bounds[i + 1] - SPIRAL_REACH_M), bounds[i + 1])
        s2_range = (bounds[j], min(bounds[j + 1] - KEPT_PART_M, bounds[j] + SPIRAL_REACH_M))
        if s1_range[0] > s1_range[1] or s2_range[0] > s2_range[1]:
            continue
        residual, s1, s2, solution = _best_spiral(moments, s1_range, s2_range)
        if s2 - s1 < MIN_SPIRAL_M:
            continue
        stairs = sum(
            _part_residual(chords, slice(*np.searchsorted(chords.mid_s, (bounds[k], bounds[k + 1]))), is_spiral[k])
            for k in range(i, j + 1)
        )
        stair_parameters = PART_PARAMETERS * (j - i + 1) + int(is_spiral[i : j + 1].sum())
        penalty = PARAMETER_PENALTY * (stair_parameters - SPIRAL_PARAMETERS)
        gain = (stairs - residual) / chords.noise_variance + penalty
        step_s, step = _best_step(moments, s1_range[0], s2_range[1])
        long = s2 - s1 >= LONG_SPIRAL_M
        kept = gain > 0 and (step - residual) / chords.noise_variance > (0.0 if long else PARAMETER_PENALTY)
        if not kept and long:
            kept = _kept_on_offsets(chords, rows, bounds[i : j + 2], is_spiral[i : j + 1], (s1, s2), step_s, penalty)
        if kept and gain > best_gain:
            _, k_i, k_change = solution
            best_gain = gain
            best = (i, j, s1, s2, k_i, k_i + k_change)
    if best is None:
        return None
    i, j, s1, s2, k_i, k_j = best
    new_bounds = np.concatenate((bounds[: i + 1], [s1, s2], bounds[j + 1 :]))
    new_start = np.concatenate((start_k[:i], [k_i, k_i, k_j], start_k[j + 1 :]))
    new_end = np.concatenate((end_k[:i], [k_i, k_j, k_j], end_k[j + 1 :]))
    return new_bounds, new_start, new_end


def _kept_on_offsets(
    chords: _Chords,
    rows: slice,
    stair_bounds: np.ndarray,
    stair_is_spiral: np.ndarray,
    spiral: tuple[float, float],
    step_s: float,
    penalty: float,
) -> bool:
    """Whether a long clothoid from ``spiral[0]`` to ``spiral[1]`` beats, on the sideways
    offsets, the staircase it would replace (with ``penalty`` for the parameters that has
    more) and, by more than :data:`PARAMETER_PENALTY`, the best single step near ``step_s``."""
    step_values = _grid(step_s - COARSE_STEP_M, step_s + COARSE_STEP_M, FINE_STEP_M)
    models: list[Callable[[np.ndarray], np.ndarray]] = [partial(_spiral_integrals, s1=spiral[0], s2=spiral[1])]
    models.append(partial(_staircase_integrals, bounds=stair_bounds, is_spiral=stair_is_spiral))
    models += [partial(_spiral_integrals, s1=float(x), s2=float(x)) for x in step_values]
    residuals = _sideways_residuals(chords, rows, models)
    spiral_residual, stairs_residual, step_residual = residuals[0], residuals[1], residuals[2:].min()
    return bool(stairs_residual - spiral_residual + penalty > 0 and step_residual - spiral_residual > PARAMETER_PENALTY)
