"""Fits the radius profile of each polyline with the fit its kind needs; also the three-point baseline."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from csws.standard import DEFAULT_WARNING_RADIUS_M, WarningSpeedPolicy

from .artefacts import netted_turns
from .chords import _chords, _coordinate_noise_m, _validated
from .corners import with_corner_rules, with_floor
from .curves import curves_from_profile
from .dense import _dense_parts, _Fit, _is_mapped, _is_sparse, _polyline_vertex_s, _Segmentation
from .polish import _sparse_parts
from .profile import Curve, RadiusProfile, profile_from_parts, straight_profile
from .transitions import with_transitions


def radius_profiles(polylines: Sequence[np.ndarray]) -> list[RadiusProfile]:
    """Radius profiles of many polylines at once.

    All polylines are processed together in flat arrays (running sums, ``reduceat``), so
    a network of tens of thousands of lanes takes seconds; each polyline's profile is
    the same as when it is profiled alone.

    Parameters
    ----------
    polylines
        ``(n, 2)`` arrays of vertex coordinates, m. Empty, one-point and all-repeated
        polylines give a straight profile without parts; repeated consecutive vertices
        are ignored.

    Returns
    -------
    list[RadiusProfile]
        One per polyline, in order.

    Raises
    ------
    ValueError
        When a polyline is not ``(n, 2)`` or has NaN or infinite coordinates.
    """
    points = [_validated(xy, i) for i, xy in enumerate(polylines)]
    if not points:
        return []
    chords = _chords(points)
    if len(chords.length_m) == 0:
        return [
            straight_profile(chords.vertex_s[chords.polyline_first_vertex[p] : chords.polyline_first_vertex[p + 1]])
            for p in range(len(points))
        ]
    noise_m = _coordinate_noise_m(chords, len(points))
    segmentation = _Segmentation(chords, noise_m)
    segmentation.split_until_stable()
    segmentation.open_steps()
    segmentation.refine_until_stable()
    fit = segmentation.fit_on_arc_lengths()
    mapped = _is_mapped(chords, noise_m)
    sparse_parts = _sparse_parts(chords, noise_m, np.flatnonzero(_is_sparse(chords, noise_m)))
    return [_polyline_profile(segmentation, fit, sparse_parts, bool(mapped[p]), p) for p in range(len(points))]


def _polyline_profile(
    segmentation: _Segmentation, fit: _Fit, sparse_parts: dict, mapped: bool, polyline: int
) -> RadiusProfile:
    """The profile of one polyline from the fit it was given.

    A dense shape gets clothoids where its headings show them
    (:func:`csws.curvature.transitions.with_transitions`); a map way, fitted sparse or
    dense, is kept to what its nodes can say (:func:`csws.curvature.corners.with_corner_rules`).
    """
    chords = segmentation.chords
    vertex_s = _polyline_vertex_s(chords, polyline)
    rows = slice(*chords.polyline_first_chord[polyline : polyline + 2])
    if polyline in sparse_parts:
        bounds, curvature = sparse_parts[polyline]
        parts = (bounds, curvature, curvature)
    elif (dense := _dense_parts(segmentation, fit, polyline)) is None:
        return straight_profile(vertex_s)
    elif mapped or len(dense[1]) == 1:
        parts = (dense[0], dense[1], dense[1])
    else:
        parts = with_transitions(
            chords.start_s[rows] + 0.5 * chords.length_m[rows],
            chords.heading[rows],
            segmentation.weight[rows],
            float(segmentation.noise_variance[rows.start]),
            chords.length_m[rows],
            *dense,
        )
    if mapped:
        noise_m = float(segmentation.noise_variance[rows.start] / 2.0) ** 0.5
        turn_rad, _ = netted_turns(_vertex_turns(chords.heading[rows]), chords.length_m[rows])
        parts = with_corner_rules(chords.start_s[rows], chords.length_m[rows], turn_rad, noise_m, *parts)
    else:
        parts = (parts[0], *with_floor(*parts[1:]))
    return profile_from_parts(vertex_s, *parts)


def _vertex_turns(heading_rad: np.ndarray) -> np.ndarray:
    """The turn at each vertex between consecutive chords of the given headings, wrapped to [-pi, pi), rad."""
    return np.remainder(np.diff(heading_rad) + np.pi, 2.0 * np.pi) - np.pi


def radius_profile(xy: np.ndarray) -> RadiusProfile:
    """The radius profile of one polyline; see :func:`radius_profiles`."""
    return radius_profiles([_validated(xy)])[0]


def find_curves(
    xy: np.ndarray, warning_radius_m: float = DEFAULT_WARNING_RADIUS_M, *, policy: WarningSpeedPolicy
) -> list[Curve]:
    """The curves (3.4-3.8) of one polyline, clothoids cut by ``policy``; see :func:`curves_from_profile`."""
    return curves_from_profile(radius_profile(xy), warning_radius_m, policy=policy)


def three_point_radius(xy: np.ndarray) -> np.ndarray:
    """Radius of the circle through each vertex and its two neighbours, m.

    The textbook baseline, kept for comparison only: on cm-rounded dense shapes its
    error exceeds the curvature of gentle curves. ``inf`` at the two end vertices and
    where the three points are collinear or repeated.
    """
    points = _validated(xy)
    radius = np.full(len(points), np.inf)
    if len(points) < 3:
        return radius
    a, b, c = points[:-2], points[1:-1], points[2:]
    ab = np.hypot(*(b - a).T)
    bc = np.hypot(*(c - b).T)
    ca = np.hypot(*(a - c).T)
    doubled_area = np.abs((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])
    with np.errstate(divide="ignore", invalid="ignore"):
        inner = ab * bc * ca / (2.0 * doubled_area)
    radius[1:-1] = np.where(doubled_area > 0, inner, np.inf)
    return radius
