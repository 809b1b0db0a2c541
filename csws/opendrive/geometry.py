"""The reference line of an OpenDRIVE road: position, heading and curvature along its plan view.

Lines, arcs and spirals (clothoids) have curvature linear in arc length, so their κ(s) is
exact; their positions are closed form (line, arc) or integrated on a grid of
:data:`INTEGRATION_STEP_M` (spiral: heading closed form, position by the trapezoidal rule,
error well under a micrometre for road curvatures). ``poly3`` and ``paramPoly3`` are given
in a parameter that is not arc length: they are sampled on the same grid, their arc length
integrated, and their curvature taken from the parametric derivatives (exact at each sample).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .model import Geometry, OpenDriveError, Road

__all__ = ["INTEGRATION_STEP_M", "Poses", "geometry_poses", "reference_poses", "reference_curvature_parts"]

#: Grid step of the numerical integration of spirals, poly3 and paramPoly3, m.
INTEGRATION_STEP_M = 0.05


class Poses(NamedTuple):
    """Points along a line: arc length, position, heading and signed curvature, each ``(n,)``."""

    s: np.ndarray
    x: np.ndarray
    y: np.ndarray
    hdg: np.ndarray
    curvature: np.ndarray


def _grid(length: float, step: float) -> np.ndarray:
    """Arc lengths from 0 to ``length`` at most ``step`` apart, both ends included."""
    count = max(int(math.ceil(length / step)), 1)
    return np.linspace(0.0, length, count + 1)


def _placed(geometry: Geometry, u: np.ndarray, local_x: np.ndarray, local_y: np.ndarray) -> tuple[np.ndarray, ...]:
    """Local coordinates rotated by the geometry's heading and moved to its start."""
    cos_h, sin_h = math.cos(geometry.hdg), math.sin(geometry.hdg)
    return geometry.x + cos_h * local_x - sin_h * local_y, geometry.y + sin_h * local_x + cos_h * local_y


def _integrated(heading: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Local position along a curve of known heading at arc lengths ``u`` (trapezoidal rule)."""
    du = np.diff(u)
    cos_h, sin_h = np.cos(heading), np.sin(heading)
    local_x = np.concatenate(([0.0], np.cumsum(0.5 * du * (cos_h[1:] + cos_h[:-1]))))
    local_y = np.concatenate(([0.0], np.cumsum(0.5 * du * (sin_h[1:] + sin_h[:-1]))))
    return local_x, local_y


def _parametric(geometry: Geometry, step: float) -> Poses:
    """Poses of a ``poly3`` or ``paramPoly3``, sampled in its parameter and arc length integrated."""
    names = ("aU", "bU", "cU", "dU", "aV", "bV", "cV", "dV")
    if geometry.kind == "poly3":
        coefficients = (0.0, 1.0, 0.0, 0.0, *(geometry.param(name) for name in "abcd"))
        p_end = _poly3_parameter_end(geometry, coefficients)
    else:
        coefficients = tuple(geometry.param(name) for name in names)
        p_end = geometry.length if geometry.param("pRange") == 1.0 else 1.0
    count = max(int(math.ceil(geometry.length / step)), 8)
    p = np.linspace(0.0, p_end, count * 4 + 1)
    au, bu, cu, du, av, bv, cv, dv = coefficients
    u, v = au + p * (bu + p * (cu + p * du)), av + p * (bv + p * (cv + p * dv))
    du1, dv1 = bu + p * (2 * cu + 3 * p * du), bv + p * (2 * cv + 3 * p * dv)
    du2, dv2 = 2 * cu + 6 * p * du, 2 * cv + 6 * p * dv
    speed = np.hypot(du1, dv1)
    if np.any(speed <= 0):
        raise OpenDriveError(f"a {geometry.kind} at s={geometry.s:g} stands still (zero derivative)")
    arc = np.concatenate(([0.0], np.cumsum(0.5 * np.diff(p) * (speed[1:] + speed[:-1]))))
    curvature = (du1 * dv2 - dv1 * du2) / speed**3
    x, y = _placed(geometry, arc, u - au, v - av)
    return Poses(geometry.s + arc, x, y, geometry.hdg + np.arctan2(dv1, du1), curvature)


def _poly3_parameter_end(geometry: Geometry, coefficients: tuple[float, ...]) -> float:
    """The local x at which a ``poly3``'s arc length reaches its length (it is never beyond the length)."""
    b, c, d = coefficients[5:8]
    p = np.linspace(0.0, geometry.length, max(int(geometry.length / INTEGRATION_STEP_M), 64) + 1)
    speed = np.hypot(1.0, b + p * (2 * c + 3 * p * d))
    arc = np.concatenate(([0.0], np.cumsum(0.5 * np.diff(p) * (speed[1:] + speed[:-1]))))
    return float(np.interp(geometry.length, arc, p))


def geometry_poses(geometry: Geometry, step: float = INTEGRATION_STEP_M) -> Poses:
    """Poses along one ``<geometry>`` record, its start and end included, at most ``step`` apart in arc length.

    Raises
    ------
    OpenDriveError
        For a record of an unknown kind or a parametric curve that stands still.
    """
    if geometry.kind in ("poly3", "paramPoly3"):
        return _parametric(geometry, step)
    u = _grid(geometry.length, step)
    if geometry.kind == "line":
        curvature = np.zeros(len(u))
    elif geometry.kind == "arc":
        curvature = np.full(len(u), geometry.param("curvature"))
    elif geometry.kind == "spiral":
        start, end = geometry.param("curvStart"), geometry.param("curvEnd")
        rate = (end - start) / geometry.length if geometry.length > 0 else 0.0
        curvature = start + rate * u
    else:
        raise OpenDriveError(f"unknown plan-view geometry {geometry.kind!r}")
    heading = u * (curvature[0] + 0.5 * (curvature - curvature[0]))
    if geometry.kind == "line":
        local_x, local_y = u, np.zeros(len(u))
    elif geometry.kind == "arc" and curvature[0] != 0:
        k = curvature[0]
        local_x, local_y = np.sin(k * u) / k, (1.0 - np.cos(k * u)) / k
    else:
        local_x, local_y = _integrated(heading, u)
    x, y = _placed(geometry, u, local_x, local_y)
    return Poses(geometry.s + u, x, y, geometry.hdg + heading, curvature)


def reference_poses(road: Road, step: float = INTEGRATION_STEP_M) -> Poses:
    """Poses along a road's whole reference line, each geometry's start and end included."""
    pieces = [geometry_poses(geometry, step) for geometry in road.geometries if geometry.length > 0]
    if not pieces:
        raise OpenDriveError(f"road {road.road_id}: the plan view has no length")
    return Poses(*(np.concatenate([getattr(piece, field) for piece in pieces]) for field in Poses._fields))


def reference_curvature_parts(road: Road) -> list[tuple[float, float, float, float]]:
    """The exact κ(s) of a road's reference line where it is piecewise linear: ``(s0, s1, κ0, κ1)`` per
    line, arc or spiral (poly3 and paramPoly3 records are left out: their κ is not linear in s)."""
    parts = []
    for geometry in road.geometries:
        if geometry.kind == "line":
            parts.append((geometry.s, geometry.end_s, 0.0, 0.0))
        elif geometry.kind == "arc":
            k = geometry.param("curvature")
            parts.append((geometry.s, geometry.end_s, k, k))
        elif geometry.kind == "spiral":
            parts.append((geometry.s, geometry.end_s, geometry.param("curvStart"), geometry.param("curvEnd")))
    return parts
