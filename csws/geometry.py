"""Builds exact road geometry from straights, circular arcs and clothoids.

A road is described as a sequence of :class:`Piece` objects, each with curvature
linear in arc length: constant on a straight (0) or an arc, changing evenly along a
clothoid (Euler spiral, the transition curve of road design). Positions along straights
and arcs are computed in closed form, along clothoids by Gauss-Legendre quadrature of
the heading, exact to well under a micrometre. The test tracks (clause 7.4, Tables 3
and 4), the tests and the benchmarks all share one exact construction and one ground
truth: the curvature at every arc length is known, so curve start and end points (3.4,
3.5) and radii are exact by construction.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = [
    "Piece",
    "straight",
    "arc",
    "clothoid",
    "piece_starts_s",
    "pose_at",
    "curvature_at",
    "sample_pieces",
    "wrap_angle_rad",
]

#: Gauss-Legendre nodes and weights on [0, 1] for the positions along a clothoid: its
#: heading is quadratic in arc length, and 24 nodes integrate its cosine and sine over
#: any road-sized turn to rounding error.
_LEGENDRE_NODES, _LEGENDRE_WEIGHTS = np.polynomial.legendre.leggauss(24)
_QUADRATURE_NODES, _QUADRATURE_WEIGHTS = (_LEGENDRE_NODES + 1.0) / 2.0, _LEGENDRE_WEIGHTS / 2.0


@dataclass(frozen=True)
class Piece:
    """A stretch of road whose curvature changes linearly with arc length.

    Attributes
    ----------
    length_m
        Arc length of the piece, m (> 0).
    curvature
        Signed curvature at its start, 1/m: positive turns left, negative right, 0 is straight.
    end_curvature
        Signed curvature at its end, 1/m; None for a piece of constant curvature (a
        straight or an arc), else the piece is a clothoid.
    """

    length_m: float
    curvature: float = 0.0
    end_curvature: float | None = None

    def __post_init__(self) -> None:
        if not (np.isfinite(self.length_m) and self.length_m > 0):
            raise ValueError(f"piece length must be a positive number of metres, got {self.length_m!r}")
        if not np.isfinite(self.curvature) or not np.isfinite(self.final_curvature):
            raise ValueError(f"piece curvature must be finite, got {self.curvature!r}, {self.end_curvature!r}")

    @property
    def final_curvature(self) -> float:
        """Signed curvature at the end of the piece, 1/m."""
        return self.curvature if self.end_curvature is None else self.end_curvature

    @property
    def radius_m(self) -> float:
        """Smallest radius on the piece, m; ``inf`` for a straight."""
        largest = max(abs(self.curvature), abs(self.final_curvature))
        return float("inf") if largest == 0 else 1.0 / largest

    @property
    def angle_deg(self) -> float:
        """Central angle the piece turns through (3.6), degrees, unsigned."""
        return float(np.degrees(abs(self.curvature + self.final_curvature) / 2.0 * self.length_m))


def straight(length_m: float) -> Piece:
    """A straight piece of ``length_m`` metres."""
    return Piece(length_m, 0.0)


def arc(radius_m: float, angle_deg: float, direction: str = "left") -> Piece:
    """A circular arc of ``radius_m`` turning ``angle_deg`` degrees to the ``direction`` (left/right)."""
    if direction not in ("left", "right"):
        raise ValueError(f"direction must be 'left' or 'right', got {direction!r}")
    if not (np.isfinite(radius_m) and radius_m > 0):
        raise ValueError(f"arc radius must be a positive number of metres, got {radius_m!r}")
    sign = 1.0 if direction == "left" else -1.0
    return Piece(radius_m * np.radians(angle_deg), sign / radius_m)


def clothoid(length_m: float, start_radius_m: float, end_radius_m: float, direction: str = "left") -> Piece:
    """A clothoid of ``length_m`` metres whose radius goes from ``start_radius_m`` to
    ``end_radius_m`` (``inf`` for a straight), turning to the ``direction`` (left/right)."""
    if direction not in ("left", "right"):
        raise ValueError(f"direction must be 'left' or 'right', got {direction!r}")
    for radius_m in (start_radius_m, end_radius_m):
        if not radius_m > 0:
            raise ValueError(f"clothoid radii must be positive numbers of metres (inf for straight), got {radius_m!r}")
    sign = 1.0 if direction == "left" else -1.0
    return Piece(length_m, sign / start_radius_m, sign / end_radius_m)


def piece_starts_s(pieces: Sequence[Piece]) -> np.ndarray:
    """Arc length at the start of each piece and at the end of the last: ``len(pieces) + 1`` values."""
    return np.concatenate(([0.0], np.cumsum([p.length_m for p in pieces])))


def _piece_start_poses(
    pieces: Sequence[Piece], start_xy: tuple[float, float], start_heading_rad: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """x, y and heading at the start of each piece (and at the end of the last)."""
    count = len(pieces)
    x = np.empty(count + 1)
    y = np.empty(count + 1)
    heading = np.empty(count + 1)
    x[0], y[0], heading[0] = start_xy[0], start_xy[1], start_heading_rad
    for i, piece in enumerate(pieces):
        change = (piece.final_curvature - piece.curvature) / piece.length_m
        x[i + 1], y[i + 1], heading[i + 1] = _advance(x[i], y[i], heading[i], piece.curvature, change, piece.length_m)
    return x, y, heading


def _advance(x0, y0, heading0, curvature, curvature_change, distance):
    """Pose after ``distance`` metres from (x0, y0, heading0) with the curvature starting at
    ``curvature`` and changing by ``curvature_change`` per metre; arrays broadcast."""
    curvature, change, distance = (np.asarray(a, dtype=float) for a in (curvature, curvature_change, distance))
    heading = heading0 + curvature * distance + change * distance**2 / 2.0
    turning = curvature != 0
    safe_curvature = np.where(turning, curvature, 1.0)
    dx = np.where(turning, (np.sin(heading) - np.sin(heading0)) / safe_curvature, distance * np.cos(heading0))
    dy = np.where(turning, (np.cos(heading0) - np.cos(heading)) / safe_curvature, distance * np.sin(heading0))
    spiral = change != 0
    if np.any(spiral):
        # Heading at the quadrature nodes along [0, distance], integrated into the offset.
        t = distance[..., None] * _QUADRATURE_NODES
        along = np.asarray(heading0, dtype=float)[..., None] + curvature[..., None] * t + change[..., None] * t**2 / 2.0
        dx = np.where(spiral, distance * (np.cos(along) @ _QUADRATURE_WEIGHTS), dx)
        dy = np.where(spiral, distance * (np.sin(along) @ _QUADRATURE_WEIGHTS), dy)
    return x0 + dx, y0 + dy, heading


def pose_at(
    pieces: Sequence[Piece],
    s: np.ndarray,
    start_xy: tuple[float, float] = (0.0, 0.0),
    start_heading_rad: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact x, y (m) and heading (rad) at arc lengths ``s`` along the pieces.

    ``s`` is clipped to the road's length.
    """
    starts = piece_starts_s(pieces)
    s = np.clip(np.asarray(s, dtype=float), 0.0, starts[-1])
    index = np.clip(np.searchsorted(starts, s, side="right") - 1, 0, len(pieces) - 1)
    x0, y0, heading0 = _piece_start_poses(pieces, start_xy, start_heading_rad)
    curvature = np.array([p.curvature for p in pieces])
    change = np.array([(p.final_curvature - p.curvature) / p.length_m for p in pieces])
    return _advance(x0[index], y0[index], heading0[index], curvature[index], change[index], s - starts[index])


def curvature_at(pieces: Sequence[Piece], s: np.ndarray) -> np.ndarray:
    """Exact signed curvature (1/m) at arc lengths ``s`` along the pieces; at a piece boundary,
    that of the piece starting there. ``s`` is clipped to the road's length."""
    starts = piece_starts_s(pieces)
    s = np.clip(np.asarray(s, dtype=float), 0.0, starts[-1])
    index = np.clip(np.searchsorted(starts, s, side="right") - 1, 0, len(pieces) - 1)
    first = np.array([p.curvature for p in pieces])
    last = np.array([p.final_curvature for p in pieces])
    fraction = (s - starts[index]) / np.diff(starts)[index]
    return first[index] + (last[index] - first[index]) * fraction


def sample_pieces(
    pieces: Sequence[Piece],
    spacing_m: float,
    start_xy: tuple[float, float] = (0.0, 0.0),
    start_heading_rad: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """A polyline along the pieces with vertices about ``spacing_m`` apart.

    Every piece boundary is a vertex, and each piece is divided evenly, so that a
    SUMO shape built from it has its curve start and end points exactly where the
    pieces say.

    Returns
    -------
    xy
        ``(n, 2)`` vertex coordinates, m.
    s
        ``(n,)`` exact arc length of each vertex along the pieces, m.
    """
    if not (np.isfinite(spacing_m) and spacing_m > 0):
        raise ValueError(f"spacing must be a positive number of metres, got {spacing_m!r}")
    starts = piece_starts_s(pieces)
    parts = [
        np.linspace(starts[i], starts[i + 1], max(1, int(np.ceil(p.length_m / spacing_m))) + 1)[:-1]
        for i, p in enumerate(pieces)
    ]
    s = np.concatenate(parts + [starts[-1:]])
    x, y, _ = pose_at(pieces, s, start_xy, start_heading_rad)
    return np.column_stack((x, y)), s


def wrap_angle_rad(angle_rad):
    """Angles wrapped to [-pi, pi) (floats or arrays)."""
    return (angle_rad + np.pi) % (2 * np.pi) - np.pi
