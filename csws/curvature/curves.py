"""Finds the curves (3.3-3.8) of a radius profile whose curvature is piecewise linear in arc length.

A curve is a maximal stretch turning one way with a radius no larger than the warning
curvature radius R_c (3.2). Its start point (3.4) is where the radius falls to R_c, and
its end point (3.5) where it rises above R_c again: on a clothoid these lie inside it,
where its linear curvature crosses 1/R_c. Its angle (3.6) is the integral of the
curvature between them.

A curve's parts are its curvature points of interest (3.11): each arc is one, and each
clothoid is cut into pieces over which the warning speed V_w of every category and level
changes by at most :data:`SPIRAL_PIECE_KMH`, each taken at the radius of its own start.
That start is a real point of the road with that radius, so the warning distance of
formula (1) to it is one the road requires, and the onset of a warning over a spiral is
that of its pieces' starts; between two neighbouring pieces V_w and formula (1) differ
by at most what 1 km/h of V_w makes (about 2 v_w / g per m/s: 1.4 m at 90 km/h).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from csws.standard import DEFAULT_WARNING_RADIUS_M, Column, WarningSpeedPolicy

from .profile import ConstantRadiusPart, Curve, ProfilePart, RadiusProfile

__all__ = ["SPIRAL_PIECE_KMH", "checked_warning_radius_m", "curves_from_profile"]

#: Largest change of the warning speed V_w (any category, any level) along one piece of a clothoid, km/h.
SPIRAL_PIECE_KMH = 1.0
#: Step of the warning speed between the points at which a clothoid is looked at when it is cut into pieces, km/h.
SPIRAL_SAMPLE_KMH = 0.05
#: Most points a clothoid is looked at.
MAX_SPIRAL_SAMPLES = 20_000


def _curved_span(part: ProfilePart, limit: float, sign: float) -> tuple[float, float] | None:
    """The stretch of ``part`` where ``sign`` * curvature >= ``limit`` (1/R_c), or None."""
    k0, k1 = sign * part.curvature, sign * part.final_curvature
    if part.length_m <= 0 or max(k0, k1) < limit:
        return None
    if min(k0, k1) >= limit:
        return part.start_s, part.end_s
    crossing = part.start_s + (limit - k0) / (k1 - k0) * part.length_m
    return (crossing, part.end_s) if k1 > k0 else (part.start_s, crossing)


def checked_warning_radius_m(warning_radius_m: float) -> float:
    """The warning curvature radius R_c (3.2) as a float, m; ValueError unless it is a positive finite number."""
    if not (math.isfinite(warning_radius_m) and warning_radius_m > 0):
        raise ValueError(f"warning radius must be a positive number of metres, got {warning_radius_m!r}")
    return float(warning_radius_m)


def _warning_speeds_kmh(radius_m: np.ndarray, policy: WarningSpeedPolicy) -> np.ndarray:
    """V_w of every column and level of ``policy`` at each radius, ``(6, n)``, km/h."""
    return np.concatenate(
        [policy.warning_speeds_kmh(radius_m, np.full(len(radius_m), index)) for index in range(len(Column))]
    )


def _spiral_samples(part: ProfilePart, start_s: float, end_s: float, policy: WarningSpeedPolicy) -> np.ndarray:
    """Arc lengths on ``[start_s, end_s]`` of a clothoid at which V_w moves by about
    :data:`SPIRAL_SAMPLE_KMH` from one to the next: even in 1/sqrt(|curvature|), which V_w
    follows (V_w = sqrt(a R) for a lateral acceleration a)."""
    k_start, k_end = np.abs(part.curvature_at(np.array([start_s, end_s])))
    speeds = _warning_speeds_kmh(1.0 / np.array([k_start, k_end]), policy)
    count = int(
        min(MAX_SPIRAL_SAMPLES, max(2, math.ceil(np.max(np.abs(speeds[:, 1] - speeds[:, 0])) / SPIRAL_SAMPLE_KMH) + 1))
    )
    magnitude = np.linspace(k_start**-0.5, k_end**-0.5, count) ** -2.0
    fraction = (magnitude - k_start) / (k_end - k_start) if k_end != k_start else np.linspace(0.0, 1.0, count)
    return start_s + np.clip(fraction, 0.0, 1.0) * (end_s - start_s)


def _spiral_pieces(
    part: ProfilePart, start_s: float, end_s: float, policy: WarningSpeedPolicy
) -> list[ConstantRadiusPart]:
    """The stretch ``[start_s, end_s]`` of a clothoid cut into pieces whose start points' V_w
    differ from one to the next by less than :data:`SPIRAL_PIECE_KMH` in every column and
    level, each at the radius of its start."""
    s = _spiral_samples(part, start_s, end_s, policy)
    radius = 1.0 / np.abs(part.curvature_at(s))
    speeds = _warning_speeds_kmh(radius, policy)
    starts = [0]
    while True:
        moved = np.max(np.abs(speeds[:, starts[-1] :] - speeds[:, starts[-1], None]), axis=0) >= SPIRAL_PIECE_KMH
        if not moved.any():
            break
        starts.append(starts[-1] + max(1, int(np.argmax(moved)) - 1))
    ends = starts[1:] + [len(s) - 1]
    return [
        ConstantRadiusPart(float(s[a]), float(s[b]), float(radius[a]), spiral=True)
        for a, b in zip(starts, ends, strict=False)
    ]


def _pieces(part: ProfilePart, span: tuple[float, float], policy: WarningSpeedPolicy) -> list[ConstantRadiusPart]:
    """The curvature points of interest of one part's curved stretch."""
    if part.is_spiral:
        return _spiral_pieces(part, *span, policy)
    return [ConstantRadiusPart(span[0], span[1], part.radius_m)]


def _curve(spans: Sequence[tuple[ProfilePart, tuple[float, float]]], sign: float, policy: WarningSpeedPolicy) -> Curve:
    """A curve made of the curved stretches of consecutive parts that turn the same way."""
    angle_rad = sum(
        abs(part.curvature_at_one(start) + part.curvature_at_one(end)) / 2.0 * (end - start)
        for part, (start, end) in spans
    )
    parts = tuple(piece for part, span in spans for piece in _pieces(part, span, policy))
    return Curve(
        start_s=spans[0][1][0],
        end_s=spans[-1][1][1],
        angle_deg=math.degrees(float(angle_rad)),
        direction="left" if sign > 0 else "right",
        min_radius_m=min(part.radius_m for part, _ in spans),
        parts=parts,
    )


def curves_from_profile(
    profile: RadiusProfile, warning_radius_m: float = DEFAULT_WARNING_RADIUS_M, *, policy: WarningSpeedPolicy
) -> list[Curve]:
    """The curves of a radius profile: maximal stretches turning the same way with a radius no
    larger than the warning curvature radius R_c.

    The curve start (3.4) is where the radius becomes <= R_c and the curve end (3.5) where
    it becomes > R_c again, inside a clothoid where there is one; a change of direction
    ends one curve and starts the next, so an S-bend is two curves. A curve of several
    arcs is a multi curve (3.8).

    Parameters
    ----------
    profile
        A profile from :func:`radius_profile` or :func:`radius_profiles`.
    warning_radius_m
        R_c (3.2), m, > 0.
    policy
        The warning speeds the clothoids are cut by (a piece's V_w changes by under
        :data:`SPIRAL_PIECE_KMH`): those the warning uses.

    Returns
    -------
    list[Curve]
        In order along the polyline.
    """
    limit = 1.0 / checked_warning_radius_m(warning_radius_m)
    curves: list[Curve] = []
    run: list[tuple[ProfilePart, tuple[float, float]]] = []
    run_sign = 0.0
    for part in profile.parts:
        spans = [
            (span, sign) for sign in (1.0, -1.0) if (span := _curved_span(part, limit, sign)) and span[1] > span[0]
        ]
        for span, sign in sorted(spans):
            joined = run and sign == run_sign and span[0] <= run[-1][1][1]
            if run and not joined:
                curves.append(_curve(run, run_sign, policy))
                run = []
            run.append((part, span))
            run_sign = sign
        if run and run[-1][0] is not part:
            curves.append(_curve(run, run_sign, policy))
            run = []
    if run:
        curves.append(_curve(run, run_sign, policy))
    return curves
