"""Exact road geometry made of straights and circular arcs.

A road is described as a sequence of :class:`Piece` objects, each of constant
curvature (0 on a straight). Positions along it are computed in closed form, so the
test tracks (clause 7.4, Tables 3 and 4), the tests and the benchmarks all share one
exact construction and one ground truth: the piece boundaries are where curves start
and end (3.4, 3.5) and each arc's radius is exact by construction.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

__all__ = ["Piece", "straight", "arc", "piece_starts_s", "pose_at", "sample_pieces", "wrap_angle_rad"]


@dataclass(frozen=True)
class Piece:
    """A stretch of road of constant curvature.

    Attributes
    ----------
    length_m
        Arc length of the piece, m (> 0).
    curvature
        Signed curvature, 1/m: positive turns left, negative right, 0 is straight.
    """

    length_m: float
    curvature: float = 0.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.length_m) and self.length_m > 0):
            raise ValueError(f"piece length must be a positive number of metres, got {self.length_m!r}")
        if not np.isfinite(self.curvature):
            raise ValueError(f"piece curvature must be finite, got {self.curvature!r}")

    @property
    def radius_m(self) -> float:
        """Radius of the piece, m; ``inf`` for a straight."""
        return float("inf") if self.curvature == 0 else 1.0 / abs(self.curvature)

    @property
    def angle_deg(self) -> float:
        """Central angle the piece turns through (3.6), degrees, unsigned."""
        return float(np.degrees(abs(self.curvature) * self.length_m))


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
        x[i + 1], y[i + 1], heading[i + 1] = _advance(x[i], y[i], heading[i], piece.curvature, piece.length_m)
    return x, y, heading


def _advance(x0, y0, heading0, curvature, distance):
    """Pose after ``distance`` metres of constant ``curvature`` from (x0, y0, heading0); arrays broadcast."""
    curvature = np.asarray(curvature, dtype=float)
    distance = np.asarray(distance, dtype=float)
    heading = heading0 + curvature * distance
    turning = curvature != 0
    safe_curvature = np.where(turning, curvature, 1.0)
    dx = np.where(turning, (np.sin(heading) - np.sin(heading0)) / safe_curvature, distance * np.cos(heading0))
    dy = np.where(turning, (np.cos(heading0) - np.cos(heading)) / safe_curvature, distance * np.sin(heading0))
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
    return _advance(x0[index], y0[index], heading0[index], curvature[index], s - starts[index])


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
