"""Radius profiles and curves of road polylines (T/ITS 0091-2018, 3.2-3.8).

A road centreline arrives as a polyline: a dense SUMO lane shape (vertices 0.5-1 m
apart, coordinates rounded to 1 cm) or a sparse map way (nodes 5-30 m apart with
decimetre-level noise). The radius through three consecutive vertices is useless on
both: on a dense shape a 1 cm rounding error bends a 0.5 m chord by more than a
500 m curve does. This module therefore models the road as the standard does, as
straights and constant-radius curves joined at points (3.4-3.8), and fits that model
to the whole polyline:

1. Each chord's heading belongs to the arc length of its midpoint (on a circle the
   chord is parallel to the tangent there), so heading against arc length is
   continuous and piecewise linear, its slope being the curvature.
2. The heading is cut into parts of constant curvature by binary segmentation: a
   part is split where two lines fit its headings significantly better than one,
   judged against the coordinate noise estimated from the polyline itself.
3. Each knot (curvature step) is moved to where the lines fitted to its two parts
   intersect, chords straddling it are left out of the fits, and neighbouring parts
   that one line fits as well are merged. Two lines that do not cross mean a curve
   shorter than its neighbours' resolution; the chords around it become its own part.
4. The chords of the curved parts are converted to arc lengths (a chord of length c
   on radius R spans ``2 R asin(c / 2R)``) and the parts are fitted once more.

A curve (3.4, 3.5) is then a maximal run of parts turning the same way with a radius
no larger than the warning curvature radius R_c; its parts are the constant-radius
parts of a single (3.7) or multi curve (3.8).

All polylines of a network are processed together in flat arrays, so the number of
numpy operations does not grow with the number of lanes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .standard import DEFAULT_WARNING_RADIUS_M

__all__ = [
    "ProfilePart",
    "RadiusProfile",
    "ConstantRadiusPart",
    "Curve",
    "radius_profile",
    "radius_profiles",
    "curves_from_profile",
    "find_curves",
    "three_point_radius",
]

#: Chords shorter than this are treated as repeated vertices, m.
MIN_CHORD_M = 1e-6
#: Lower bound of the coordinate noise, m: that of rounding to the centimetre, as SUMO
#: writes shapes. Rounding a regularly spaced line can leave errors too regular for
#: :func:`_coordinate_noise_m` to see, yet they still bend short chords.
MIN_NOISE_M = 0.01 / math.sqrt(12.0)
#: Fewest chords a part of constant curvature is fitted over.
MIN_PART_CHORDS = 2
#: A split (or a knot kept) must reduce the normalised residual by PENALTY * ln(chords) + OFFSET.
SPLIT_PENALTY = 2.0
SPLIT_OFFSET = 15.0
#: Knot refinement passes between two merge tests.
REFINE_PASSES = 4
#: A chord straddles a knot when the knot lies more than this fraction of it from either end.
STRADDLE_FRACTION = 0.05
#: Fewest noise samples a polyline's noise is taken as their median from (else their RMS).
MIN_MEDIAN_SAMPLES = 10
#: Converts the median absolute deviation of a normal sample into its standard deviation.
MAD_TO_SIGMA = 1.4826
#: A polyline whose median chord is at least this long is a sparse one (a map way), m.
SPARSE_CHORD_M = 3.0
#: Fewest and most chords a polyline is fitted as a sparse one with (the sparse fit is
#: per polyline and grows with the square of its chords; longer ones take the dense path).
MIN_SPARSE_CHORDS = 4
MAX_SPARSE_CHORDS = 80
#: Positions tried around the best vertex or chord middle when placing a sparse knot.
FINE_KNOT_STEPS = 16
#: Passes moving each knot of a sparse polyline to its best place.
SPARSE_REFINE_PASSES = 2
#: A pair of knots added together must pass this many times the threshold of one.
PAIR_THRESHOLD_FACTOR = 2.0
#: Lower bound of the coordinate noise of a sparse polyline, m: a map way's nodes are not
#: placed more precisely than this, and the fit's own approximation stays below it.
SPARSE_MIN_NOISE_M = 0.05
#: Sparse chords shorter than this many times the coordinate noise are joined with the next.
SHORT_CHORD_NOISE_FACTOR = 5.0
#: A knot of a sparse polyline must reduce the normalised residual by SPLIT_PENALTY * ln(chords) + this.
SPARSE_KNOT_OFFSET = 10.0
#: A part of a sparse polyline is curved only if making it straight grows the normalised residual by more.
SPARSE_STRAIGHT_THRESHOLD = 20.0


@dataclass(frozen=True)
class ProfilePart:
    """A stretch of constant curvature found in a polyline.

    Attributes
    ----------
    start_s, end_s
        Arc length of its ends along the polyline, m.
    curvature
        Signed curvature, 1/m, positive turning left.
    """

    start_s: float
    end_s: float
    curvature: float

    @property
    def radius_m(self) -> float:
        """Radius of the part, m; ``inf`` on a straight."""
        with np.errstate(over="ignore"):
            return float(np.divide(1.0, abs(self.curvature))) if self.curvature else math.inf

    @property
    def length_m(self) -> float:
        """Arc length of the part, m."""
        return self.end_s - self.start_s


@dataclass(frozen=True)
class RadiusProfile:
    """Curvature and radius along a polyline.

    Attributes
    ----------
    s
        Arc length along the polyline at each input vertex, m (``s[0] == 0``; a repeated
        vertex has the arc length of the one it repeats).
    curvature
        Signed curvature at each vertex, 1/m, positive turning left: that of the part the
        vertex lies in, or of the part starting at it when it is a knot.
    radius
        ``1 / |curvature|`` at each vertex, m; ``inf`` on straights.
    parts
        The parts of constant curvature the vertex values come from, in order, covering
        ``[0, s[-1]]``; empty when the polyline has no length.
    """

    s: np.ndarray
    curvature: np.ndarray
    radius: np.ndarray
    parts: tuple[ProfilePart, ...]


@dataclass(frozen=True)
class ConstantRadiusPart:
    """A constant-radius part of a curve: the whole of a single curve (3.7) or one of the
    directly joined curves of a multi curve (3.8).

    Attributes
    ----------
    start_s, end_s
        Arc length of its ends along the polyline, m.
    radius_m
        Its radius, m.
    """

    start_s: float
    end_s: float
    radius_m: float


@dataclass(frozen=True)
class Curve:
    """A curve: a stretch whose radius is at most the warning curvature radius R_c.

    Attributes
    ----------
    start_s
        Curve start point (3.4): where the radius becomes <= R_c, m along the polyline.
    end_s
        Curve end point (3.5): where the radius becomes > R_c again (or the road turns
        the other way), m.
    angle_deg
        Curve angle (3.6): the central angle between start and end, degrees, unsigned.
    direction
        ``"left"`` or ``"right"``.
    min_radius_m
        The smallest radius in the curve, m.
    parts
        Its constant-radius parts: one for a single curve (3.7), two or more for a multi
        curve (3.8).
    """

    start_s: float
    end_s: float
    angle_deg: float
    direction: str
    min_radius_m: float
    parts: tuple[ConstantRadiusPart, ...]

    @property
    def is_multi(self) -> bool:
        """Whether this is a multi curve (3.8): two or more directly joined constant-radius curves."""
        return len(self.parts) >= 2


# --------------------------------------------------------------------------- input


def _validated(xy: np.ndarray, index: int | None = None) -> np.ndarray:
    """``xy`` as a float ``(n, 2)`` array; ValueError on a wrong shape or non-finite coordinates."""
    where = "" if index is None else f" (polyline {index})"
    try:
        points = np.asarray(xy, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"polyline{where} must be an (n, 2) array of numbers") from None
    if points.size == 0:
        return np.empty((0, 2))
    if points.ndim != 2 or points.shape[1] != 2:
        raise ValueError(f"polyline{where} must have shape (n, 2), got {points.shape}")
    if not np.all(np.isfinite(points)):
        raise ValueError(f"polyline{where} has NaN or infinite coordinates")
    return points


@dataclass(frozen=True)
class _Chords:
    """The chords of many polylines, concatenated, with repeated vertices dropped.

    ``polyline_first_chord[p]:polyline_first_chord[p + 1]`` are the chords of polyline p.
    ``vertex_s`` is the arc length at every input vertex, flat over all polylines.
    """

    start_s: np.ndarray
    length_m: np.ndarray
    heading: np.ndarray
    polyline: np.ndarray
    polyline_first_chord: np.ndarray
    vertex_s: np.ndarray
    polyline_first_vertex: np.ndarray


def _chords(polylines: Sequence[np.ndarray]) -> _Chords:
    """Chords, headings and vertex arc lengths of all polylines in flat arrays."""
    counts = np.array([len(p) for p in polylines], dtype=np.int64)
    first_vertex = np.concatenate(([0], np.cumsum(counts)))
    points = np.concatenate([np.empty((0, 2)), *polylines])
    polyline_of_vertex = np.repeat(np.arange(len(polylines)), counts)
    step = np.diff(points, axis=0)
    step_m = np.hypot(step[:, 0], step[:, 1])
    # A chord joins vertex i to i + 1 of the same polyline; repeated vertices add none.
    is_chord = (polyline_of_vertex[1:] == polyline_of_vertex[:-1]) & (step_m > MIN_CHORD_M)
    along_m = np.concatenate(([0.0], np.cumsum(np.where(is_chord, step_m, 0.0))))
    vertex_s = along_m - along_m[first_vertex[:-1]][polyline_of_vertex]
    chord_index = np.flatnonzero(is_chord)
    polyline = polyline_of_vertex[chord_index]
    heading = np.unwrap(np.arctan2(step[chord_index, 1], step[chord_index, 0]))
    return _Chords(
        start_s=vertex_s[chord_index],
        length_m=step_m[chord_index],
        heading=heading,
        polyline=polyline,
        polyline_first_chord=np.searchsorted(polyline, np.arange(len(polylines) + 1)),
        vertex_s=vertex_s,
        polyline_first_vertex=first_vertex,
    )


# --------------------------------------------------------------------------- noise


def _group_median(values: np.ndarray, group: np.ndarray, group_count: int) -> np.ndarray:
    """Median of ``values`` per group (groups numbered 0..group_count-1); NaN for an empty group."""
    order = np.lexsort((values, group))
    sorted_values = values[order]
    starts = np.searchsorted(group[order], np.arange(group_count + 1))
    sizes = np.diff(starts)
    median = np.full(group_count, np.nan)
    filled = sizes > 0
    low = starts[:-1][filled] + (sizes[filled] - 1) // 2
    high = starts[:-1][filled] + sizes[filled] // 2
    median[filled] = 0.5 * (sorted_values[low] + sorted_values[high])
    return median


def _coordinate_noise_m(chords: _Chords, polyline_count: int) -> np.ndarray:
    """Standard deviation of the vertices' sideways noise per polyline, m.

    The change of the discrete curvature between consecutive vertex triples cancels any
    constant curvature and leaves a known combination of the sideways errors of four
    vertices; its median absolute value, scaled to that combination, estimates the
    noise robustly (knots spoil only a few samples). Polylines too short for an
    estimate get the floor :data:`MIN_NOISE_M`.
    """
    c = chords.length_m
    inverse = 1.0 / c
    same = chords.polyline[2:] == chords.polyline[:-2]
    mean_0 = 0.5 * (c[:-2] + c[1:-1])  # between chords j and j + 1
    mean_1 = 0.5 * (c[1:-1] + c[2:])  # between chords j + 1 and j + 2
    turn = np.diff(chords.heading)
    curvature_change = turn[1:] / mean_1 - turn[:-1] / mean_0
    e0, e1, e2 = inverse[:-2], inverse[1:-1], inverse[2:]
    gain = np.sqrt(
        (e0 / mean_0) ** 2
        + (e1 / mean_1 + (e0 + e1) / mean_0) ** 2
        + ((e1 + e2) / mean_1 + e1 / mean_0) ** 2
        + (e2 / mean_1) ** 2
    )
    sample = np.abs(curvature_change[same]) / gain[same]
    group = chords.polyline[:-2][same]
    noise = MAD_TO_SIGMA * _group_median(sample, group, polyline_count)
    # A median of a handful of samples is often far too small; there the root mean
    # square, which errs on the large side, is the safer estimate.
    count = np.bincount(group, minlength=polyline_count)
    rms = np.sqrt(np.bincount(group, sample**2, minlength=polyline_count) / np.fmax(count, 1))
    noise = np.where(count < MIN_MEDIAN_SAMPLES, rms, noise)
    return np.fmax(np.nan_to_num(noise, nan=MIN_NOISE_M), MIN_NOISE_M)


# --------------------------------------------------------------------------- line fits


@dataclass(frozen=True)
class _Fit:
    """Weighted line fits of heading against arc length, one per part."""

    mean_s: np.ndarray
    mean_heading: np.ndarray
    curvature: np.ndarray


def _prefix_sums(mid_s: np.ndarray, heading: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """Running sums of w, w s, w s^2, w h, w s h, w h^2 over the chords, each with a leading 0.

    ``mid_s`` and ``heading`` should be centred per polyline to keep the sums small.
    """
    terms = np.stack(
        (weight, weight * mid_s, weight * mid_s**2, weight * heading, weight * mid_s * heading, weight * heading**2)
    )
    return np.concatenate((np.zeros((6, 1)), np.cumsum(terms, axis=1)), axis=1)


def _level_and_slope_sums(prefix: np.ndarray, first: np.ndarray, stop: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For chords ``first:stop``: the weighted sum of squares about the mean heading, and
    the part of it a sloped line explains."""
    sw, sx, sxx, sy, sxy, syy = prefix[:, stop] - prefix[:, first]
    with np.errstate(divide="ignore", invalid="ignore"):
        cxx = sxx - sx * sx / sw
        cxy = sxy - sx * sy / sw
        about_mean = np.nan_to_num(syy - sy * sy / sw)
        explained = np.nan_to_num(np.where(cxx > 0, cxy * cxy / cxx, 0.0))
    return about_mean, explained


def _residual(prefix: np.ndarray, first: np.ndarray, stop: np.ndarray) -> np.ndarray:
    """Weighted residual sum of squares of the line fitted to chords ``first:stop``."""
    about_mean, explained = _level_and_slope_sums(prefix, first, stop)
    return np.fmax(about_mean - explained, 0.0)


def _fit_parts(mid_s: np.ndarray, heading: np.ndarray, weight: np.ndarray, starts: np.ndarray) -> _Fit:
    """Weighted least-squares line of heading against ``mid_s`` over each part.

    Parts are chord ranges ``starts[i]:starts[i + 1]`` (the last runs to the end).
    """
    total = np.add.reduceat(weight, starts)
    mean_s = np.add.reduceat(weight * mid_s, starts) / total
    mean_heading = np.add.reduceat(weight * heading, starts) / total
    sizes = np.diff(np.append(starts, len(mid_s)))
    ds = mid_s - np.repeat(mean_s, sizes)
    dh = heading - np.repeat(mean_heading, sizes)
    sxx = np.add.reduceat(weight * ds * ds, starts)
    sxy = np.add.reduceat(weight * ds * dh, starts)
    with np.errstate(divide="ignore", invalid="ignore"):
        curvature = np.where(sxx > 0, sxy / sxx, 0.0)
    return _Fit(mean_s, mean_heading, curvature)


def _split_threshold(chord_count: np.ndarray) -> np.ndarray:
    """Least normalised residual reduction that justifies a knot in a part of ``chord_count`` chords.

    Grows with the logarithm of the number of places a knot could go, so that a long
    noisy straight does not get a knot by chance.
    """
    return SPLIT_PENALTY * np.log(np.fmax(chord_count, 1)) + SPLIT_OFFSET


# --------------------------------------------------------------------------- the network model


class _Segmentation:
    """Parts of constant curvature for all chords of a network.

    Parts are chord ranges; ``starts`` holds the first chord of every part (every
    polyline's first chord among them) and ``knot_s`` the refined arc length of each
    part's start (a polyline's own start for its first part).
    """

    def __init__(self, chords: _Chords, noise_m: np.ndarray) -> None:
        self.chords = chords
        self.chord_count = len(chords.length_m)
        self.noise_variance = 2.0 * noise_m[chords.polyline] ** 2  # of a chord heading times its length
        self.weight = chords.length_m**2  # headings of long chords are the more precise
        self.start_s = chords.start_s
        self.length_m = chords.length_m
        self.polyline_starts = chords.polyline_first_chord[:-1][np.diff(chords.polyline_first_chord) > 0]
        self.starts = self.polyline_starts.copy()
        self.knot_s = self.start_s[self.starts]

    # -- geometry of the current arc-length coordinates

    @property
    def mid_s(self) -> np.ndarray:
        return self.start_s + 0.5 * self.length_m

    def _centred(self) -> tuple[np.ndarray, np.ndarray]:
        """Chord mid arc lengths and headings centred per polyline (keeps running sums small)."""
        polyline = self.chords.polyline
        count = np.bincount(polyline)
        used = count > 0
        mean_s = np.bincount(polyline, self.mid_s)[used] / count[used]
        mean_h = np.bincount(polyline, self.chords.heading)[used] / count[used]
        sizes = count[used]
        return self.mid_s - np.repeat(mean_s, sizes), self.chords.heading - np.repeat(mean_h, sizes)

    def _ends(self) -> np.ndarray:
        return np.append(self.starts[1:], self.chord_count)

    def _is_knot(self) -> np.ndarray:
        """Whether each part start is a knot rather than the start of a polyline."""
        return ~np.isin(self.starts, self.polyline_starts)

    # -- step 2: binary segmentation

    def split_until_stable(self) -> None:
        """Split parts where two lines fit significantly better than one, until none is."""
        mid_s, heading = self._centred()
        prefix = _prefix_sums(mid_s, heading, self.weight)
        while self._split_once(prefix):
            pass
        self.knot_s = self.start_s[self.starts]

    def _split_once(self, prefix: np.ndarray) -> bool:
        first, stop = self.starts, self._ends()
        sizes = stop - first
        candidate_counts = np.fmax(sizes - 2 * MIN_PART_CHORDS + 1, 0)
        if candidate_counts.sum() == 0:
            return False
        part = np.repeat(np.arange(len(first)), candidate_counts)
        rank = np.arange(len(part)) - np.repeat(np.cumsum(candidate_counts) - candidate_counts, candidate_counts)
        split = first[part] + MIN_PART_CHORDS + rank
        whole = _residual(prefix, first, stop)[part]
        gain = (whole - _residual(prefix, first[part], split) - _residual(prefix, split, stop[part]))
        gain /= self.noise_variance[split]
        order = np.lexsort((-gain, part))
        best = order[np.searchsorted(part[order], np.unique(part))]
        accepted = best[gain[best] > _split_threshold(sizes[part[best]])]
        if len(accepted) == 0:
            return False
        self.starts = np.sort(np.concatenate((self.starts, split[accepted])))
        return True

    # -- step 3: knot refinement and merging

    def refine_until_stable(self) -> None:
        """Refine the knots and merge parts that one line fits as well, until nothing merges."""
        while True:
            for _ in range(REFINE_PASSES):
                self._refine_once()
            if not self._merge_once():
                return

    def _fit_weight(self) -> np.ndarray:
        """Chord weights with chords straddling a knot left out, unless their part needs them."""
        knots = self.knot_s[self._is_knot()]
        part_of_chord = np.repeat(np.arange(len(self.starts)), np.diff(np.append(self.starts, self.chord_count)))
        polyline = self.chords.polyline
        offset = self._polyline_offset_s()
        start_g = self.start_s + offset[polyline]
        knot_g = knots + offset[polyline[self.starts[self._is_knot()]]]
        # The first knot after each chord start, in network-wide arc length.
        knot_after = np.append(knot_g, np.inf)[np.searchsorted(knot_g, start_g, side="right")]
        margin = STRADDLE_FRACTION * self.length_m
        straddles = (knot_after - start_g > margin) & (start_g + self.length_m - knot_after > margin)
        weight = np.where(straddles, 0.0, self.weight)
        kept = np.add.reduceat((weight > 0).astype(np.int64), self.starts)
        needs_all = kept[part_of_chord] < MIN_PART_CHORDS
        return np.where(needs_all, self.weight, weight)

    def _polyline_offset_s(self) -> np.ndarray:
        """A network-wide arc-length offset per polyline that keeps polylines apart."""
        lengths = np.zeros(len(self.chords.polyline_first_chord) - 1)
        np.maximum.at(lengths, self.chords.polyline, self.start_s + self.length_m)
        return np.concatenate(([0.0], np.cumsum(lengths + 1.0)))[:-1]

    def fit(self) -> _Fit:
        """The line of every part, fitted without the chords straddling its knots."""
        mid_s, heading = self.mid_s, self.chords.heading
        return _fit_parts(mid_s, heading, self._fit_weight(), self.starts)

    def _crossings(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Where the lines of the two parts at each knot cross.

        Returns the index of the part each knot starts, the crossing's arc length (the
        current chord boundary where the lines do not cross between the two parts'
        centres) and whether they do cross there. Lines that do not cross mean a heading step: a
        curve too short for the parts to resolve.
        """
        fit = self.fit()
        after = np.flatnonzero(self._is_knot())
        before = after - 1
        slope_change = fit.curvature[before] - fit.curvature[after]
        with np.errstate(divide="ignore", invalid="ignore"):
            crossing = (
                fit.mean_heading[after]
                - fit.mean_heading[before]
                - fit.curvature[after] * fit.mean_s[after]
                + fit.curvature[before] * fit.mean_s[before]
            ) / slope_change
        # Between the two parts' centres: neighbouring knots then cannot pass each other.
        crosses = np.isfinite(crossing) & (crossing > fit.mean_s[before]) & (crossing < fit.mean_s[after])
        return after, np.where(crosses, crossing, self.start_s[self.starts[after]]), crosses

    def _refine_once(self) -> None:
        """Move each knot to where the lines of its two parts cross, and its chord boundary with it."""
        if not self._is_knot().any():
            return
        after, knot, _ = self._crossings()
        self.knot_s = self.knot_s.copy()
        self.knot_s[after] = knot
        self._move_boundaries(after, knot)
        self.knot_s = self._ordered_knots()

    def open_steps(self) -> None:
        """Give each heading step a part of its own: the chords either side of it.

        A curve shorter than the parts around it shows as a step between two lines that
        do not cross. Its own part, fitted to the chords that straddle it, turns the
        step into a short curve whose ends are where its line crosses its neighbours'.
        """
        for _ in range(REFINE_PASSES):
            self._refine_once()
        if not self._is_knot().any():
            return
        after, _, crosses = self._crossings()
        ends = self._ends()
        step = after[~crosses]
        room = (self.starts[step] - self.starts[step - 1] >= MIN_PART_CHORDS + 1) & (
            ends[step] - self.starts[step] >= MIN_PART_CHORDS + 1
        )
        step = step[room]
        self.starts = np.concatenate((np.delete(self.starts, step), self.starts[step] - 1, self.starts[step] + 1))
        self.knot_s = np.concatenate((np.delete(self.knot_s, step), self.start_s[self.starts[-2 * len(step):]]))
        order = np.argsort(self.starts, kind="stable")
        self.starts, self.knot_s = self.starts[order], self.knot_s[order]

    def _move_boundaries(self, after: np.ndarray, knot: np.ndarray) -> None:
        """Start each knot's part at the vertex nearest the knot, keeping every part MIN_PART_CHORDS long."""
        polyline = self.chords.polyline
        offset = self._polyline_offset_s()[polyline]
        start_g = self.start_s + offset
        knot_g = knot + offset[self.starts[after]]
        nearest = np.clip(np.searchsorted(start_g, knot_g), 1, self.chord_count - 1)
        nearer_previous = (knot_g - start_g[nearest - 1]) < (start_g[nearest] - knot_g)
        target = nearest - nearer_previous
        old = self.starts.copy()
        old_sizes = np.diff(np.append(old, self.chord_count))
        new = old.copy()
        new[after] = target
        while True:
            sizes = np.diff(np.append(new, self.chord_count))
            short = np.flatnonzero(sizes < np.minimum(old_sizes, MIN_PART_CHORDS))
            if len(short) == 0:
                break
            revert = np.concatenate((short, np.minimum(short + 1, len(new) - 1)))
            new[revert] = old[revert]
        self.starts = new

    def _ordered_knots(self) -> np.ndarray:
        """Knot arc lengths made non-decreasing along each polyline."""
        offset = self._polyline_offset_s()[self.chords.polyline[self.starts]]
        return np.maximum.accumulate(self.knot_s + offset) - offset

    def _merge_once(self) -> bool:
        """Drop the knots that do not reduce the residual significantly; a knot goes only
        when it is the least significant of its neighbours, so each merge is tested alone."""
        is_knot = self._is_knot()
        if not is_knot.any():
            return False
        mid_s, heading = self._centred()
        prefix = _prefix_sums(mid_s, heading, self._fit_weight())
        ends = self._ends()
        after = np.flatnonzero(is_knot)
        before = after - 1
        first, middle, stop = self.starts[before], self.starts[after], ends[after]
        gain = _residual(prefix, first, stop) - _residual(prefix, first, middle) - _residual(prefix, middle, stop)
        gain /= self.noise_variance[middle]
        significance = np.full(len(self.starts), np.inf)
        significance[after] = gain - _split_threshold(stop - first)
        left = np.concatenate(([np.inf], significance[:-1]))
        right = np.concatenate((significance[1:], [np.inf]))
        drop = (significance < 0) & (significance <= left) & (significance < right)
        if not drop.any():
            return False
        keep = ~drop
        self.starts = self.starts[keep]
        self.knot_s = self.knot_s[keep]
        return True

    # -- step 4: chord to arc length

    def fit_on_arc_lengths(self) -> _Fit:
        """Refit with each chord's length replaced by the arc it spans on its part's curvature.

        A chord c on radius R spans an arc ``2 R asin(c / 2R)``; on sparse polylines of
        tight curves the difference reaches several percent of the radius. The returned
        curvatures are per arc length; the knots are mapped back to the polyline's own
        (chord) arc length.
        """
        fit = self.fit()
        sizes = np.diff(np.append(self.starts, self.chord_count))
        curvature = np.abs(np.repeat(fit.curvature, sizes))
        half_angle = np.arcsin(np.clip(0.5 * self.chords.length_m * curvature, 0.0, 1.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            arc_m = np.where(curvature > 0, 2.0 * half_angle / curvature, self.chords.length_m)
        old_start = self.start_s
        first = self.chords.polyline_first_chord
        along = np.cumsum(arc_m)
        along_before = np.concatenate(([0.0], along))[first[:-1]][self.chords.polyline]
        self.start_s = along - arc_m - along_before
        self.length_m = arc_m
        self.knot_s = self._map_s(self.knot_s, old_start, self.chords.length_m, self.start_s, self.length_m)
        self.refine_until_stable()
        arc_fit = self._without_insignificant_curvature(self.fit())
        self.knot_s = self._map_s(self.knot_s, self.start_s, self.length_m, old_start, self.chords.length_m)
        self.start_s, self.length_m = old_start, self.chords.length_m
        return arc_fit

    def _without_insignificant_curvature(self, fit: _Fit) -> _Fit:
        """``fit`` with the curvature of knotless polylines set to 0 where a sloped line
        does not fit their headings significantly better than a level one, by the same
        measure a knot must pass: a few noisy nodes on a straight must not make a curve.
        (Parts beside a knot keep their curvature: the knot already proved the change.)"""
        mid_s, heading = self._centred()
        prefix = _prefix_sums(mid_s, heading, self._fit_weight())
        first, stop = self.starts, self._ends()
        gain = _level_and_slope_sums(prefix, first, stop)[1] / self.noise_variance[first]
        alone = ~self._is_knot() & ~np.isin(stop, self.starts[self._is_knot()])
        significant = (gain > _split_threshold(stop - first)) | ~alone
        return _Fit(fit.mean_s, fit.mean_heading, np.where(significant, fit.curvature, 0.0))

    def _map_s(
        self,
        knot_s: np.ndarray,
        from_start: np.ndarray,
        from_length: np.ndarray,
        to_start: np.ndarray,
        to_length: np.ndarray,
    ) -> np.ndarray:
        """Knots from one arc-length coordinate of the chords to another, linearly within a chord."""
        polyline = self.chords.polyline[self.starts]
        offset = self._polyline_offset_s()
        from_g = from_start + offset[self.chords.polyline]
        knot_g = knot_s + offset[polyline]
        chord = np.clip(np.searchsorted(from_g, knot_g, side="right") - 1, self.chords.polyline_first_chord[polyline], None)
        fraction = np.clip((knot_g - from_g[chord]) / from_length[chord], 0.0, 1.0)
        return to_start[chord] + fraction * to_length[chord]


# --------------------------------------------------------------------------- sparse polylines


@dataclass(frozen=True)
class _Chordset:
    """One polyline's chords in an arc-length coordinate ``u``: chord i spans ``[a[i], b[i]]``.

    ``heading`` is each chord's (unwrapped) heading and ``root_weight`` the square root
    of its fit weight (its chord length: a long chord's heading is the more precise).
    """

    a: np.ndarray
    b: np.ndarray
    heading: np.ndarray
    root_weight: np.ndarray

    @property
    def end(self) -> float:
        return float(self.b[-1])


def _chord_means_of_ramps(chords: _Chordset, ramp_start: np.ndarray, ramp_length: np.ndarray) -> np.ndarray:
    """Mean over each chord of each ramp ``clip(u - start, 0, length)``, ``(chords, ramps)``.

    A chord's direction is the mean of the road's heading over the arc it spans (exact
    on a circle), so a heading that is continuous and piecewise linear in ``u`` (a sum
    of ramps) predicts every chord's heading linearly, including chords across a knot.
    """

    def integral(u: np.ndarray) -> np.ndarray:
        past = u[:, None] - ramp_start[None, :]
        return 0.5 * np.clip(past, 0.0, ramp_length) ** 2 + ramp_length * np.fmax(past - ramp_length, 0.0)

    return (integral(chords.b) - integral(chords.a)) / (chords.b - chords.a)[:, None]


def _ramp_design(chords: _Chordset, bounds: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Weighted design matrix of a continuous heading with knots at ``bounds[1:-1]``: a
    level and one slope (curvature) per part, only for the parts marked ``free``."""
    ramps = _chord_means_of_ramps(chords, bounds[:-1][free], np.diff(bounds)[free])
    return np.column_stack((np.ones(len(chords.a)), ramps)) * chords.root_weight[:, None]


def _residual_and_fit(chords: _Chordset, bounds: np.ndarray, free: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Weighted residual sum of squares, coefficients and their unscaled covariance."""
    design = _ramp_design(chords, bounds, free)
    target = chords.heading * chords.root_weight
    coefficients, *_ = np.linalg.lstsq(design, target, rcond=None)
    residual = target - design @ coefficients
    covariance = np.linalg.pinv(design.T @ design)
    return float(residual @ residual), coefficients, covariance


def _residualised(chords: _Chordset, bounds: np.ndarray, candidates: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The residual of the continuous fit with knots ``bounds[1:-1]`` (all parts free), and
    the hinge column of a knot at each candidate with that fit's columns projected out.

    Also returns whether each projected column is far enough from 0 to be a new knot.
    """
    design = _ramp_design(chords, bounds, np.ones(len(bounds) - 1, dtype=bool))
    basis, _ = np.linalg.qr(design)
    target = chords.heading * chords.root_weight
    residual = target - basis @ (basis.T @ target)
    hinge = _chord_means_of_ramps(chords, candidates, chords.end + 1.0 - candidates) * chords.root_weight[:, None]
    scale = np.einsum("ij,ij->j", hinge, hinge)
    hinge -= basis @ (basis.T @ hinge)
    usable = np.einsum("ij,ij->j", hinge, hinge) > 1e-9 * scale
    return residual, hinge, usable


def _knot_gains(chords: _Chordset, bounds: np.ndarray, candidates: np.ndarray) -> np.ndarray:
    """Reduction of the weighted residual from adding a knot at each candidate to the
    continuous fit with knots ``bounds[1:-1]`` (all parts free)."""
    residual, hinge, usable = _residualised(chords, bounds, candidates)
    with np.errstate(divide="ignore", invalid="ignore"):
        gain = (residual @ hinge) ** 2 / np.einsum("ij,ij->j", hinge, hinge)
    return np.where(usable, gain, 0.0)


def _best_knot_pair(chords: _Chordset, bounds: np.ndarray) -> tuple[np.ndarray, float]:
    """The two knots at vertices or chord middles that together reduce the residual most,
    and that reduction. A curve between straights, or one shorter than the chords around
    it, needs both its knots before either pays off on its own."""
    candidates = _coarse_candidates(chords, 0.0, chords.end)
    residual, hinge, usable = _residualised(chords, bounds, candidates)
    hinge, candidates = hinge[:, usable], candidates[usable]
    if len(candidates) < 2:
        return candidates, 0.0
    gram = hinge.T @ hinge
    along = hinge.T @ residual
    diagonal = np.diag(gram)
    determinant = np.outer(diagonal, diagonal) - gram**2
    with np.errstate(divide="ignore", invalid="ignore"):
        gain = (np.outer(along**2, diagonal) - 2.0 * np.outer(along, along) * gram + np.outer(diagonal, along**2)) / determinant
    gain = np.where(determinant > 1e-6 * np.outer(diagonal, diagonal), gain, 0.0)
    first, second = np.unravel_index(int(np.argmax(np.triu(gain, 1))), gain.shape)
    return candidates[[first, second]], float(gain[first, second])


def _coarse_candidates(chords: _Chordset, low: float, high: float) -> np.ndarray:
    """The vertices and chord middles strictly between ``low`` and ``high``."""
    coarse = np.concatenate((chords.a, 0.5 * (chords.a + chords.b), [chords.end]))
    return np.unique(coarse[(coarse > low) & (coarse < high)])


def _best_knot(chords: _Chordset, bounds: np.ndarray, low: float, high: float) -> tuple[float, float]:
    """The knot strictly between ``low`` and ``high`` that reduces the residual most, and
    that reduction: searched at the vertices and chord middles, then finely around the best."""
    coarse = _coarse_candidates(chords, low, high)
    if len(coarse) == 0:
        return low, 0.0
    gain = _knot_gains(chords, bounds, coarse)
    best = int(np.argmax(gain))
    fine_low = coarse[best - 1] if best > 0 else low
    fine_high = coarse[best + 1] if best + 1 < len(coarse) else high
    fine = np.linspace(fine_low, fine_high, FINE_KNOT_STEPS + 2)[1:-1]
    fine_gain = _knot_gains(chords, bounds, fine)
    if fine_gain.max() > gain[best]:
        return float(fine[np.argmax(fine_gain)]), float(fine_gain.max())
    return float(coarse[best]), float(gain[best])


def _with_knot(bounds: np.ndarray, knot: float) -> np.ndarray:
    return np.sort(np.append(bounds, knot))


def _refined_knots(chords: _Chordset, bounds: np.ndarray) -> np.ndarray:
    """Each knot in turn moved to where it fits best between its neighbours."""
    for _ in range(SPARSE_REFINE_PASSES):
        for knot in range(1, len(bounds) - 1):
            others = np.delete(bounds, knot)
            position, _ = _best_knot(chords, others, bounds[knot - 1], bounds[knot + 1])
            bounds = _with_knot(others, position)
    return bounds


def _knot_fit(chords: _Chordset, noise_variance: float, threshold: float) -> np.ndarray:
    """Knots of the continuous heading: added one at a time while the best one reduces
    the normalised residual by more than ``threshold``, then the least significant
    dropped while it does not."""
    bounds = np.array([0.0, chords.end])
    while len(bounds) - 2 < len(chords.a) // 2:
        knot, gain = _best_knot(chords, bounds, 0.0, chords.end)
        if gain > threshold * noise_variance:
            bounds = _refined_knots(chords, _with_knot(bounds, knot))
            continue
        pair, gain = _best_knot_pair(chords, bounds)
        if gain <= PAIR_THRESHOLD_FACTOR * threshold * noise_variance:
            break
        bounds = _refined_knots(chords, np.sort(np.concatenate((bounds, pair))))
    while len(bounds) > 2:
        all_free = np.ones(len(bounds) - 2, dtype=bool)
        full = _residual_and_fit(chords, bounds, np.ones(len(bounds) - 1, dtype=bool))[0]
        loss = [_residual_and_fit(chords, np.delete(bounds, k), all_free)[0] - full for k in range(1, len(bounds) - 1)]
        weakest = int(np.argmin(loss))
        if loss[weakest] > threshold * noise_variance:
            break
        bounds = _refined_knots(chords, np.delete(bounds, weakest + 1))
    return bounds


def _residuals_of_bounds(chords: _Chordset, bounds: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Weighted residual sum of squares of the continuous fit for each row of ``bounds``
    (``(trials, parts + 1)``, same ``free`` parts), by batched normal equations."""
    ramp_start, ramp_length = bounds[:, :-1][:, free], np.diff(bounds, axis=1)[:, free]
    past = chords.a[None, :, None], chords.b[None, :, None]
    integral = [
        0.5 * np.clip(u - ramp_start[:, None, :], 0.0, ramp_length[:, None, :]) ** 2
        + ramp_length[:, None, :] * np.fmax(u - ramp_start[:, None, :] - ramp_length[:, None, :], 0.0)
        for u in past
    ]
    scale = np.fmax(ramp_length[:, None, :], 1.0)
    ramps = (integral[1] - integral[0]) / ((chords.b - chords.a)[None, :, None] * scale)
    design = np.concatenate((np.ones(ramps.shape[:2] + (1,)), ramps), axis=2) * chords.root_weight[None, :, None]
    target = chords.heading * chords.root_weight
    normal = np.einsum("tij,tik->tjk", design, design)
    normal += 1e-12 * np.eye(normal.shape[1]) * np.trace(normal, axis1=1, axis2=2)[:, None, None]
    coefficients = np.linalg.solve(normal, np.einsum("tij,i->tj", design, target)[..., None])[..., 0]
    residual = target[None, :] - np.einsum("tij,tj->ti", design, coefficients)
    return np.einsum("ti,ti->t", residual, residual)


def _refined_constrained(chords: _Chordset, bounds: np.ndarray, free: np.ndarray) -> tuple[np.ndarray, float]:
    """Each knot in turn moved to where the fit with only the ``free`` parts curved is
    best, between its neighbours; returns the knots and the residual."""
    residual = float(_residuals_of_bounds(chords, bounds[None, :], free)[0])
    for knot in range(1, len(bounds) - 1):
        low, high = bounds[knot - 1], bounds[knot + 1]
        positions = np.concatenate((_coarse_candidates(chords, low, high), np.linspace(low, high, FINE_KNOT_STEPS + 2)[1:-1]))
        trials = np.repeat(bounds[None, :], len(positions), axis=0)
        trials[:, knot] = positions
        residuals = _residuals_of_bounds(chords, trials, free)
        best = int(np.argmin(residuals))
        if residuals[best] < residual:
            bounds, residual = trials[best], float(residuals[best])
    return bounds, residual


def _with_straights(chords: _Chordset, bounds: np.ndarray, noise_variance: float, threshold: float) -> tuple[np.ndarray, np.ndarray]:
    """Parts made straight (curvature 0) one at a time, the knots moved to fit, while the
    residual grows by less than ``threshold`` normalised: a curvature must earn its place.

    Returns the knots and which parts stay curved.
    """
    free = np.ones(len(bounds) - 1, dtype=bool)
    residual = float(_residuals_of_bounds(chords, bounds[None, :], free)[0])
    while free.any():
        trials = []
        for part in np.flatnonzero(free):
            trial_free = free.copy()
            trial_free[part] = False
            trials.append((*_refined_constrained(chords, bounds, trial_free), trial_free))
        trial_bounds, trial_residual, trial_free = min(trials, key=lambda trial: trial[1])
        if trial_residual - residual > threshold * noise_variance:
            break
        bounds, residual, free = trial_bounds, trial_residual, trial_free
    return bounds, free


def _curvatures(chords: _Chordset, bounds: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Curvature of each part: fitted for the ``free`` parts, 0 for the others."""
    curvature = np.zeros(len(bounds) - 1)
    if free.any():
        curvature[free] = _residual_and_fit(chords, bounds, free)[1][1:]
    return curvature


def _heading_change(chords: _Chordset, bounds: np.ndarray, curvature: np.ndarray) -> np.ndarray:
    """Heading change of the fitted road across each chord, rad."""
    ramp_length = np.diff(bounds)
    def turned(u: np.ndarray) -> np.ndarray:
        return np.clip(u[:, None] - bounds[None, :-1], 0.0, ramp_length) @ curvature
    return turned(chords.b) - turned(chords.a)


def _merged_straights(bounds: np.ndarray, curvature: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Knots between two parts of equal curvature (two straights) removed."""
    keep = np.concatenate(([True], curvature[1:] != curvature[:-1]))
    return np.append(bounds[:-1][keep], bounds[-1]), curvature[keep]


def _map_along(u: np.ndarray, from_a: np.ndarray, from_b: np.ndarray, to_a: np.ndarray, to_b: np.ndarray) -> np.ndarray:
    """Positions from one arc-length coordinate of the chords to another, linearly within a chord."""
    chord = np.clip(np.searchsorted(from_a, u, side="right") - 1, 0, len(from_a) - 1)
    fraction = np.clip((u - from_a[chord]) / (from_b[chord] - from_a[chord]), 0.0, 1.0)
    return to_a[chord] + fraction * (to_b[chord] - to_a[chord])


def _without_short_chords(
    start_s: np.ndarray, length_m: np.ndarray, heading: np.ndarray, shortest_m: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Chords of one polyline with the vertices that leave a chord shorter than
    ``shortest_m`` dropped (the first and last vertex are kept): the heading of a chord
    not much longer than the coordinate noise is noise.

    Returns each remaining chord's start arc length, arc length along the polyline and heading.
    """
    step = np.column_stack((length_m * np.cos(heading), length_m * np.sin(heading)))
    vertex_xy = np.concatenate((np.zeros((1, 2)), np.cumsum(step, axis=0)))
    vertex_s = np.append(start_s, start_s[-1] + length_m[-1])
    kept = [0]
    for vertex in range(1, len(vertex_s)):
        if np.hypot(*(vertex_xy[vertex] - vertex_xy[kept[-1]])) >= shortest_m:
            kept.append(vertex)
    if kept[-1] != len(vertex_s) - 1:
        kept[-1 if len(kept) > 1 else len(kept):] = [len(vertex_s) - 1]
    if len(kept) == len(vertex_s):
        return start_s, length_m, heading
    kept_xy, kept_s = vertex_xy[kept], vertex_s[kept]
    kept_step = np.diff(kept_xy, axis=0)
    kept_heading = np.arctan2(kept_step[:, 1], kept_step[:, 0])
    kept_heading = np.unwrap(np.append(heading[0], kept_heading))[1:]
    return kept_s[:-1], np.diff(kept_s), kept_heading


def _sparse_parts(start_s: np.ndarray, length_m: np.ndarray, heading: np.ndarray, noise_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Parts of one sparse polyline from a continuous piecewise-linear fit of its heading.

    Returns the part bounds in the polyline's arc length (``[0, ..., end]``) and each
    part's curvature per arc length of the road, 1/m.

    A map way has few nodes per curve, so the independent line per part of the dense
    method has too few chords to fit; here the heading is one continuous function
    (the road has no kinks, 3.4-3.8) with free knots, every chord predicted by the
    mean heading over the arc it spans, chords across a knot included. Knots are
    added and dropped by the same significance as the dense method's splits, and a
    part whose curvature is not significant is a straight. The chords are then
    replaced by the arcs they span on the fitted road (a chord of a tight curve is
    shorter than its arc) and the fit repeated.
    """
    start_s, length_m, heading = _without_short_chords(start_s, length_m, heading, SHORT_CHORD_NOISE_FACTOR * noise_m)
    noise_variance = 2.0 * max(noise_m, SPARSE_MIN_NOISE_M) ** 2
    knot_threshold = float(_split_threshold(np.array([len(start_s)]))[0]) - SPLIT_OFFSET + SPARSE_KNOT_OFFSET
    chord_a, chord_b = start_s, start_s + length_m
    chords = _Chordset(chord_a, chord_b, heading, length_m)
    bounds = _knot_fit(chords, noise_variance, knot_threshold)
    bounds, free = _with_straights(chords, bounds, noise_variance, SPARSE_STRAIGHT_THRESHOLD)
    curvature = _curvatures(chords, bounds, free)
    half_turn = 0.5 * np.abs(_heading_change(chords, bounds, curvature))
    arc_m = length_m * np.where(half_turn > 1e-9, half_turn / np.sin(np.fmax(half_turn, 1e-9)), 1.0)
    arc_b = np.cumsum(arc_m)
    arc_chords = _Chordset(arc_b - arc_m, arc_b, heading, length_m)
    arc_bounds = _map_along(bounds, chord_a, chord_b, arc_chords.a, arc_chords.b)
    arc_bounds, _ = _refined_constrained(arc_chords, arc_bounds, free)
    curvature = _curvatures(arc_chords, arc_bounds, free)
    bounds = _map_along(arc_bounds, arc_chords.a, arc_chords.b, chord_a, chord_b)
    bounds[0], bounds[-1] = 0.0, chord_b[-1]
    return _merged_straights(bounds, curvature)


# --------------------------------------------------------------------------- profiles


def _straight_profile(vertex_s: np.ndarray) -> RadiusProfile:
    """The profile of a polyline without length: straight at every vertex, no parts."""
    return RadiusProfile(vertex_s.copy(), np.zeros(len(vertex_s)), np.full(len(vertex_s), np.inf), ())


def _polyline_vertex_s(chords: _Chords, polyline: int) -> np.ndarray:
    return chords.vertex_s[chords.polyline_first_vertex[polyline] : chords.polyline_first_vertex[polyline + 1]]


def _profile(vertex_s: np.ndarray, bounds: np.ndarray, curvature_of_part: np.ndarray) -> RadiusProfile:
    """The radius profile of one polyline from its part bounds (``[0, ..., end]``) and curvatures."""
    part = np.clip(np.searchsorted(bounds, vertex_s, side="right") - 1, 0, len(curvature_of_part) - 1)
    curvature = curvature_of_part[part]
    with np.errstate(divide="ignore", over="ignore"):
        radius = 1.0 / np.abs(curvature)
    parts = tuple(
        ProfilePart(float(start), float(end), float(k))
        for start, end, k in zip(bounds[:-1], bounds[1:], curvature_of_part)
    )
    return RadiusProfile(vertex_s.copy(), curvature, radius, parts)


def _dense_profile(segmentation: _Segmentation, fit: _Fit, polyline: int) -> RadiusProfile:
    """The radius profile of one polyline from the network's segmentation and part fits."""
    chords = segmentation.chords
    vertex_s = _polyline_vertex_s(chords, polyline)
    first_chord, stop_chord = chords.polyline_first_chord[polyline : polyline + 2]
    if first_chord == stop_chord:
        return _straight_profile(vertex_s)
    first_part, stop_part = np.searchsorted(segmentation.starts, (first_chord, stop_chord))
    bounds = np.append(segmentation.knot_s[first_part:stop_part], vertex_s[-1])
    bounds[0] = 0.0
    return _profile(vertex_s, bounds, fit.curvature[first_part:stop_part])


def _sparse_profile(chords: _Chords, noise_m: np.ndarray, polyline: int) -> RadiusProfile:
    """The radius profile of one sparse polyline (:func:`_sparse_parts`)."""
    first, stop = chords.polyline_first_chord[polyline : polyline + 2]
    bounds, curvature = _sparse_parts(
        chords.start_s[first:stop], chords.length_m[first:stop], chords.heading[first:stop], float(noise_m[polyline])
    )
    return _profile(_polyline_vertex_s(chords, polyline), bounds, curvature)


def _is_sparse(chords: _Chords, polyline_count: int) -> np.ndarray:
    """Whether each polyline is a sparse one: :data:`MIN_SPARSE_CHORDS` to
    :data:`MAX_SPARSE_CHORDS` chords, with a median length of at least :data:`SPARSE_CHORD_M`."""
    count = np.diff(chords.polyline_first_chord)
    median_m = _group_median(chords.length_m, chords.polyline, polyline_count)
    return (count >= MIN_SPARSE_CHORDS) & (count <= MAX_SPARSE_CHORDS) & (np.nan_to_num(median_m) >= SPARSE_CHORD_M)


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
            _straight_profile(chords.vertex_s[chords.polyline_first_vertex[p] : chords.polyline_first_vertex[p + 1]])
            for p in range(len(points))
        ]
    noise_m = _coordinate_noise_m(chords, len(points))
    segmentation = _Segmentation(chords, noise_m)
    segmentation.split_until_stable()
    segmentation.open_steps()
    segmentation.refine_until_stable()
    fit = segmentation.fit_on_arc_lengths()
    sparse = _is_sparse(chords, len(points))
    return [
        _sparse_profile(chords, noise_m, p) if sparse[p] else _dense_profile(segmentation, fit, p)
        for p in range(len(points))
    ]


def radius_profile(xy: np.ndarray) -> RadiusProfile:
    """The radius profile of one polyline; see :func:`radius_profiles`."""
    return radius_profiles([_validated(xy)])[0]


# --------------------------------------------------------------------------- curves


def _curve(parts: Sequence[ProfilePart]) -> Curve:
    """A curve made of consecutive parts that turn the same way."""
    angle_rad = sum(abs(p.curvature) * p.length_m for p in parts)
    return Curve(
        start_s=parts[0].start_s,
        end_s=parts[-1].end_s,
        angle_deg=math.degrees(angle_rad),
        direction="left" if parts[0].curvature > 0 else "right",
        min_radius_m=min(p.radius_m for p in parts),
        parts=tuple(ConstantRadiusPart(p.start_s, p.end_s, p.radius_m) for p in parts),
    )


def curves_from_profile(profile: RadiusProfile, warning_radius_m: float = DEFAULT_WARNING_RADIUS_M) -> list[Curve]:
    """The curves of a radius profile: maximal runs of parts turning the same way with a
    radius no larger than the warning curvature radius R_c.

    The curve start (3.4) is where the radius becomes <= R_c and the curve end (3.5) where
    it becomes > R_c again; a change of direction ends one curve and starts the next, so
    an S-bend is two curves. A run of several radii is a multi curve (3.8).

    Parameters
    ----------
    profile
        A profile from :func:`radius_profile` or :func:`radius_profiles`.
    warning_radius_m
        R_c (3.2), m, > 0.

    Returns
    -------
    list[Curve]
        In order along the polyline.
    """
    if not (math.isfinite(warning_radius_m) and warning_radius_m > 0):
        raise ValueError(f"warning radius must be a positive number of metres, got {warning_radius_m!r}")
    curves: list[Curve] = []
    run: list[ProfilePart] = []
    for part in profile.parts:
        in_curve = part.radius_m <= warning_radius_m and part.length_m > 0
        if run and not (in_curve and np.sign(part.curvature) == np.sign(run[0].curvature)):
            curves.append(_curve(run))
            run = []
        if in_curve:
            run.append(part)
    if run:
        curves.append(_curve(run))
    return curves


def find_curves(xy: np.ndarray, warning_radius_m: float = DEFAULT_WARNING_RADIUS_M) -> list[Curve]:
    """The curves (3.4-3.8) of one polyline; see :func:`curves_from_profile`."""
    return curves_from_profile(radius_profile(xy), warning_radius_m)


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
