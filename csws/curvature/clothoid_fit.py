"""Fits a road whose curvature runs along a clothoid between two constant parts to a stretch of a polyline's chords.

The measuring half of the transition-curve search (:mod:`csws.curvature.transitions` decides
which staircases become clothoids). Between two constant parts with curvatures ``k_i`` and
``k_j``, the heading of a road that runs ``k_i`` up to ``s1``, changes linearly to ``k_j`` at
``s2`` and runs ``k_j`` on is

    theta(s) = c + k_i (s - s1) + (k_j - k_i) g(s),
    g(s) = 0 before s1, (s - s1)^2 / 2L on the spiral (L = s2 - s1), s - s1 - L/2 after,

linear in ``(c, k_i, k_j - k_i)`` for given ``(s1, s2)``. Running sums of the chords'
weighted powers of arc length (:class:`_Moments`) give the least-squares fit for every
``(s1, s2)`` of a grid in a few array operations; the best is refined on a finer grid
(:func:`_best_spiral`; a step, a clothoid of no length, :func:`_best_step`). A stretch fitted
part by part, a line on each constant part and a parabola on each clothoid, is
:func:`_part_residual`.

The same models are also judged on the road's sideways offsets (:func:`_sideways_residuals`):
a chord's heading error is the difference of its two vertices' sideways errors, so a
deviation that lasts tens of metres hardly shows in headings, while it moves every vertex it
spans.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

#: Grid steps of the spiral-end search: coarse over the whole reach, then fine around the best, m.
COARSE_STEP_M = 2.0
FINE_STEP_M = 0.1


@dataclass(frozen=True)
class _Chords:
    """One polyline's chords: middle arc length, heading (unwrapped), weight (inverse
    heading variance in units of the noise variance ``noise_variance``) and length."""

    mid_s: np.ndarray
    heading: np.ndarray
    weight: np.ndarray
    noise_variance: float
    length_m: np.ndarray


def _part_residual(chords: _Chords, rows: slice, spiral: bool) -> float:
    """Weighted residual sum of squares of heading against arc length over ``rows`` fitted alone:
    a line on a part of constant curvature, a parabola on a clothoid."""
    w, s, h = chords.weight[rows], chords.mid_s[rows], chords.heading[rows]
    degree = 2 if spiral else 1
    if w.sum() <= 0 or len(s) <= degree:
        return 0.0
    s = s - s.mean()
    design = np.column_stack([s**k for k in range(degree + 1)]) * np.sqrt(w)[:, None]
    target = h * np.sqrt(w)
    solution, *_ = np.linalg.lstsq(design, target, rcond=None)
    return float(np.sum((design @ solution - target) ** 2))


class _Moments:
    """Running sums over a stretch of chords of w s^k (k = 0..4), w s^k h (k = 0..2) and w h^2,
    in arc length and heading centred on the stretch (keeps the powers small)."""

    def __init__(self, chords: _Chords, rows: slice) -> None:
        self.mid_s = chords.mid_s[rows]
        self.origin_s = float(self.mid_s.mean())
        s = self.mid_s - self.origin_s
        h = chords.heading[rows] - float(chords.heading[rows].mean())
        w = chords.weight[rows]
        terms = [w * s**k for k in range(5)] + [w * s**k * h for k in range(3)] + [w * h * h]
        self.sums = np.concatenate((np.zeros((9, 1)), np.cumsum(terms, axis=1)), axis=1)

    def between(self, first: np.ndarray, stop: np.ndarray) -> np.ndarray:
        """The nine sums over chords ``first:stop``, ``(9, ...)``."""
        return self.sums[:, stop] - self.sums[:, first]

    def residual(self, s1: np.ndarray, s2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Weighted residual of the best clothoid road with its spiral from ``s1`` to ``s2`` (arrays),
        and that road's parameters."""
        first = np.searchsorted(self.mid_s, s1)
        stop = np.searchsorted(self.mid_s, s2)
        end = np.full_like(first, len(self.mid_s))
        whole = self.between(np.zeros_like(first), end)
        spiral = self.between(first, stop)
        after = self.between(stop, end)
        a, length = s1 - self.origin_s, s2 - s1
        with np.errstate(divide="ignore", invalid="ignore"):
            half = np.where(length > 0, 0.5 / length, 0.0)
        # On the spiral, g = u^2 / 2L with u = s - s1.
        u2 = spiral[2] - 2 * a * spiral[1] + a * a * spiral[0]
        su2 = spiral[3] - 2 * a * spiral[2] + a * a * spiral[1]
        u4 = spiral[4] - 4 * a * spiral[3] + 6 * a**2 * spiral[2] - 4 * a**3 * spiral[1] + a**4 * spiral[0]
        u2h = spiral[7] - 2 * a * spiral[6] + a * a * spiral[5]
        # After it, g = s - m with m = s1 + L/2.
        m = a + length / 2
        g = half * u2 + after[1] - m * after[0]
        sg = half * su2 + after[2] - m * after[1]
        gg = half * half * u4 + after[2] - 2 * m * after[1] + m * m * after[0]
        gh = half * u2h + after[6] - m * after[5]
        normal = np.stack(
            (
                np.stack((whole[0], whole[1], g), axis=-1),
                np.stack((whole[1], whole[2], sg), axis=-1),
                np.stack((g, sg, gg), axis=-1),
            ),
            axis=-2,
        )
        right = np.stack((whole[5], whole[6], gh), axis=-1)
        solution = _solved(normal, right)
        return np.fmax(whole[8] - np.sum(solution * right, axis=-1), 0.0), solution


def _solved(normal: np.ndarray, right: np.ndarray) -> np.ndarray:
    """Solutions of many symmetric 3 x 3 normal equations by their adjugates (Cramer's rule);
    a singular one (a spiral over no chord, where the third column vanishes) by the first two."""
    (a, b, c), (_, d, e), (_, _, f) = (normal[..., i, :].T for i in range(3))
    adjugate = np.stack(
        (
            np.stack((d * f - e * e, c * e - b * f, b * e - c * d), axis=-1),
            np.stack((c * e - b * f, a * f - c * c, b * c - a * e), axis=-1),
            np.stack((b * e - c * d, b * c - a * e, a * d - b * b), axis=-1),
        ),
        axis=-2,
    )
    determinant = a * adjugate[..., 0, 0] + b * adjugate[..., 1, 0] + c * adjugate[..., 2, 0]
    regular = np.abs(determinant) > 1e-12 * np.abs(normal).max(axis=(-2, -1)) ** 3
    with np.errstate(divide="ignore", invalid="ignore"):
        solution = np.einsum("...ij,...j->...i", adjugate, right) / determinant[..., None]
    line_determinant = a * d - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        line = np.stack(
            (
                (d * right[..., 0] - b * right[..., 1]) / line_determinant,
                (a * right[..., 1] - b * right[..., 0]) / line_determinant,
                np.zeros_like(a),
            ),
            axis=-1,
        )
    return np.nan_to_num(np.where(regular[..., None], solution, line))


def _grid(low: float, high: float, step: float) -> np.ndarray:
    """Points from ``low`` to ``high`` about ``step`` apart, both ends included."""
    return np.linspace(low, high, max(2, int(np.ceil((high - low) / step)) + 1)) if high > low else np.array([low])


def _best_spiral(
    moments: _Moments, s1_range: tuple[float, float], s2_range: tuple[float, float]
) -> tuple[float, float, float, np.ndarray]:
    """The spiral ends with the least residual in the given ranges: ``(residual, s1, s2, solution)``."""
    centre1, centre2 = _least_on_grid(moments, _grid(*s1_range, COARSE_STEP_M), _grid(*s2_range, COARSE_STEP_M))[1:3]
    fine1 = _grid(max(s1_range[0], centre1 - COARSE_STEP_M), min(s1_range[1], centre1 + COARSE_STEP_M), FINE_STEP_M)
    fine2 = _grid(max(s2_range[0], centre2 - COARSE_STEP_M), min(s2_range[1], centre2 + COARSE_STEP_M), FINE_STEP_M)
    return _least_on_grid(moments, fine1, fine2)


def _best_step(moments: _Moments, low: float, high: float) -> tuple[float, float]:
    """Where a road whose curvature steps at one point between ``low`` and ``high`` (a
    clothoid of no length) fits the headings best, and its residual: the step a clothoid
    must beat."""
    coarse = _grid(low, high, COARSE_STEP_M)
    centre = coarse[int(np.argmin(moments.residual(coarse, coarse)[0]))]
    fine = _grid(max(low, centre - COARSE_STEP_M), min(high, centre + COARSE_STEP_M), FINE_STEP_M)
    residual = moments.residual(fine, fine)[0]
    best = int(np.argmin(residual))
    return float(fine[best]), float(residual[best])


def _spiral_integrals(s: np.ndarray, s1: float, s2: float) -> np.ndarray:
    """The integrals from ``s1`` to each ``s`` of the heading columns ``(1, s - s1, g(s))`` of a
    road with its spiral from ``s1`` to ``s2`` (a step at ``s1`` where they meet)."""
    u = s - s1
    after = np.clip(u, 0.0, None)
    length = s2 - s1
    if length > 0:
        on_spiral = np.clip(u, 0.0, length)
        beyond = after - on_spiral
        g = on_spiral**3 / (6.0 * length) + beyond * (length / 2.0 + beyond / 2.0)
    else:
        g = after**2 / 2.0
    return np.column_stack((u, u * u / 2.0, g))


def _staircase_integrals(s: np.ndarray, bounds: np.ndarray, is_spiral: np.ndarray) -> np.ndarray:
    """The integrals up to each ``s`` of the heading columns of parts fitted each on its own:
    a line on a constant part, a parabola on a clothoid, zero outside the part."""
    columns = []
    for start_s, end_s, spiral in zip(bounds[:-1], bounds[1:], is_spiral, strict=True):
        middle_s = 0.5 * (start_s + end_s)
        inside = np.clip(s, start_s, end_s) - middle_s
        columns += [
            (inside ** (degree + 1) - (start_s - middle_s) ** (degree + 1)) / (degree + 1)
            for degree in range(3 if spiral else 2)
        ]
    return np.column_stack(columns)


def _sideways_residuals(chords: _Chords, rows: slice, models: list[Callable[[np.ndarray], np.ndarray]]) -> np.ndarray:
    """The residual of each heading model over ``rows`` judged on sideways offsets, in units
    of the vertices' noise variance.

    A chord's heading times its length, summed along the chords, is each vertex's offset
    from a line (to first order in the heading's change); a model's is the integral of
    its heading, so each model is given as the integrals of its heading columns at the
    vertices (which makes a chord straddling a change of curvature no error). The
    offsets' errors are the vertices' own sideways errors, independent with variance
    ``noise_variance / 2``, so a residual here weighs a lasting deviation by every vertex
    it moves, where the chords' headings, whose errors are differences of neighbouring
    vertices', hide it.
    """
    length = chords.length_m[rows]
    heading = chords.heading[rows] - float(chords.heading[rows].mean())
    offsets = np.concatenate(([0.0], np.cumsum(length * heading)))
    vertex_s = np.concatenate(([chords.mid_s[rows.start] - 0.5 * length[0]], chords.mid_s[rows] + 0.5 * length))
    vertex_variance = chords.noise_variance / 2.0
    residuals = []
    for model in models:
        columns = model(vertex_s) - model(vertex_s[:1])
        columns = np.column_stack((np.ones(len(offsets)), columns))
        solution, *_ = np.linalg.lstsq(columns, offsets, rcond=None)
        residuals.append(float(np.sum((columns @ solution - offsets) ** 2)) / vertex_variance)
    return np.array(residuals)


def _least_on_grid(
    moments: _Moments, s1_values: np.ndarray, s2_values: np.ndarray
) -> tuple[float, float, float, np.ndarray]:
    """The spiral with the least residual among all ``s1 <= s2`` of two grids: ``(residual, s1, s2, solution)``."""
    s1, s2 = (grid.ravel() for grid in np.meshgrid(s1_values, s2_values, indexing="ij"))
    keep = s2 >= s1
    residual, solution = moments.residual(s1[keep], s2[keep])
    best = int(np.argmin(residual))
    return float(residual[best]), float(s1[keep][best]), float(s2[keep][best]), solution[best]
