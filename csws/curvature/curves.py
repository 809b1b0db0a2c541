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
#: A clothoid stretch whose curvature changes by less than this share of its own is sampled evenly in s: the
#: fraction of the change a sample reaches is then lost in rounding (an arc given as a spiral part whose end
#: curvature differs in the last bits).
CURVATURE_CHANGE_FLOOR = 1e-9


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


def _spiral_samples(
    spans: Sequence[tuple[ProfilePart, tuple[float, float]]], policy: WarningSpeedPolicy
) -> tuple[np.ndarray, np.ndarray]:
    """Arc lengths and radii at which consecutive clothoid stretches (``(part, (start_s, end_s))``) are looked at
    when they are cut into pieces: in each, points at which V_w moves by about :data:`SPIRAL_SAMPLE_KMH` from one
    to the next, even in 1/sqrt(|curvature|), which V_w follows (V_w = sqrt(a R) for a lateral acceleration a);
    where one stretch meets the next, the next one's start. All stretches in one pass: a road whose clothoids
    are given as many short linear parts (an exact lane profile) costs no more per part than a few numbers."""
    parts = [part for part, _ in spans]
    start_s = np.array([span[0] for _, span in spans])
    end_s = np.array([span[1] for _, span in spans])
    k_start = np.abs(_curvatures_at(parts, np.arange(len(parts)), start_s))
    k_end = np.abs(_curvatures_at(parts, np.arange(len(parts)), end_s))
    speeds = _warning_speeds_kmh(1.0 / np.concatenate((k_start, k_end)), policy)
    moved_kmh = np.max(np.abs(speeds[:, len(spans) :] - speeds[:, : len(spans)]), axis=0)
    count = np.clip(np.ceil(moved_kmh / SPIRAL_SAMPLE_KMH).astype(np.int64) + 1, 2, MAX_SPIRAL_SAMPLES)
    span = np.repeat(np.arange(len(spans)), count)
    first = np.concatenate(([0], np.cumsum(count)[:-1]))
    step = (np.arange(len(span)) - first[span]) / (count[span] - 1)
    magnitude = (k_start[span] ** -0.5 + step * (k_end[span] ** -0.5 - k_start[span] ** -0.5)) ** -2.0
    change = k_end[span] - k_start[span]
    # Where the curvature hardly changes, the fraction from it is rounding noise: even steps in s instead.
    graded = np.abs(change) > CURVATURE_CHANGE_FLOOR * np.maximum(k_start[span], k_end[span])
    fraction = np.divide(magnitude - k_start[span], change, out=step.copy(), where=graded)
    s = start_s[span] + np.clip(fraction, 0.0, 1.0) * (end_s[span] - start_s[span])
    kept = np.ones(len(s), dtype=bool)
    kept[np.cumsum(count)[:-1] - 1] = False  # a joint is the next stretch's start
    return s[kept], 1.0 / np.abs(_curvatures_at(parts, span[kept], s[kept]))


def _curvatures_at(parts: Sequence[ProfilePart], index: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Signed curvature of ``parts[index[i]]`` at ``s[i]`` for every i (:meth:`ProfilePart.curvature_at`), 1/m."""
    begin, length, k0, k1 = (
        np.array([getattr(part, name) for part in parts])[index]
        for name in ("start_s", "length_m", "curvature", "final_curvature")
    )
    fraction = np.clip(np.divide(s - begin, length, out=np.zeros(len(s)), where=length > 0), 0.0, 1.0)
    return k0 + (k1 - k0) * fraction


def _first_moved(speeds_kmh: np.ndarray, start: int) -> int | None:
    """The first sample after ``start`` whose V_w (``(columns, samples)``) differs from that at ``start`` by
    :data:`SPIRAL_PIECE_KMH` or more in some column, None where none does: looked for in windows doubling in
    width, so that cutting a long run of samples into many pieces reads each sample about once."""
    low, width = start, 64
    while low < speeds_kmh.shape[1]:
        high = min(low + width, speeds_kmh.shape[1])
        window = np.abs(speeds_kmh[:, low:high] - speeds_kmh[:, start, None]).max(axis=0) >= SPIRAL_PIECE_KMH
        if window.any():
            return low + int(np.argmax(window))
        low, width = high, 2 * width
    return None


def _moved_within_monotone(speeds_kmh: np.ndarray, radius_m: np.ndarray) -> np.ndarray:
    """For every sample, the first later one whose V_w differs from its own by :data:`SPIRAL_PIECE_KMH` or more in
    some column, looked for along its stretch of monotone radius (where V_w of every column is monotone, so one
    sorted search per column finds it for all samples at once); the sample count where it is not on that stretch."""
    count = speeds_kmh.shape[1]
    found = np.full(count, count)
    turns = np.flatnonzero(np.diff(np.sign(np.diff(radius_m))) != 0) + 1
    bounds = [0, *turns.tolist(), count - 1]
    for low, high in zip(bounds[:-1], bounds[1:], strict=True):
        rising = radius_m[high] >= radius_m[low]
        stretch = speeds_kmh[:, low : high + 1] * (1.0 if rising else -1.0)
        first = np.min([np.searchsorted(row, row + SPIRAL_PIECE_KMH, side="left") for row in stretch], axis=0)
        found[low : high + 1] = np.where(first <= high - low, low + first, count)
    return found


def _spiral_pieces(
    spans: Sequence[tuple[ProfilePart, tuple[float, float]]], policy: WarningSpeedPolicy
) -> list[ConstantRadiusPart]:
    """Consecutive clothoid stretches cut into pieces whose start points' V_w differ from one to the next by less
    than :data:`SPIRAL_PIECE_KMH` in every column and level, each at the radius of its start."""
    s, radius = _spiral_samples(spans, policy)
    speeds = _warning_speeds_kmh(radius, policy)
    within = _moved_within_monotone(speeds, radius)
    starts = [0]
    while True:
        start = starts[-1]
        moved = int(within[start]) if within[start] < len(s) else _first_moved(speeds, start)
        if moved is None:
            break
        starts.append(start + max(1, moved - start - 1))
    ends = starts[1:] + [len(s) - 1]
    return [
        ConstantRadiusPart(float(s[a]), float(s[b]), float(radius[a]), spiral=True)
        for a, b in zip(starts, ends, strict=False)
    ]


def _pieces(
    spans: Sequence[tuple[ProfilePart, tuple[float, float]]], policy: WarningSpeedPolicy
) -> list[ConstantRadiusPart]:
    """The curvature points of interest of a curve's curved stretches: each arc one, each run of consecutive
    clothoid stretches cut into pieces together (:func:`_spiral_pieces`)."""
    pieces: list[ConstantRadiusPart] = []
    run: list[tuple[ProfilePart, tuple[float, float]]] = []
    for part, span in spans:
        if part.is_spiral:
            run.append((part, span))
            continue
        if run:
            pieces += _spiral_pieces(run, policy)
            run = []
        pieces.append(ConstantRadiusPart(span[0], span[1], part.radius_m))
    return pieces + (_spiral_pieces(run, policy) if run else [])


def _curve(spans: Sequence[tuple[ProfilePart, tuple[float, float]]], sign: float, policy: WarningSpeedPolicy) -> Curve:
    """A curve made of the curved stretches of consecutive parts that turn the same way."""
    angle_rad = sum(
        abs(part.curvature_at_one(start) + part.curvature_at_one(end)) / 2.0 * (end - start)
        for part, (start, end) in spans
    )
    parts = tuple(_pieces(spans, policy))
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
