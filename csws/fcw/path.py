"""Path prediction of the forward collision warning (GB/T 33577-2017 4.2 d, 4.3.2 d, 4.6, Annex B).

A class II or III system estimates the subject's path (4.2 d) so that on a curve of Table 1 it
warns of the vehicle in its own lane and not of the one in the adjacent lane, which a straight
beam sees ahead of it (Annex B: on R 125 m a straight beam a lane wide covers the own lane only
to D = (R W_L - W_L^2 / 4)^0.5 = 20.8 m).

Two predictions, in the subject's frame (x forward from its front, y to the left):

* from the yaw rate: a circle of curvature yaw rate / speed (or the curvature given), tangent
  to the subject's heading at its front;
* from the map (where the vehicle is map-matched): the road ahead's curvature as a profile along
  the path, piecewise linear in arc length (:class:`PathCurvature`, e.g. from
  :class:`csws.road.path.PathProfile` by :func:`path_curvature_ahead`), which no camera sees.

An object's lateral offset from the path is its offset from a circle: for the yaw rate the
path's own, for the map the circle tangent at the front that reaches, at the object's arc
length s, the path's lateral displacement there, κ_eq(s) = 2 ∫0^s (s - u) κ(u) du / s². On a
constant radius that is the path itself; where the curvature changes it errs along the path,
hardly across it (0.05 m at 80 m for a straight running into R 125 m, 0.3 m at 120 m for R 125 m
running out into a straight), which is what the in-path test needs. Only arithmetic and square
roots are used, so floats and arrays give the same values to the bit.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from csws.fcw.numeric import sqrt, where

__all__ = [
    "MIN_YAW_SPEED_MPS",
    "straight_beam_range_m",
    "PathCurvature",
    "CurvatureTable",
    "curvature_tables",
    "path_table",
    "path_curvature_ahead",
    "yaw_path_curvature_1pm",
    "offset_from_circle_m",
    "equivalent_curvature_1pm",
    "fleet_equivalent_curvature_1pm",
]

#: Below this speed the yaw rate says nothing of the path's curvature (yaw rate / speed blows up): straight ahead.
MIN_YAW_SPEED_MPS = 1.0


@dataclass(frozen=True)
class PathCurvature:
    """The curvature of the road ahead along the path, from the subject's front (s = 0).

    Attributes
    ----------
    s_m
        Arc lengths of the knots, m: the first 0, strictly increasing.
    curvature_1pm
        Signed curvature at each knot, 1/m (positive turning left), linear between knots and
        held beyond the last one.
    """

    s_m: tuple[float, ...]
    curvature_1pm: tuple[float, ...]

    def __post_init__(self) -> None:
        s, k = np.asarray(self.s_m, dtype=float), np.asarray(self.curvature_1pm, dtype=float)
        if s.ndim != 1 or s.shape != k.shape or s.size == 0:
            raise ValueError("path curvature: s_m and curvature_1pm must be equal-length, non-empty sequences")
        if not (np.all(np.isfinite(s)) and np.all(np.isfinite(k))):
            raise ValueError("path curvature: s_m and curvature_1pm must be finite (no NaN)")
        if s[0] != 0.0 or np.any(np.diff(s) <= 0.0):
            raise ValueError("path curvature: s_m must start at 0 (the subject's front) and increase strictly")
        object.__setattr__(self, "s_m", tuple(float(v) for v in s))
        object.__setattr__(self, "curvature_1pm", tuple(float(v) for v in k))


@dataclass(frozen=True)
class CurvatureTable:
    """One path's integrals at its knots, as lists (for the per-object look-up on floats).

    ``heading`` is ∫κ (the heading change, rad), ``lateral`` ∫∫κ (the small-angle lateral
    displacement, m), ``slope`` dκ/ds on the segment starting at each knot (0 after the last).
    """

    s_m: list[float]
    curvature_1pm: list[float]
    slope: list[float]
    heading: list[float]
    lateral: list[float]
    knots: int = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "knots", len(self.s_m))


def curvature_tables(s_m: np.ndarray, curvature_1pm: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Slope, heading and lateral integrals at the knots of paths padded to one length, ``(paths, knots)``.

    Padding knots carry ``s = inf``; a path's last real knot gets slope 0 (the curvature is held).
    The integrals of the piecewise linear curvature are exact: over a segment of length h,
    heading += (κ0 + κ1) h / 2 and lateral += heading0 h + (2 κ0 + κ1) h² / 6.
    """
    h = np.diff(np.where(np.isfinite(s_m), s_m, np.nan), axis=1)
    real = np.isfinite(h)
    h = np.where(real, h, 0.0)
    k0, k1 = curvature_1pm[:, :-1], np.where(real, curvature_1pm[:, 1:], curvature_1pm[:, :-1])
    slope = np.zeros_like(s_m)
    slope[:, :-1] = np.where(real, (k1 - k0) / np.where(real, h, 1.0), 0.0)
    heading = np.zeros_like(s_m)
    heading[:, 1:] = np.cumsum((k0 + k1) * h / 2.0, axis=1)
    lateral = np.zeros_like(s_m)
    lateral[:, 1:] = np.cumsum(heading[:, :-1] * h + (2.0 * k0 + k1) * h * h / 6.0, axis=1)
    return slope, heading, lateral


def path_table(path: PathCurvature) -> CurvatureTable:
    """One path's :class:`CurvatureTable`: :func:`curvature_tables` on one row (the fleet's values to the bit)."""
    s = np.asarray([path.s_m], dtype=float)
    k = np.asarray([path.curvature_1pm], dtype=float)
    slope, heading, lateral = curvature_tables(s, k)
    return CurvatureTable(
        list(path.s_m), list(path.curvature_1pm), slope[0].tolist(), heading[0].tolist(), lateral[0].tolist()
    )


def _lateral_at(s: Any, s0: Any, k0: Any, slope: Any, heading0: Any, lateral0: Any) -> Any:
    """∫∫κ at ``s`` on the segment starting at ``s0``: lateral0 + heading0 d + κ0 d²/2 + slope d³/6."""
    d = s - s0
    return lateral0 + heading0 * d + k0 * d * d / 2.0 + slope * d * d * d / 6.0


def _equivalent_at(s: Any, lateral: Any, k0: Any) -> Any:
    """κ_eq = 2 ∫∫κ / s² (the curvature at the front where s is 0)."""
    far = s > 0.0
    return where(far, 2.0 * lateral / where(far, s * s, 1.0), k0)


def _arc_from_chord(chord_m: Any, curvature_1pm: Any) -> Any:
    """The arc on a circle of ``curvature_1pm`` whose chord is ``chord_m``: c (1 + (κ c)² / 24), to O((κc)^4)."""
    kc = curvature_1pm * chord_m
    return chord_m * (1.0 + kc * kc / 24.0)


def equivalent_curvature_1pm(table: CurvatureTable, x_m: float, y_m: float) -> float:
    """κ_eq of the map path at the arc length of the point (x, y): from the chord, refined once by its arc."""
    chord = sqrt(x_m * x_m + y_m * y_m)
    kappa = _table_equivalent(table, chord)
    return _table_equivalent(table, _arc_from_chord(chord, kappa))


def _table_equivalent(table: CurvatureTable, s: float) -> float:
    """κ_eq at arc length ``s`` from one path's table."""
    k = max(bisect.bisect_right(table.s_m, s) - 1, 0)
    lateral = _lateral_at(s, table.s_m[k], table.curvature_1pm[k], table.slope[k], table.heading[k], table.lateral[k])
    return _equivalent_at(s, lateral, table.curvature_1pm[0])


def fleet_equivalent_curvature_1pm(
    s_m: np.ndarray,
    curvature_1pm: np.ndarray,
    tables: tuple[np.ndarray, ...],
    row: np.ndarray,
    x_m: np.ndarray,
    y_m: np.ndarray,
) -> np.ndarray:
    """κ_eq for points (x, y) on padded paths (row ``row`` of each), as :func:`equivalent_curvature_1pm`."""
    knots = s_m[row]
    chord = np.sqrt(x_m * x_m + y_m * y_m)
    kappa = _fleet_equivalent(knots, curvature_1pm, tables, row, chord)
    return _fleet_equivalent(knots, curvature_1pm, tables, row, _arc_from_chord(chord, kappa))


def _fleet_equivalent(
    knots: np.ndarray, curvature_1pm: np.ndarray, tables: tuple[np.ndarray, ...], row: np.ndarray, s: np.ndarray
) -> np.ndarray:
    """κ_eq at arc lengths ``s`` on the points' padded knots: the knot is the last one at or before s (as bisect)."""
    slope, heading, lateral = tables
    k = np.maximum((knots <= s[:, None]).sum(axis=1) - 1, 0)
    at = _lateral_at(
        s, knots[np.arange(s.size), k], curvature_1pm[row, k], slope[row, k], heading[row, k], lateral[row, k]
    )
    return _equivalent_at(s, at, curvature_1pm[row, 0])


def straight_beam_range_m(radius_m: float, lane_width_m: float) -> float:
    """Annex B, formula (B.1): how far a straight beam a lane wide covers the own lane on a curve of
    ``radius_m``, D = (R W_L - W_L^2 / 4)^0.5; beyond it only a predicted path keeps to the lane."""
    return math.sqrt(radius_m * lane_width_m - lane_width_m * lane_width_m / 4.0)


def yaw_path_curvature_1pm(speed_mps: Any, yaw_rate_rps: Any) -> Any:
    """The path's curvature from the yaw rate, yaw rate / speed (constant curvature); 0 below
    :data:`MIN_YAW_SPEED_MPS`, where a yaw rate says nothing of the path."""
    moving = speed_mps >= MIN_YAW_SPEED_MPS
    return where(moving, yaw_rate_rps / where(moving, speed_mps, 1.0), 0.0)


def offset_from_circle_m(x_m: Any, y_m: Any, curvature_1pm: Any) -> Any:
    """The signed offset (left positive) of the point (x, y) from the circle of curvature κ
    tangent to the x axis at the origin: e = -c / (1 + sqrt(1 + κ c)), c = κ (x² + y²) - 2 y.

    It is the root of κ e² - 2 e = c that is y on a straight (κ = 0), written without the
    cancellation of 1/κ - r; for κ > 0 it is 1/κ - r with r the distance from the circle's centre.
    Beyond the far side of the circle (1 + κ c < 0) the point is taken as off the path (inf).
    """
    c = curvature_1pm * (x_m * x_m + y_m * y_m) - 2.0 * y_m
    inside = 1.0 + curvature_1pm * c
    real = inside >= 0.0
    return where(real, -c / (1.0 + sqrt(where(real, inside, 0.0))), float("inf"))


def path_curvature_ahead(path: Any, vehicle_s_m: float, range_m: float) -> PathCurvature:
    """The curvature profile of a map path (:class:`csws.road.path.PathProfile`, or a
    :class:`csws.ahead.horizon.PathAhead`'s ``path``) from the vehicle's front at ``vehicle_s_m``
    over ``range_m``: the profile's vertex curvatures, linear between them."""
    profile = path.profile
    s, kappa = np.asarray(profile.s, dtype=float), np.asarray(profile.curvature, dtype=float)
    keep = np.flatnonzero((s > vehicle_s_m) & (s < vehicle_s_m + range_m) & np.concatenate(([True], np.diff(s) > 0)))
    start_kappa = float(np.interp(vehicle_s_m, s, kappa))
    return PathCurvature((0.0, *(s[keep] - vehicle_s_m).tolist()), (start_kappa, *kappa[keep].tolist()))
