"""Whether a fitted profile turns a polyline corner, and the way cleared for the corner's arc where it does not.

The second rule of :func:`csws.curvature.artefacts.kept_to_polyline` reads a corner's stretch here:
its **window**, where a curve turns the corner (the second vertex before it to the second after, or
its arc's extent where that reaches further, but no further than halfway to the corners beside it, whose
turning is theirs); whether the curves there turn its net turn (:func:`is_covered`); and, where they do
not, those curves made straight within the window so that the corner's arc replaces them
(:func:`without_curves_at`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from .corners import ANGLE_TOLERANCE_DEG, corner_arc_extent, curvature_at, curve_runs

if TYPE_CHECKING:
    from .artefacts import Corner, PolylineTurns

__all__ = ["corner_window", "halfway_to_neighbours", "is_covered", "without_curves_at"]


def _overlapping(
    corner: Corner, reach: tuple[float, float], bounds: np.ndarray, start_k: np.ndarray, end_k: np.ndarray
) -> list[np.ndarray]:
    """The curves (runs of parts turning one way) turning the corner's way whose net turn counts its vertices: those
    running into the segments between its ``reach`` (the vertices before and after it)."""
    side = math.copysign(1.0, corner.turn_rad)
    return [
        parts
        for parts in curve_runs(start_k, end_k)
        if bounds[parts[-1] + 1] > reach[0]
        and bounds[parts[0]] < reach[1]
        and side * (start_k[parts[0]] + end_k[parts[0]]) > 0
    ]


def corner_window(turns: PolylineTurns, corner: Corner, limits: tuple[float, float]) -> tuple[float, float]:
    """Where a curve turns a corner, m: from the second vertex before it to the second after (node noise moves
    turning from one vertex to the next, and a fit spreads it so), or where its arc would lie
    (:func:`csws.curvature.corners.corner_arc_extent`, the largest arc the map leaves room for) where that reaches
    further, but within ``limits`` (:func:`halfway_to_neighbours`). A curve's turn beyond it is the road's turn
    beyond: a long gentle curve the fit ran through a corner turns at its own radius at the corner, not at the
    corner's, and the arc of the corner next to it turns that corner, not this one."""
    before = int(np.searchsorted(turns.vertex_s, corner.start_s, side="left")) - 2
    after = int(np.searchsorted(turns.vertex_s, corner.end_s, side="right")) + 1
    last = len(turns.vertex_s) - 1
    arms_m, inner_m, vertices = turns.arms(corner)
    low, high = corner_arc_extent((corner.start_s, corner.end_s, corner.turn_rad), arms_m, inner_m, vertices)
    low, high = min(low, float(turns.vertex_s[max(before, 0)])), max(high, float(turns.vertex_s[min(after, last)]))
    return max(low, limits[0]), min(high, limits[1])


def halfway_to_neighbours(corners: list[Corner], index: int) -> tuple[float, float]:
    """From halfway between the last vertex of the corner before corner ``index`` and its first vertex to halfway
    between its last vertex and the first of the corner after, m (unbounded where it has no such neighbour): the
    stretch whose turning is this corner's."""
    corner = corners[index]
    low = (corners[index - 1].end_s + corner.start_s) / 2.0 if index > 0 else -math.inf
    high = (corner.end_s + corners[index + 1].start_s) / 2.0 if index + 1 < len(corners) else math.inf
    return low, high


def _turn_within(
    parts: np.ndarray, window: tuple[float, float], bounds: np.ndarray, start_k: np.ndarray, end_k: np.ndarray
) -> float:
    """How much ``parts`` turn within ``window`` (left positive), rad: their curvature, linear in each part,
    integrated there."""
    turned = 0.0
    for part in parts.tolist():
        part_start, part_end = float(bounds[part]), float(bounds[part + 1])
        low, high = max(part_start, window[0]), min(part_end, window[1])
        if high > low:
            slope = (end_k[part] - start_k[part]) / (part_end - part_start)
            mean_k = start_k[part] + slope * ((low + high) / 2.0 - part_start)
            turned += float(mean_k) * (high - low)
    return turned


def _split_at(
    bounds: np.ndarray, start_k: np.ndarray, end_k: np.ndarray, s: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The parts with a bound at ``s``: a part across it cut in two, its curvature unchanged."""
    if s <= bounds[0] or s >= bounds[-1] or np.any(bounds == s):
        return bounds, start_k, end_k
    part = int(np.searchsorted(bounds, s, side="right")) - 1
    at_s = curvature_at(bounds, start_k, end_k, s)
    return np.insert(bounds, part + 1, s), np.insert(start_k, part + 1, at_s), np.insert(end_k, part, at_s)


def without_curves_at(
    corner: Corner,
    reach: tuple[float, float],
    window: tuple[float, float],
    bounds: np.ndarray,
    start_k: np.ndarray,
    end_k: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The parts with the curves that turn a corner's way at it but fall short of its turn made straight within its
    ``window``: the corner's arc replaces them there, rather than adding to them. What is left of them beyond the
    window goes too where it turns less than :data:`ANGLE_TOLERANCE_DEG`: a sliver of the corner's turn."""
    for s in window:
        bounds, start_k, end_k = _split_at(bounds, start_k, end_k, s)
    start_k, end_k = start_k.copy(), end_k.copy()
    left = np.zeros(len(start_k), dtype=bool)
    for parts in _overlapping(corner, reach, bounds, start_k, end_k):
        inside = (bounds[parts] >= window[0]) & (bounds[parts + 1] <= window[1])
        start_k[parts[inside]] = 0.0
        end_k[parts[inside]] = 0.0
        left[parts[~inside]] = True
    angle_rad = (start_k + end_k) / 2.0 * np.diff(bounds)
    for sliver in curve_runs(np.where(left, start_k, 0.0), np.where(left, end_k, 0.0)):
        if abs(float(angle_rad[sliver].sum())) < math.radians(ANGLE_TOLERANCE_DEG):
            start_k[sliver] = 0.0
            end_k[sliver] = 0.0
    return bounds, start_k, end_k


def is_covered(
    corner: Corner,
    reach: tuple[float, float],
    window: tuple[float, float],
    bounds: np.ndarray,
    start_k: np.ndarray,
    end_k: np.ndarray,
) -> bool:
    """Whether the curves reaching the corner's stretch turn its way within its ``window`` by its net turn, less
    the tolerance, or more (no more than their own stretch's net turn: :func:`_within_net_turn`)."""
    turned = sum(
        _turn_within(parts, window, bounds, start_k, end_k)
        for parts in _overlapping(corner, reach, bounds, start_k, end_k)
    )
    return turned * math.copysign(1.0, corner.turn_rad) >= abs(corner.turn_rad) - math.radians(ANGLE_TOLERANCE_DEG)
