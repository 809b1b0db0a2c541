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
numpy operations does not grow with the number of lanes. Sparse polylines (map ways,
see :func:`_sparse_batch_parts`) are fitted in a few batches of similar chord counts,
each step for all polylines of a batch and all their trial knot positions at once. A
map way's chords are too few and too noisy for the fit of their headings to be the
last word, so the road it finds is finally fitted to the nodes themselves, in the plane
(:func:`_polished`): the maximum-likelihood road under isotropic node noise, exact on
exact nodes, with straights tried at its ends where the heading fit ran a curve into one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, is_dataclass
from typing import Any, Sequence

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

#: Chords shorter than this are treated as repeated vertices, m. With coordinates rounded
#: to the centimetre such a chord's heading is off by more than 10 degrees, and netconvert
#: leaves centimetre-long backward chords at junctions that would read as a U-turn.
MIN_CHORD_M = 0.05
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
#: Fewest and most chords a polyline is fitted as a sparse one with (the sparse fit's work
#: grows steeply with the chords and knots of a polyline; longer ones take the dense path).
MIN_SPARSE_CHORDS = 4
MAX_SPARSE_CHORDS = 80
#: Positions tried around the best vertex or chord middle when placing a sparse knot.
FINE_KNOT_STEPS = 4
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
#: Parts of a polyline tried straight (with knots moved) in each round: those cheapest to straighten with knots held.
STRAIGHT_SCREEN = 2
#: A straight tried in a curved part of a sparse polyline's road is kept when the nodes' sum
#: of squared sideways distances falls by more than this many times their noise variance
#: for each parameter it adds (a straight at an end adds a knot but no curvature).
STRAIGHT_TRIAL_THRESHOLD = 10.0
#: Levenberg-Marquardt iterations polishing a sparse polyline's road in the plane.
POLISH_ITERATIONS = 12
#: Steps every trial road is polished with (plain steps, :data:`STEP_SCALES` not tried)
#: before only the closest of each kind is polished on.
FIRST_POLISH_ITERATIONS = 3
#: A polish step gaining less than this fraction of the sum of squares ends a trial's polish.
POLISH_TOLERANCE = 1e-3
#: Least Levenberg-Marquardt damping (relative to the normal equations' diagonal).
MIN_DAMPING = 1e-6
#: Levenberg-Marquardt damping at which a trial's polish ends (its steps keep failing).
MAX_DAMPING = 10.0
#: Newton steps projecting the nodes onto the road before the polish (each of its steps adds one).
PROJECTION_STEPS = 1
#: The longer multiples of each polish step tried beside it (:func:`_best_scaled_step`).
STEP_SCALES = (3.0, 10.0)
#: How far the polish's other starting roads stretch the longest curved part (shrinking below 1).
STRETCH_FACTORS = (0.5, 2.0)
#: How much of a curved end part a straight tried there first takes, as fractions of the
#: part counted in nodes from the polyline's end (the polish then moves its knot).
END_STRAIGHT_FRACTIONS = (0.25, 0.5, 0.75)
#: Where a straight is first put into the middle of a curved part, and where a curved part
#: is first narrowed to between two straights, as fractions of the part (counted in nodes).
MIDDLE_STRAIGHT_SPANS = ((0.25, 0.5), (0.25, 0.75), (0.5, 0.75))
ARC_SPANS = MIDDLE_STRAIGHT_SPANS
#: Straights are tried only on roads whose nodes' sum of squared sideways distances exceeds
#: this many times what the noise (the polyline's own estimate) leaves on the right road.
STRAIGHT_TRIAL_MISFIT = 1.0
#: Fewest nodes more than parameters a road with added straights must have to be tried.
MIN_TRIAL_FREEDOM = 1
#: Fewest nodes more than parameters a road's residual must have to estimate the noise from.
MIN_VARIANCE_FREEDOM = 2
#: Shortest part the polish lets a knot make, m.
MIN_POLISHED_PART_M = 0.1
#: Chord counts sparse polylines are padded to, so that few batches are fitted (each in one set of array operations).
SPARSE_BATCH_CHORDS = np.array([4, 5, 6, 8, 10, 12, 16, 20, 24, 32, 40, 48, 64, 80])
#: Most array elements (polylines x trials x chords x parts) fitted in one go.
MAX_FIT_ELEMENTS = 2_000_000


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
    # A median of few samples is often far too small, and a noise estimate too small
    # turns noise into bends; below a few dozen samples the root mean square, which
    # errs on the large side, bounds it from below.
    count = np.bincount(group, minlength=polyline_count)
    rms = np.sqrt(np.bincount(group, sample**2, minlength=polyline_count) / np.fmax(count, 1))
    noise = np.where(count < 3 * MIN_MEDIAN_SAMPLES, np.fmax(noise, rms), noise)
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
#
# Sparse polylines are fitted in batches: the polylines of one batch have the same
# number of chords, and every step below is done for all of them (and for all their
# trial knot positions) in one set of array operations. Knot lists differ in length, so
# each polyline's bounds are padded with its end: a part of no length adds a column of
# zeros to the fit, which the regularised normal equations give a coefficient of 0.


@dataclass(frozen=True)
class _SparseBatch:
    """Chords of sparse polylines of similar chord counts, in an arc-length coordinate
    ``u``: chord i of polyline p spans ``[a[p, i], b[p, i]]``.

    ``heading`` is each chord's (unwrapped) heading, ``root_weight`` the square root of
    its fit weight (its chord length: a long chord's heading is the more precise), ``end``
    each polyline's length in ``u`` and ``count`` its number of chords. The rows are
    padded to a common length with chords of no weight beyond ``end``.
    """

    a: np.ndarray
    b: np.ndarray
    heading: np.ndarray
    root_weight: np.ndarray
    end: np.ndarray
    count: np.ndarray

    def rows(self, index: np.ndarray | slice) -> "_SparseBatch":
        """The batch of the polylines ``index``."""
        return _SparseBatch(*(getattr(self, field)[index] for field in ("a", "b", "heading", "root_weight", "end", "count")))

    def coarse_candidates(self) -> np.ndarray:
        """Each polyline's vertices and chord middles in order, ``(polylines, 2 chords)``."""
        coarse = np.empty((len(self.a), 2 * self.a.shape[1]))
        coarse[:, 0::2] = self.a
        coarse[:, 1::2] = 0.5 * (self.a + self.b)
        return coarse


def _chord_means_of_ramps(batch: _SparseBatch, ramp_start: np.ndarray, ramp_length: np.ndarray) -> np.ndarray:
    """Mean over each chord of each ramp ``clip(u - start, 0, length)``.

    ``ramp_start`` and ``ramp_length`` are ``(polylines, trials, ramps)``; the result is
    ``(polylines, trials, chords, ramps)``. A chord's direction is the mean of the road's
    heading over the arc it spans (exact on a circle), so a heading that is continuous
    and piecewise linear in ``u`` (a sum of ramps) predicts every chord's heading
    linearly, including chords across a knot.
    """
    start, length = ramp_start[:, :, None, :], ramp_length[:, :, None, :]

    def integral(u: np.ndarray) -> np.ndarray:
        past = np.fmax(u[:, None, :, None] - start, 0.0)
        within = np.minimum(past, length)
        return within * (past - 0.5 * within)

    return (integral(batch.b) - integral(batch.a)) / (batch.b - batch.a)[:, None, :, None]


def _design(batch: _SparseBatch, bounds: np.ndarray, free: np.ndarray | bool) -> tuple[np.ndarray, np.ndarray]:
    """Weighted design matrices of a continuous heading with knots at ``bounds[..., 1:-1]``.

    ``bounds`` is ``(polylines, trials, parts + 1)``; each matrix has a level column and
    one slope (curvature) column per part, zero for the parts not ``free`` (straights).
    Ramps are scaled by their length (at least 1 m) to keep the equations well
    conditioned; also returns that scale, ``(polylines, trials, parts)``.
    """
    ramp_length = np.diff(bounds, axis=-1)
    scale = np.fmax(ramp_length, 1.0)
    ramps = _chord_means_of_ramps(batch, bounds[..., :-1], ramp_length) * (free / scale)[:, :, None, :]
    design = np.concatenate((np.ones(ramps.shape[:-1] + (1,)), ramps), axis=-1)
    return design * batch.root_weight[:, None, :, None], scale


def _least_squares(design: np.ndarray, columns: np.ndarray) -> np.ndarray:
    """Coefficients ``(..., terms, k)`` of the least-squares fit of ``columns`` ``(..., chords, k)``
    on ``design`` ``(..., chords, terms)``, by normal equations regularised so that a
    zero column gets a coefficient of 0."""
    transposed = np.swapaxes(design, -1, -2)
    normal = transposed @ design
    normal += 1e-12 * np.trace(normal, axis1=-2, axis2=-1)[..., None, None] * np.eye(normal.shape[-1])
    return np.linalg.solve(normal, transposed @ columns)


def _fitted_rows(design: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """The least-squares fits ``(polylines, k, chords)`` of the vectors ``rows`` on the columns of ``design``."""
    return np.swapaxes(design @ _least_squares(design, np.swapaxes(rows, 1, 2)), 1, 2)




def _fits(batch: _SparseBatch, bounds: np.ndarray, free: np.ndarray | bool) -> tuple[np.ndarray, np.ndarray]:
    """Weighted residual sum of squares ``(polylines, trials)`` and curvature of each part
    ``(polylines, trials, parts)`` (0 where not ``free``) of the continuous fit for every
    trial ``bounds[p, t]``."""
    free = np.broadcast_to(free, bounds.shape[:2] + (bounds.shape[2] - 1,))
    rows_per_chunk = max(1, MAX_FIT_ELEMENTS // max(1, bounds.shape[1] * batch.a.shape[1] * bounds.shape[2]))
    if len(bounds) > rows_per_chunk:
        chunks = [
            _fits(batch.rows(slice(first, first + rows_per_chunk)), bounds[first : first + rows_per_chunk], free[first : first + rows_per_chunk])
            for first in range(0, len(bounds), rows_per_chunk)
        ]
        return np.concatenate([c[0] for c in chunks]), np.concatenate([c[1] for c in chunks])
    design, scale = _design(batch, bounds, free)
    target = np.broadcast_to((batch.heading * batch.root_weight)[:, None, :, None], design.shape[:-1] + (1,))
    coefficients = _least_squares(design, target)
    residual = (target - design @ coefficients)[..., 0]
    return np.einsum("ptn,ptn->pt", residual, residual), coefficients[..., 1:, 0] / scale * free


def _projected_hinges(batch: _SparseBatch, bounds: np.ndarray, candidates: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The residual of the continuous fit with knots ``bounds[:, 1:-1]`` (all parts free),
    ``(polylines, chords)``, and the hinge column of a knot at each candidate with that
    fit's columns projected out, ``(polylines, chords, candidates)``.

    Also returns whether each projected column is far enough from 0 to be a new knot.
    """
    design, _ = _design(batch, bounds[:, None, :], True)
    hinge_length = np.fmax(batch.end[:, None] + 1.0 - candidates, 1.0)
    hinge = _chord_means_of_ramps(batch, candidates[:, None, :], hinge_length[:, None, :])[:, 0]
    hinge *= batch.root_weight[:, :, None]
    columns = np.concatenate(((batch.heading * batch.root_weight)[:, :, None], hinge), axis=2)[:, None]
    projected = (columns - design @ _least_squares(design, columns))[:, 0]
    scale = np.einsum("pnc,pnc->pc", hinge, hinge)
    hinge = projected[:, :, 1:]
    usable = np.einsum("pnc,pnc->pc", hinge, hinge) > 1e-9 * scale
    return projected[:, :, 0], hinge, usable


def _knot_gains(batch: _SparseBatch, bounds: np.ndarray, candidates: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Reduction of the weighted residual from adding a knot at each candidate to the
    continuous fit with knots ``bounds[:, 1:-1]``; ``-inf`` where not ``valid``."""
    residual, hinge, usable = _projected_hinges(batch, bounds, candidates)
    with np.errstate(divide="ignore", invalid="ignore"):
        gain = np.einsum("pn,pnc->pc", residual, hinge) ** 2 / np.einsum("pnc,pnc->pc", hinge, hinge)
    return np.where(valid, np.where(usable, gain, 0.0), -np.inf)


def _coarse_between(batch: _SparseBatch, low: np.ndarray, high: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per polyline, its vertices and chord middles strictly between ``low`` and ``high``,
    in order, ``(polylines, most)``, padded, and which of them are such candidates."""
    coarse = batch.coarse_candidates()
    first = (coarse <= low[:, None]).sum(axis=1)
    count = (coarse < high[:, None]).sum(axis=1) - first
    window = np.arange(max(int(count.max(initial=0)), 1))
    index = np.minimum(first[:, None] + window, coarse.shape[1] - 1)
    return coarse[np.arange(len(coarse))[:, None], index], window < count[:, None]


def _fine_positions(low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """:data:`FINE_KNOT_STEPS` evenly spaced positions strictly between ``low`` and ``high``."""
    fraction = np.arange(1, FINE_KNOT_STEPS + 1) / (FINE_KNOT_STEPS + 1)
    return low[:, None] + (high - low)[:, None] * fraction


def _best_knots(batch: _SparseBatch, bounds: np.ndarray, low: np.ndarray, high: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per polyline, the knot strictly between ``low`` and ``high`` that reduces the
    residual most, and that reduction: searched at the vertices and chord middles, then
    finely around the best (``low`` and 0 where there is no candidate)."""
    rows = np.arange(len(bounds))
    coarse, valid = _coarse_between(batch, low, high)
    gain = _knot_gains(batch, bounds, coarse, valid)
    best = np.argmax(gain, axis=1)
    best_gain = gain[rows, best]
    before, after = best - 1, np.minimum(best + 1, coarse.shape[1] - 1)
    fine_low = np.where((best > 0) & valid[rows, before], coarse[rows, before], low)
    fine_high = np.where((best + 1 < coarse.shape[1]) & valid[rows, after], coarse[rows, after], high)
    fine = _fine_positions(fine_low, fine_high)
    fine_gain = _knot_gains(batch, bounds, fine, np.ones(fine.shape, dtype=bool))
    fine_best = np.argmax(fine_gain, axis=1)
    use_fine = fine_gain[rows, fine_best] > best_gain
    knot = np.where(use_fine, fine[rows, fine_best], coarse[rows, best])
    knot_gain = np.where(use_fine, fine_gain[rows, fine_best], best_gain)
    found = valid.any(axis=1)
    return np.where(found, knot, low), np.where(found, knot_gain, 0.0)


def _best_knot_pairs(batch: _SparseBatch, bounds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per polyline, the two knots at vertices or chord middles that together reduce the
    residual most, ``(polylines, 2)``, and that reduction. A curve between straights, or
    one shorter than the chords around it, needs both its knots before either pays off
    on its own."""
    coarse, valid = _coarse_between(batch, np.zeros(len(bounds)), batch.end)
    residual, hinge, usable = _projected_hinges(batch, bounds, coarse)
    gram = np.einsum("pnc,pnd->pcd", hinge, hinge)
    along = np.einsum("pn,pnc->pc", residual, hinge)
    diagonal = np.einsum("pcc->pc", gram)
    outer_diagonal = diagonal[:, :, None] * diagonal[:, None, :]
    determinant = outer_diagonal - gram**2
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        gain = (
            along[:, :, None] ** 2 * diagonal[:, None, :]
            - 2.0 * along[:, :, None] * along[:, None, :] * gram
            + diagonal[:, :, None] * along[:, None, :] ** 2
        ) / determinant
    gain = np.where(determinant > 1e-6 * outer_diagonal, gain, 0.0)
    candidate = valid & usable
    pair = candidate[:, :, None] & candidate[:, None, :] & np.triu(np.ones(gram.shape[1:], dtype=bool), 1)
    gain = np.where(pair, gain, -np.inf).reshape(len(bounds), -1)
    best = np.argmax(gain, axis=1)
    first, second = np.unravel_index(best, gram.shape[1:])
    rows = np.arange(len(bounds))
    return np.column_stack((coarse[rows, first], coarse[rows, second])), np.fmax(gain[rows, best], 0.0)


def _trimmed(bounds: np.ndarray, knots: np.ndarray) -> np.ndarray:
    """``bounds`` without the padding columns that no polyline needs."""
    return bounds[:, : int(knots.max(initial=0)) + 2]


def _with_knots(bounds: np.ndarray, knots: np.ndarray) -> np.ndarray:
    """Each row's bounds with its new ``knots`` ``(polylines, new)`` put in order (into the padding)."""
    bounds = np.concatenate((bounds, np.repeat(bounds[:, -1:], knots.shape[1], axis=1)), axis=1)
    bounds[:, -knots.shape[1] :] = knots
    return np.sort(bounds, axis=1)


def _without_knot(bounds: np.ndarray, knot: np.ndarray) -> np.ndarray:
    """Each row's bounds with its knot ``knot[p]`` (a column index) made padding."""
    bounds = bounds.copy()
    bounds[np.arange(len(bounds)), knot] = bounds[:, -1]
    return np.sort(bounds, axis=1)


def _refined_knots(batch: _SparseBatch, bounds: np.ndarray, knots: np.ndarray, near: np.ndarray | None = None) -> np.ndarray:
    """Each knot in turn moved to where it fits best between its neighbours (only the
    knots marked ``near``, ``(polylines, columns)``, if given)."""
    bounds = bounds.copy()
    for _ in range(SPARSE_REFINE_PASSES):
        for column in range(1, int(knots.max(initial=0)) + 1):
            rows = np.flatnonzero((knots >= column) & (True if near is None else near[:, column]))
            if rows.size == 0:
                continue
            others = _trimmed(bounds[rows], knots[rows]).copy()
            low, high = others[:, column - 1].copy(), others[:, column + 1].copy()
            others[:, column] = low  # a part of no length: the knot is gone
            bounds[rows, column] = _best_knots(batch.rows(rows), others, low, high)[0]
    return bounds


def _knot_fit(batch: _SparseBatch, limit: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Knots of the continuous heading: added one at a time while the best one reduces
    the residual by more than ``limit``, then the least significant dropped while it
    does not.

    Returns the bounds, padded with each polyline's end, and the number of knots.
    """
    most_knots = batch.count // 2
    # Room for one knot more than most_knots: a pair may be added to most_knots - 1.
    bounds = np.column_stack((np.zeros(len(batch.a)), np.repeat(batch.end[:, None], int(most_knots.max()) + 2, axis=1)))
    knots = np.zeros(len(bounds), dtype=np.int64)
    adding = np.ones(len(bounds), dtype=bool)
    while (active := np.flatnonzero(adding & (knots < most_knots))).size:
        knot, gain = _best_knots(batch.rows(active), _trimmed(bounds[active], knots[active]), np.zeros(len(active)), batch.end[active])
        single = gain > limit[active]
        rest = active[~single]
        pair, pair_gain = np.empty((0, 2)), np.empty(0)
        if rest.size:
            pair, pair_gain = _best_knot_pairs(batch.rows(rest), _trimmed(bounds[rest], knots[rest]))
        paired = pair_gain > PAIR_THRESHOLD_FACTOR * limit[rest]
        adding[rest[~paired]] = False
        changed = np.concatenate((active[single], rest[paired]))
        new = np.concatenate((np.column_stack((knot[single], knot[single])), pair[paired]))
        new[: single.sum(), 1] = bounds[active[single], -1]  # one knot: the other is padding
        knots[changed] += np.concatenate((np.ones(single.sum(), dtype=np.int64), np.full(paired.sum(), 2)))
        bounds[changed] = _with_knots(bounds[changed], new)[:, : bounds.shape[1]]
        # A new knot moves its neighbours' best places; the knots further away keep theirs.
        is_new = (bounds[changed][:, :, None] == new[:, None, :]).any(axis=2)
        near = is_new | np.roll(is_new, 1, axis=1) | np.roll(is_new, -1, axis=1)
        bounds[changed] = _refined_knots(batch.rows(changed), bounds[changed], knots[changed], near)
    dropping = knots > 0
    while (active := np.flatnonzero(dropping & (knots > 0))).size:
        rows = batch.rows(active)
        trial_bounds = _trimmed(bounds[active], knots[active])
        full = _fits(rows, trial_bounds[:, None, :], True)[0][:, 0]
        trials = np.repeat(trial_bounds[:, None, :], trial_bounds.shape[1] - 2, axis=1)
        column = np.arange(1, trial_bounds.shape[1] - 1)
        trials[:, np.arange(len(column)), column] = trials[:, np.arange(len(column)), column - 1]
        loss = _fits(rows, trials, True)[0] - full[:, None]
        loss[column[None, :] > knots[active][:, None]] = np.inf
        weakest = np.argmin(loss, axis=1)
        drop = loss[np.arange(len(active)), weakest] <= limit[active]
        dropping[active[~drop]] = False
        changed = active[drop]
        knots[changed] -= 1
        bounds[changed] = _without_knot(bounds[changed], weakest[drop] + 1)
        bounds[changed] = _refined_knots(batch.rows(changed), bounds[changed], knots[changed])
    return bounds, knots


def _moved_knot_residuals(
    batch: _SparseBatch, bounds: np.ndarray, free: np.ndarray, column: int, positions: np.ndarray
) -> np.ndarray:
    """Weighted residual sum of squares ``(polylines, trials)`` of the continuous fit (only
    the ``free`` parts curved) with the knot ``bounds[:, column]`` moved to each of
    ``positions`` ``(polylines, trials)``.

    Only the slopes of the two parts beside the knot change with it, so the fit of the
    other columns is made once per polyline and each trial adds two projected columns.
    """
    fixed_free = free.copy()
    fixed_free[:, column - 1 : column + 1] = False
    fixed = _design(batch, bounds[:, None, :], fixed_free[:, None, :])[0][:, 0]
    low, high = bounds[:, column - 1 : column], bounds[:, column + 1 : column + 2]
    before_m, after_m = positions - low, high - positions
    # The ramps of the two parts add up to one ramp from low to high, wherever the knot is.
    before = _chord_means_of_ramps(batch, np.broadcast_to(low, positions.shape)[:, :, None], before_m[:, :, None])[..., 0]
    both = _chord_means_of_ramps(batch, low[:, :, None], (high - low)[:, :, None])[..., 0]
    root_weight = batch.root_weight[:, None, :]
    after = (both - before) * (root_weight * (free[:, column, None] / np.fmax(after_m, 1.0))[:, :, None])
    before *= root_weight * (free[:, column - 1, None] / np.fmax(before_m, 1.0))[:, :, None]
    trials = positions.shape[1]
    rows = np.concatenate(((batch.heading * batch.root_weight)[:, None, :], before, after), axis=1)
    projected = rows - _fitted_rows(fixed, rows)
    residual, added = projected[:, :1], projected[:, 1:]
    # A column the fixed ones (nearly) contain adds nothing; its rounding noise must not either.
    added *= (np.einsum("ptn,ptn->pt", added, added) > 1e-9 * np.einsum("ptn,ptn->pt", rows[:, 1:], rows[:, 1:]))[..., None]
    added_before, added_after = added[:, :trials], added[:, trials:]
    g00 = np.einsum("ptn,ptn->pt", added_before, added_before)
    g11 = np.einsum("ptn,ptn->pt", added_after, added_after)
    g01 = np.einsum("ptn,ptn->pt", added_before, added_after)
    b0, b1 = (np.einsum("pn,ptn->pt", residual[:, 0], added_part) for added_part in (added_before, added_after))
    determinant = g00 * g11 - g01**2
    with np.errstate(divide="ignore", invalid="ignore"):
        both_explained = (g11 * b0**2 - 2.0 * g01 * b0 * b1 + g00 * b1**2) / determinant
        one_explained = np.fmax(np.where(g00 > 0, b0**2 / g00, 0.0), np.where(g11 > 0, b1**2 / g11, 0.0))
    explained = np.where(determinant > 1e-12 * g00 * g11, both_explained, one_explained)
    return np.einsum("pn,pn->p", residual[:, 0], residual[:, 0])[:, None] - explained


def _refined_constrained(
    batch: _SparseBatch, bounds: np.ndarray, knots: np.ndarray, free: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Each knot in turn moved to where the fit with only the ``free`` parts curved is
    best, between its neighbours; returns the knots and the residual."""
    bounds = bounds.copy()
    residual = _fits(batch, bounds[:, None, :], free[:, None, :])[0][:, 0]
    for column in range(1, int(knots.max(initial=0)) + 1):
        # A knot between two straights changes nothing wherever it is.
        rows = np.flatnonzero((knots >= column) & (free[:, column - 1] | free[:, column]))
        if rows.size == 0:
            continue
        low, high = bounds[rows, column - 1], bounds[rows, column + 1]
        coarse, coarse_valid = _coarse_between(batch.rows(rows), low, high)
        # The knot's present place last: moves must beat it as computed the same way.
        positions = np.concatenate((coarse, _fine_positions(low, high), bounds[rows, column : column + 1]), axis=1)
        valid = np.concatenate((coarse_valid, np.ones((len(rows), FINE_KNOT_STEPS + 1), dtype=bool)), axis=1)
        trial_residual = np.where(valid, _moved_knot_residuals(batch.rows(rows), bounds[rows], free[rows], column, positions), np.inf)
        best = np.argmin(trial_residual[:, :-1], axis=1)
        best_residual = trial_residual[np.arange(len(rows)), best]
        better = best_residual < trial_residual[:, -1]
        bounds[rows[better], column] = positions[better, best[better]]
        residual[rows] = np.where(better, best_residual, trial_residual[:, -1])
    return bounds, residual


def _with_straights(batch: _SparseBatch, bounds: np.ndarray, knots: np.ndarray, limit: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Parts made straight (curvature 0) one at a time, the knots moved to fit, while the
    residual grows by less than ``limit``: a curvature must earn its place.

    Returns the bounds and which parts stay curved.
    """
    bounds = bounds.copy()
    free = np.arange(bounds.shape[1] - 1)[None, :] <= knots[:, None]
    residual = _fits(batch, bounds[:, None, :], free[:, None, :])[0][:, 0]
    going = free.any(axis=1)
    while (active := np.flatnonzero(going)).size:
        polyline, part = np.nonzero(free[active])
        polyline = active[polyline]
        trial_free = free[polyline]
        trial_free[np.arange(len(part)), part] = False
        # Only the parts whose straightening costs least with the knots held are tried with them moved.
        held = _fits(batch.rows(polyline), bounds[polyline][:, None, :], trial_free[:, None, :])[0][:, 0]
        order = np.lexsort((held, polyline))
        rank = np.arange(len(order)) - np.searchsorted(polyline[order], polyline[order])
        screened = np.sort(order[rank < STRAIGHT_SCREEN])
        polyline, trial_free = polyline[screened], trial_free[screened]
        trial_bounds, trial_residual = _refined_constrained(batch.rows(polyline), bounds[polyline], knots[polyline], trial_free)
        # The best trial of each polyline (trials are grouped by polyline, in order).
        order = np.lexsort((trial_residual, polyline))
        best = order[np.searchsorted(polyline[order], active)]
        accept = trial_residual[best] - residual[active] <= limit[active]
        going[active[~accept]] = False
        best, changed = best[accept], active[accept]
        bounds[changed, : trial_bounds.shape[1]] = trial_bounds[best]
        residual[changed] = trial_residual[best]
        free[changed] = trial_free[best]
        going[changed] = free[changed].any(axis=1)
    return bounds, free


# The polish: the road model fitted to the nodes themselves. A chord's heading is a poor
# measurement on a map way: two neighbouring chords share a noisy node, and a short chord's
# heading is mostly noise. The maximum-likelihood road is the one whose distance to the
# nodes is least, so the heading fit's parts are finally fitted in the plane: the road
# starts near the first node with a heading and runs through its parts (straights and
# arcs joined without kinks, 3.4-3.8); every node is projected onto it, and knots,
# curvatures and the start are moved by Levenberg-Marquardt steps on the nodes' sideways
# distances. Points are complex numbers x + iy.


@dataclass(frozen=True)
class _Nodes:
    """The nodes of sparse polylines relative to each one's first: ``xy`` (complex) and
    ``s`` (arc length along the polyline), ``(polylines, nodes)``, padded; ``real`` says
    which are nodes."""

    xy: np.ndarray
    s: np.ndarray
    real: np.ndarray


def _padded_nodes(polylines: list[tuple[np.ndarray, np.ndarray, np.ndarray]]) -> _Nodes:
    """The nodes of polylines given by all their chords' start arc lengths, lengths and headings."""
    size = max(len(start_s) for start_s, _, _ in polylines) + 1
    xy, s = np.zeros((len(polylines), size), dtype=complex), np.zeros((len(polylines), size))
    real = np.arange(size)[None, :] <= np.array([len(start_s) for start_s, _, _ in polylines])[:, None]
    for row, (start_s, length_m, heading) in enumerate(polylines):
        count = len(start_s)
        xy[row, 1 : count + 1] = np.cumsum(length_m * np.exp(1j * heading))
        s[row, : count + 1] = np.append(start_s, start_s[-1] + length_m[-1])
        xy[row, count + 1 :], s[row, count + 1 :] = xy[row, count], s[row, count]
    return _Nodes(xy, s, real)


@dataclass(frozen=True)
class _Road:
    """Trial roads ``(polylines, trials)``: the first node's sideways ``offset`` from the
    road's start (m, along the normal of ``base_heading``), the start heading's ``turn``
    from ``base_heading`` (rad), part ``bounds`` ``(..., parts + 1)`` in the road's arc
    length, part ``curvature`` and which parts are ``free`` to curve, and ``last``, the
    index of the last part of each (the parts after it are padding of no length). The
    first part extends backwards and the last forwards without end."""

    base_heading: np.ndarray
    offset: np.ndarray
    turn: np.ndarray
    bounds: np.ndarray
    curvature: np.ndarray
    free: np.ndarray
    last: np.ndarray

    def start(self) -> np.ndarray:
        """The road's start point (complex), the first node being at 0."""
        return 1j * np.exp(1j * self.base_heading) * self.offset

    def heading(self) -> np.ndarray:
        """The road's heading at its start, rad."""
        return self.base_heading + self.turn

    def parameters(self) -> np.ndarray:
        """The parameters the polish moves, ``(..., 2 * parts + 1)``: offset, turn, inner bounds, curvatures."""
        return np.concatenate((self.offset[..., None], self.turn[..., None], self.bounds[..., 1:-1], self.curvature), axis=-1)

    def movable(self) -> np.ndarray:
        """Which parameters move: the offset and turn, the knots between real parts and the free curvatures."""
        parts = self.curvature.shape[-1]
        knots = np.arange(1, parts) <= self.last[..., None]
        return np.concatenate((np.ones(self.offset.shape + (2,), dtype=bool), knots, self.free), axis=-1)

    def with_parameters(self, parameters: np.ndarray) -> "_Road":
        """The roads with the :meth:`parameters` ``parameters`` (a part not free stays straight)."""
        parts = self.curvature.shape[-1]
        bounds = self.bounds.copy()
        bounds[..., 1:-1] = parameters[..., 2 : parts + 1]
        return _Road(self.base_heading, parameters[..., 0], parameters[..., 1], bounds,
                     parameters[..., parts + 1 :] * self.free, self.free, self.last)

    def feasible_fraction(self, step: np.ndarray) -> np.ndarray:
        """The largest fraction (at most 1, with a margin) of the parameter ``step`` that
        leaves every real part at least :data:`MIN_POLISHED_PART_M` long."""
        parts = self.curvature.shape[-1]
        moved = np.concatenate((np.zeros_like(step[..., :1]), step[..., 2 : parts + 1], np.zeros_like(step[..., :1])), axis=-1)
        shrink = -np.diff(moved, axis=-1)
        room = np.diff(self.bounds, axis=-1) - MIN_POLISHED_PART_M
        real = np.arange(parts) <= self.last[..., None]
        with np.errstate(divide="ignore", invalid="ignore"):
            limit = np.where(real & (shrink > 0), np.fmax(room, 0.0) / shrink, np.inf)
        return np.fmin(1.0, 0.9 * limit.min(axis=-1))

    def is_ordered(self) -> np.ndarray:
        """Whether every real part is at least :data:`MIN_POLISHED_PART_M` long."""
        real = np.arange(self.curvature.shape[-1]) <= self.last[..., None]
        return np.all((np.diff(self.bounds, axis=-1) >= MIN_POLISHED_PART_M) | ~real, axis=-1)


def _chord(length: np.ndarray, heading: np.ndarray, curvature: np.ndarray) -> np.ndarray:
    """The chord (complex) of a part of ``length`` that starts at ``heading`` and curves by
    ``curvature``: ``l·exp(i(φ + a/2))·sin(a/2)/(a/2)`` with ``a = κ l`` the angle it turns,
    exact on a straight (a = 0) and without cancellation near it."""
    half_turn = 0.5 * curvature * length
    return length * np.sinc(half_turn / np.pi) * np.exp(1j * (heading + half_turn))


def _area_factor(angle: np.ndarray) -> np.ndarray:
    """``(1 + i a - exp(i a)) / a²``: the integral of a part's points over its length l
    from its start A with heading φ is ``l A + l² exp(i φ)`` times this."""
    small = np.abs(angle) < 1e-2
    safe = np.where(small, 1.0, angle)
    series = 0.5 + angle * (1j / 6.0 - angle * (1.0 / 24.0 + angle * (1j / 120.0 - angle / 720.0)))
    return np.where(small, series, (1.0 + 1j * safe - np.exp(1j * safe)) / safe**2)


@dataclass(frozen=True)
class _RoadPoints:
    """The road at the nodes' positions ``t`` ``(polylines, trials, nodes)``: ``point``
    (complex), ``heading``, the ``part`` each is on and its ``progress`` along that part
    from the part's start; per part ``(..., parts)``, its start point ``corner``, start
    heading ``part_heading`` and ``length``."""

    point: np.ndarray
    heading: np.ndarray
    part: np.ndarray
    progress: np.ndarray
    corner: np.ndarray
    part_heading: np.ndarray
    length: np.ndarray


def _road_points(road: _Road, t: np.ndarray) -> _RoadPoints:
    """The road's points and headings at the arc lengths ``t``."""
    length = np.diff(road.bounds, axis=-1)
    turned = np.cumsum(road.curvature * length, axis=-1)
    part_heading = road.heading()[..., None] + np.concatenate((np.zeros_like(turned[..., :1]), turned[..., :-1]), axis=-1)
    moved = np.cumsum(_chord(length, part_heading, road.curvature), axis=-1)
    corner = road.start()[..., None] + np.concatenate((np.zeros_like(moved[..., :1]), moved[..., :-1]), axis=-1)
    part = np.minimum((t[..., None] >= road.bounds[..., None, 1:-1]).sum(axis=-1), road.last[..., None])
    progress = t - np.take_along_axis(road.bounds, part, axis=-1)
    curvature = np.take_along_axis(road.curvature, part, axis=-1)
    heading = np.take_along_axis(part_heading, part, axis=-1)
    point = np.take_along_axis(corner, part, axis=-1) + _chord(progress, heading, curvature)
    return _RoadPoints(point, heading + curvature * progress, part, progress, corner, part_heading, length)


def _projected(road: _Road, nodes: _Nodes, t: np.ndarray, steps: int) -> tuple[np.ndarray, np.ndarray, _RoadPoints]:
    """The nodes projected onto the road by ``steps`` Newton steps along it from ``t``;
    returns their arc lengths after one step more, their sideways distances (left
    positive) from the road's tangent where they are, and the road there."""
    xy = nodes.xy[:, None, :]
    for _ in range(steps):
        at = _road_points(road, t)
        t = t + np.real(np.exp(-1j * at.heading) * (xy - at.point))
    at = _road_points(road, t)
    offset = np.exp(-1j * at.heading) * (xy - at.point)
    return t + np.real(offset), np.imag(offset) * nodes.real[:, None, :], at


def _sideways_jacobian(road: _Road, at: _RoadPoints) -> np.ndarray:
    """Derivatives of the nodes' sideways distances by the road's parameters, ``(..., nodes, 2 * parts + 1)``.

    With the nodes' arc lengths held, a parameter moves each node's road point by dP and
    its distance by ``-Im(conj(T) dP)`` (T the unit tangent). Turning the start turns the
    road about its start; moving knot k turns the road after it about the knot's corner
    by the change of curvature there; a part's curvature moves a point by
    ``i ∫ (P - P(u)) du`` over the part up to it, an integral :func:`_area_factor` gives.
    """
    back = np.exp(-1j * at.heading)
    back_real, back_imag = back.real[..., None], back.imag[..., None]

    def along_tangent(per_part: np.ndarray) -> np.ndarray:
        """``Re(conj(T) z)`` of each part's ``z`` at every node, ``(..., nodes, parts)``."""
        return back_real * per_part.real[..., None, :] - back_imag * per_part.imag[..., None, :]

    point_along = np.real(back * at.point)
    offset = -np.imag(back * 1j * np.exp(1j * road.base_heading)[..., None])
    turn = -(point_along - np.real(back * road.start()[..., None]))
    parts = np.arange(road.curvature.shape[-1])
    step = (road.curvature[..., :-1] - road.curvature[..., 1:])[..., None, :]
    knots = -step * (point_along[..., None] - along_tangent(at.corner[..., 1:])) * (at.part[..., None] >= parts[1:])
    full_area = at.length * at.corner + at.length**2 * np.exp(1j * at.part_heading) * _area_factor(road.curvature * at.length)
    own_curvature = np.take_along_axis(road.curvature, at.part, axis=-1)
    own_corner = np.take_along_axis(at.corner, at.part, axis=-1)
    own_heading = np.take_along_axis(at.part_heading, at.part, axis=-1)
    own_area = at.progress * own_corner + at.progress**2 * np.exp(1j * own_heading) * _area_factor(own_curvature * at.progress)
    passed = at.part[..., None] > parts
    curvatures = np.where(passed, along_tangent(full_area) - at.length[..., None, :] * point_along[..., None], 0.0)
    np.put_along_axis(curvatures, at.part[..., None], (np.real(back * own_area) - at.progress * point_along)[..., None], axis=-1)
    return np.concatenate((offset[..., None], turn[..., None], knots, curvatures), axis=-1)


def _polished(
    road: _Road, nodes: _Nodes, iterations: int = POLISH_ITERATIONS, wanted: np.ndarray | None = None,
    scales: tuple[float, ...] = STEP_SCALES,
) -> tuple[_Road, np.ndarray]:
    """The trial roads moved by Levenberg-Marquardt steps to where the nodes' sideways
    distances are least; returns them and that sum of squares ``(polylines, trials)``.
    Only the ``wanted`` trials (all if not given) are moved; each step is also tried
    ``scales`` times as long (:func:`_best_scaled_step`).

    Each trial is its own problem; one stops when a step no longer gains or the damping
    has grown to :data:`MAX_DAMPING`, so that the iterations are spent on those still moving.
    """
    polylines, trials = road.offset.shape
    road = _Road(*(np.array(getattr(road, f.name).reshape((-1, 1) + getattr(road, f.name).shape[2:])) for f in fields(_Road)))
    nodes = _Nodes(*(np.repeat(getattr(nodes, f.name), trials, axis=0) for f in fields(_Nodes)))
    t, distance, at = _projected(road, nodes, nodes.s[:, None, :].copy(), PROJECTION_STEPS)
    squares = np.einsum("ptn,ptn->pt", distance, distance)
    damping = np.full(squares.shape, 1e-3)
    active = np.arange(len(squares)) if wanted is None else np.flatnonzero(wanted)
    for _ in range(iterations):
        if active.size == 0:
            break
        here, here_nodes, here_at = _road_rows(road, active), _nodes_rows(nodes, active), _points_rows(at, active)
        jacobian = _sideways_jacobian(here, here_at) * (here_nodes.real[:, None, :, None] * here.movable()[..., None, :])
        normal = np.swapaxes(jacobian, -1, -2) @ jacobian
        gradient = np.einsum("ptnm,ptn->ptm", jacobian, distance[active])
        # A trial gone non-finite (a degenerate road) takes no step and stops.
        sound = np.isfinite(normal).all(axis=(-2, -1)) & np.isfinite(gradient).all(axis=-1)
        normal, gradient = np.where(sound[..., None, None], normal, 0.0), np.where(sound[..., None], gradient, 0.0)
        diagonal = np.einsum("...mm->...m", normal)
        normal += np.eye(normal.shape[-1]) * (damping[active][..., None] * diagonal + (diagonal <= 1e-12 * diagonal.max(axis=-1, keepdims=True)))[..., None, :]
        step = _solved(normal, -gradient)
        trial = _best_scaled_step(here, here_nodes, t[active], step, scales)
        better = (trial.road.is_ordered() & (trial.squares < squares[active]))[:, 0]
        gain = squares[active, 0] - trial.squares[:, 0]
        moved = active[better]
        _put_rows(road, moved, trial.road, better)
        _put_rows(at, moved, trial.at, better)
        t[moved], distance[moved], squares[moved] = trial.t[better], trial.distance[better], trial.squares[better]
        damping[active] = np.where(better, np.fmax(damping[active, 0] / 10.0, MIN_DAMPING), damping[active, 0] * 10.0)[:, None]
        done = np.where(better, gain <= POLISH_TOLERANCE * squares[active, 0], damping[active, 0] >= MAX_DAMPING) | ~sound[:, 0]
        active = active[~done]
    return _Road(*(getattr(road, f.name).reshape((polylines, trials) + getattr(road, f.name).shape[2:]) for f in fields(_Road))), squares.reshape(polylines, trials)


@dataclass(frozen=True)
class _Moved:
    """Roads ``(polylines, 1)`` after a polish step: the ``road``, the nodes' arc lengths
    ``t`` on it, their sideways ``distance``, the road ``at`` them and their sum of ``squares``."""

    road: _Road
    t: np.ndarray
    distance: np.ndarray
    at: _RoadPoints
    squares: np.ndarray


def _put_rows(target: Any, rows: np.ndarray | tuple, source: Any, take: np.ndarray | tuple) -> None:
    """Every array of the dataclass ``target`` (and of those in it) at ``rows`` set to ``source``'s at ``take``."""
    for field in fields(target):
        value = getattr(target, field.name)
        if is_dataclass(value):
            _put_rows(value, rows, getattr(source, field.name), take)
        else:
            value[rows] = getattr(source, field.name)[take]


def _moved(road: _Road, nodes: _Nodes, t: np.ndarray, step: np.ndarray) -> _Moved:
    """The roads ``road`` moved by the parameter ``step`` (as much of it as is feasible)."""
    trial = road.with_parameters(road.parameters() + step * road.feasible_fraction(step)[..., None])
    trial_t, distance, at = _projected(trial, nodes, t, 0)
    return _Moved(trial, trial_t, distance, at, np.einsum("ptn,ptn->pt", distance, distance))


def _best_scaled_step(road: _Road, nodes: _Nodes, t: np.ndarray, step: np.ndarray, scales: tuple[float, ...]) -> _Moved:
    """The roads ``road`` ``(polylines, 1)`` moved by the parameter ``step`` or by the
    multiple of it in ``scales`` (:data:`STEP_SCALES` in a full polish) that leaves the
    nodes closer.

    With the nodes held at their arc lengths, the linear model of the distances bends
    more than they do when the nodes slide along the road: along a gentle curve's start
    and end together, Gauss-Newton steps each go a small part of the way, in the same
    direction. A longer step in that direction goes further at the cost of a projection.
    """
    every = np.array((1.0, *scales))
    roads = _Road(*(np.repeat(getattr(road, f.name), len(every), axis=1) for f in fields(_Road)))
    moved = _moved(roads, nodes, t, step * every[:, None])
    return _chosen(moved, np.argmin(np.where(moved.road.is_ordered(), moved.squares, np.inf), axis=1)[:, None])


def _solved(normal: np.ndarray, right: np.ndarray) -> np.ndarray:
    """Solutions of the damped normal equations ``normal @ x = right``; where one is
    singular in floating point (parameters the nodes cannot tell apart), the least-norm one."""
    try:
        return np.linalg.solve(normal, right[..., None])[..., 0]
    except np.linalg.LinAlgError:
        return (np.linalg.pinv(normal, hermitian=True) @ right[..., None])[..., 0]


def _points_rows(at: _RoadPoints, rows: np.ndarray) -> _RoadPoints:
    """The road points of the trials ``rows``."""
    return _RoadPoints(*(getattr(at, f.name)[rows] for f in fields(_RoadPoints)))


def _base_road(batch: _SparseBatch, bounds: np.ndarray, curvature: np.ndarray, free: np.ndarray, knots: np.ndarray) -> _Road:
    """The road of the heading fit, one trial per polyline: its start heading is the
    weighted mean of the chords' headings less the turn the fit predicts over each."""
    turn = np.einsum("pnk,pk->pn", _chord_means_of_ramps(batch, bounds[:, None, :-1], np.diff(bounds)[:, None, :])[:, 0], curvature)
    weight = batch.root_weight**2
    base_heading = np.sum(weight * (batch.heading - turn), axis=1) / np.sum(weight, axis=1)
    zero = np.zeros((len(bounds), 1))
    return _Road(base_heading[:, None], zero, zero.copy(), bounds[:, None, :], curvature[:, None, :], free[:, None, :], knots[:, None])


def _road_rows(road: _Road, rows: np.ndarray) -> _Road:
    """The trial roads of the polylines ``rows``."""
    return _Road(*(getattr(road, f.name)[rows] for f in fields(_Road)))


def _split_part(road: _Road, part: np.ndarray, knot: np.ndarray, before: np.ndarray, after: np.ndarray) -> _Road:
    """The trial roads with their part ``part`` split at ``knot`` into two parts of
    curvature ``before`` and ``after`` (a curvature of 0 makes a straight), all ``(polylines, trials)``."""
    parts = road.curvature.shape[-1]
    index = np.arange(parts + 1)
    split = part[..., None]
    old = np.minimum(index - (index > split), parts - 1)
    curvature = np.take_along_axis(road.curvature, old, axis=-1)
    free = np.take_along_axis(road.free, old, axis=-1)
    curvature = np.where(index == split, before[..., None], np.where(index == split + 1, after[..., None], curvature))
    free = np.where(index == split, before[..., None] != 0, np.where(index == split + 1, after[..., None] != 0, free))
    bounds = np.sort(np.concatenate((road.bounds, knot[..., None]), axis=-1), axis=-1)
    return _Road(road.base_heading, road.offset, road.turn, bounds, curvature * free, free, road.last + 1)


def _among_nodes(nodes: _Nodes, first: np.ndarray, stop: np.ndarray, fraction: np.ndarray) -> np.ndarray:
    """Positions ``(polylines, trials)`` between ``first`` and ``stop`` at ``fraction`` of the
    way counted in nodes: the nodes between them and the two ends are spaced evenly in
    rank, and linearly between. Mappers put nodes close on a curve, so a curve short
    against a long part still gets trial knots on it."""
    s = nodes.s[:, None, :]
    inside = nodes.real[:, None, :] & (s > first[..., None]) & (s < stop[..., None])
    ranked = np.sort(np.where(inside, s, np.inf), axis=-1)
    count = inside.sum(axis=-1)
    ends = np.concatenate((first[..., None], ranked, np.full(first.shape + (1,), np.inf)), axis=-1)
    np.put_along_axis(ends, (count + 1)[..., None], stop[..., None], axis=-1)
    rank = fraction * (count + 1)
    below = np.minimum(np.floor(rank).astype(np.int64), count)
    low, high = (np.take_along_axis(ends, (below + k)[..., None], axis=-1)[..., 0] for k in (0, 1))
    return low + (rank - below) * (high - low)


def _straight_trials(road: _Road, nodes: _Nodes, part: np.ndarray, low: np.ndarray, high: np.ndarray) -> _Road:
    """Trial roads ``(polylines, fractions)`` from ``road`` (one trial per polyline), each
    with a straight over the fractions ``low[f]`` to ``high[f]`` of its part ``part``,
    counted in nodes (:func:`_among_nodes`; from the part's start when ``low`` is 0,
    which must then be the first part; to its end when ``high`` is 1).

    The trial stays close to the road: the straight takes the road's mean heading over
    it, and the arcs beside it turn from the road's heading at the part's ends to that
    (or the start is turned to it), so that the polish starts near its goal.
    """
    trials = np.shape(low)[-1]
    road = _Road(*(np.repeat(getattr(road, f.name), trials, axis=1) for f in fields(_Road)))
    part = np.repeat(part[:, None], trials, axis=1)
    first, stop = (np.take_along_axis(road.bounds, (part + k)[..., None], axis=-1)[..., 0] for k in (0, 1))
    start, end = _among_nodes(nodes, first, stop, low), _among_nodes(nodes, first, stop, high)
    start = np.where(low > 0.0, np.clip(start, first + MIN_POLISHED_PART_M, stop - 2.0 * MIN_POLISHED_PART_M), first)
    end = np.where(high < 1.0, np.clip(end, start + MIN_POLISHED_PART_M, stop - MIN_POLISHED_PART_M), stop)
    curvature = np.take_along_axis(road.curvature, part[..., None], axis=-1)[..., 0]
    half_turn = 0.5 * curvature * (end - start)
    before = curvature + half_turn / np.fmax(start - first, MIN_POLISHED_PART_M)
    after = curvature + half_turn / np.fmax(stop - end, MIN_POLISHED_PART_M)
    zero = np.zeros_like(curvature)
    if np.all(low == 0.0):
        road = _Road(road.base_heading, road.offset, road.turn + half_turn, *(getattr(road, f.name) for f in fields(_Road)[3:]))
        return _split_part(road, part, end, zero, after)
    if np.all(high == 1.0):
        return _split_part(road, part, start, before, zero)
    return _split_part(_split_part(road, part, start, before, after), part + 1, end, zero, after)


def _stretched_trials(road: _Road, factors: np.ndarray) -> _Road:
    """Trial roads ``(polylines, 1 + factors)``: ``road`` (one trial per polyline) and, for
    each factor, its longest curved part stretched by that factor about its middle (as far
    as its neighbours leave room), turning the same angle.

    A few nodes on a curve often fit a short sharp arc about as well as a long gentle
    one; the heading fit picks one, and the polish stays near what it is given. Polishing
    both from the start lets the nodes decide (3.4, 3.5: where the curve starts and ends).
    """
    trials = len(factors)
    stretched = _Road(*(np.repeat(getattr(road, f.name), trials, axis=1) for f in fields(_Road)))
    parts = road.curvature.shape[-1]
    part = np.argmax(np.where(road.free, np.diff(road.bounds, axis=-1), -1.0), axis=-1)
    bounds = stretched.bounds
    first, stop = (np.take_along_axis(bounds, np.repeat(part + k, trials, axis=1)[..., None], axis=-1)[..., 0] for k in (0, 1))
    below = np.take_along_axis(bounds, np.repeat(np.maximum(part - 1, 0), trials, axis=1)[..., None], axis=-1)[..., 0]
    above = np.take_along_axis(bounds, np.repeat(np.minimum(part + 2, parts), trials, axis=1)[..., None], axis=-1)[..., 0]
    middle, half = 0.5 * (first + stop), 0.5 * (stop - first) * factors
    is_first, is_last = part == 0, part == road.last
    start = np.where(is_first, first, np.clip(middle - half, below + MIN_POLISHED_PART_M, stop))
    end = np.where(is_last, stop, np.clip(middle + half, start + MIN_POLISHED_PART_M, above - MIN_POLISHED_PART_M))
    index = np.repeat(part, trials, axis=1)[..., None]
    np.put_along_axis(bounds, index, start[..., None], axis=-1)
    np.put_along_axis(bounds, index + 1, end[..., None], axis=-1)
    curvature = stretched.curvature
    angle = np.take_along_axis(curvature, index, axis=-1)[..., 0] * (stop - first)
    np.put_along_axis(curvature, index, (angle / np.fmax(end - start, MIN_POLISHED_PART_M))[..., None], axis=-1)
    return _joined_trials([road, stretched])


def _chosen(trials: Any, trial: np.ndarray) -> Any:
    """The dataclass of ``(polylines, trials, ...)`` arrays ``trials`` (and those in it) at
    the trials ``trial`` ``(polylines, k)`` of each polyline."""
    rows = np.arange(len(trial))[:, None]
    def chosen(values: Any) -> Any:
        return _chosen(values, trial) if is_dataclass(values) else values[rows, trial]
    return type(trials)(*(chosen(getattr(trials, f.name)) for f in fields(trials)))


def _padded_road(road: _Road) -> _Road:
    """``road`` with a part of no length more at its end (padding)."""
    return _Road(
        road.base_heading, road.offset, road.turn,
        np.concatenate((road.bounds, road.bounds[..., -1:]), axis=-1),
        np.concatenate((road.curvature, np.zeros_like(road.curvature[..., :1])), axis=-1),
        np.concatenate((road.free, np.zeros_like(road.free[..., :1])), axis=-1),
        road.last,
    )


def _one_trial_each(road: _Road) -> _Road:
    """The trial roads ``(polylines, trials)`` as ``(polylines * trials, 1)``."""
    return _Road(*(getattr(road, f.name).reshape((-1, 1) + getattr(road, f.name).shape[2:]) for f in fields(_Road)))


def _trials_of(road: _Road, polylines: int) -> _Road:
    """Trial roads ``(polylines * k, 1)`` back as ``(polylines, k)``."""
    return _Road(*(getattr(road, f.name).reshape((polylines, -1) + getattr(road, f.name).shape[2:]) for f in fields(_Road)))


def _joined_trials(roads: list[_Road]) -> _Road:
    """The trial roads of ``roads`` (of equal part counts) side by side."""
    return _Road(*(np.concatenate([getattr(r, f.name) for r in roads], axis=1) for f in fields(_Road)))


def _residual_variance(squares: np.ndarray, roads: _Road, real: np.ndarray, estimate: np.ndarray) -> np.ndarray:
    """Each polyline's sideways noise variance, m²: the smaller of its own ``estimate`` and
    what the trial road closest to its nodes leaves (its sum of squares over the nodes less
    the road's parameters, at least :data:`MIN_VARIANCE_FREEDOM` of them), at least
    :data:`SPARSE_MIN_NOISE_M` squared. The estimate from the chords errs on the large
    side where the curvature changes; a fit's residual needs a few nodes to spare."""
    freedom = real.sum(axis=1)[:, None] - roads.movable().sum(axis=-1)
    usable = freedom >= MIN_VARIANCE_FREEDOM
    best = np.argmin(np.where(usable, squares, np.inf), axis=1)
    rows = np.arange(len(squares))
    fitted = np.where(usable[rows, best], squares[rows, best] / np.fmax(freedom[rows, best], 1), np.inf)
    return np.fmax(np.fmin(fitted, estimate), SPARSE_MIN_NOISE_M**2)


def _straight_trial_roads(road: _Road, nodes: _Nodes, last: np.ndarray, longest: np.ndarray) -> tuple[_Road, list[int]]:
    """The trial roads of the four kinds :func:`_with_added_straights` tries, side by side
    ``(polylines, trials)``: a straight at the start, at the end, at both (an arc between
    them) and in the middle of the ``longest`` curved part; also returns how many of each."""
    fraction = np.array(END_STRAIGHT_FRACTIONS)
    first_part = np.zeros(len(last), dtype=np.int64)
    start_trials = _straight_trials(road, nodes, first_part, np.zeros_like(fraction), fraction)
    end_trials = _straight_trials(road, nodes, last, 1.0 - fraction, np.ones_like(fraction))
    # An arc between two straights: the straight before it first, then the one after it.
    arc_low, arc_high = (np.array(ARC_SPANS)[:, k] for k in (0, 1))
    before_arcs = _one_trial_each(_straight_trials(road, nodes, first_part, np.zeros_like(arc_low), arc_low))
    after_share = np.tile((1.0 - arc_high) / (1.0 - arc_low), len(last))[:, None]
    each_nodes = _Nodes(*(np.repeat(getattr(nodes, f.name), len(arc_low), axis=0) for f in fields(_Nodes)))
    both_trials = _trials_of(
        _straight_trials(before_arcs, each_nodes, before_arcs.last[:, 0], 1.0 - after_share, np.ones_like(after_share)), len(last)
    )
    low, high = (np.array(MIDDLE_STRAIGHT_SPANS)[:, k] for k in (0, 1))
    middle_trials = _straight_trials(road, nodes, longest, low, high)
    trials = _joined_trials([_padded_road(start_trials), _padded_road(end_trials), both_trials, middle_trials])
    return trials, [len(fraction), len(fraction), len(arc_low), len(low)]


def _with_added_straights(
    road: _Road, squares: np.ndarray, nodes: _Nodes, noise_variance: np.ndarray
) -> tuple[_Road, np.ndarray]:
    """Straights added into curved parts where the polished road then lies closer to the
    nodes by more than :data:`STRAIGHT_TRIAL_THRESHOLD` times their noise variance
    per parameter added.

    A curve's first (or last) knot is missed when the straight before it has only a few
    nodes: the straight and the curve are then fitted as one curved part that starts at
    the polyline's start (3.4), however clearly its first nodes lie on a line. A curve
    in the middle of a way may need both straights before either pays off, and two
    curves with a straight between them may have been fitted as one. So a straight at
    the start, at the end, at both and in the middle of the longest curved part are tried
    together, each from several places (:data:`END_STRAIGHT_FRACTIONS`,
    :data:`MIDDLE_STRAIGHT_SPANS`), and the road that costs least is kept. The noise
    variance is the smaller of the polyline's own estimate and what the closest road
    leaves (:func:`_residual_variance`); the estimate alone decides which roads are tried.

    Returns the roads (two parts more, padding where no straight was added) and their sums of squares.
    """
    result, squares = _padded_road(_padded_road(road)), squares.copy()
    polylines = np.arange(len(road.last))
    last = road.last[:, 0]
    longest = np.argmax(np.where(road.free[:, 0], np.diff(road.bounds[:, 0], axis=-1), -1.0), axis=-1)
    # A trial must leave the nodes enough freedom to be judged by.
    freedom = nodes.real.sum(axis=1) - road.movable()[:, 0].sum(axis=1)
    at_start = road.free[polylines, 0, 0] & (freedom - 1 >= MIN_TRIAL_FREEDOM)
    at_end = road.free[polylines, 0, last] & (freedom - 1 >= MIN_TRIAL_FREEDOM)
    at_both = at_start & at_end & (freedom - 2 >= MIN_TRIAL_FREEDOM)
    in_middle = road.free[polylines, 0, longest] & (freedom - 3 >= MIN_TRIAL_FREEDOM)
    # A road as close to the nodes as their noise lets it be leaves nothing for a straight to explain.
    rows = np.flatnonzero((at_start | at_end | in_middle) & (squares[:, 0] > STRAIGHT_TRIAL_MISFIT * freedom * noise_variance))
    if rows.size == 0:
        return result, squares
    tried = _road_rows(road, rows)
    trials, counts = _straight_trial_roads(tried, _nodes_rows(nodes, rows), last[rows], longest[rows])
    added = np.repeat([1, 1, 2, 3], counts)  # parameters each kind adds: one knot, two, two and a curvature
    kind_allowed = (at_start, at_end, at_both, in_middle)
    allowed = np.column_stack([np.repeat(ok[rows, None], count, axis=1) for count, ok in zip(counts, kind_allowed)])
    allowed &= trials.is_ordered()
    # A few steps show which trial of each kind leads; only those are polished to the end.
    trials, trial_squares = _polished(trials, _nodes_rows(nodes, rows), FIRST_POLISH_ITERATIONS, allowed, scales=())
    trial_squares = np.where(allowed, trial_squares, np.inf)
    kind_start = np.cumsum([0, *counts])
    leading = np.column_stack([
        first + np.argmin(trial_squares[:, first:stop], axis=1) for first, stop in zip(kind_start[:-1], kind_start[1:])
    ])
    trials = _chosen(trials, leading)
    added, allowed = added[leading], np.take_along_axis(allowed, leading, axis=1)
    trials, trial_squares = _polished(trials, _nodes_rows(nodes, rows), wanted=allowed)
    trial_squares = np.where(allowed, trial_squares, np.inf)
    variance = _residual_variance(
        np.concatenate((trial_squares, squares[rows]), axis=1), _joined_trials([trials, _padded_road(_padded_road(tried))]),
        nodes.real[rows], noise_variance[rows],
    )
    cost = np.where(allowed, trial_squares + added * (STRAIGHT_TRIAL_THRESHOLD * variance)[:, None], np.inf)
    best = np.argmin(cost, axis=1)
    accept = cost[np.arange(len(rows)), best] < squares[rows, 0]
    changed, best = rows[accept], best[accept]
    _put_rows(result, (changed, 0), trials, (np.flatnonzero(accept), best))
    squares[changed, 0] = trial_squares[np.flatnonzero(accept), best]
    return result, squares


def _nodes_rows(nodes: _Nodes, rows: np.ndarray, most: int | None = None) -> _Nodes:
    """The nodes of the polylines ``rows`` (the first ``most`` of each, if given)."""
    return _Nodes(nodes.xy[rows, :most], nodes.s[rows, :most], nodes.real[rows, :most])


def _along_polyline(t: np.ndarray, nodes: _Nodes, node_t: np.ndarray) -> np.ndarray:
    """Arc lengths ``t`` ``(polylines, k)`` on the road converted to arc lengths along the
    polyline, linearly between the nodes' projections ``node_t`` (beyond them, one to one)."""
    count = nodes.real.sum(axis=1)
    node_t = np.maximum.accumulate(np.where(nodes.real, node_t, np.inf), axis=1)
    after = np.clip((node_t[:, None, :] <= t[:, :, None]).sum(axis=2), 1, count[:, None] - 1)
    rows = np.arange(len(t))[:, None]
    t0, t1 = node_t[rows, after - 1], node_t[rows, after]
    s0, s1 = nodes.s[rows, after - 1], nodes.s[rows, after]
    fraction = (t - t0) / np.fmax(t1 - t0, 1e-9)
    inside = s0 + np.clip(fraction, 0.0, 1.0) * (s1 - s0)
    return inside + np.fmax(t - t1, 0.0) * (after == count[:, None] - 1) + np.fmin(t - t0, 0.0) * (after == 1)


def _polished_parts(
    batch: _SparseBatch, nodes: _Nodes, bounds: np.ndarray, curvature: np.ndarray, free: np.ndarray, knots: np.ndarray, noise_variance: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The heading fit's parts polished in the plane (:func:`_polished`), from it and from
    its longest curve stretched and shrunk (:func:`_stretched_trials`), with straights
    added where they fit (:func:`_with_added_straights`); returns bounds along the polyline,
    curvatures and the number of knots, as :func:`_sparse_batch_parts`."""
    trials = _stretched_trials(_base_road(batch, bounds, curvature, free, knots), np.array(STRETCH_FACTORS))
    ordered = trials.is_ordered()
    trials, squares = _polished(trials, nodes, FIRST_POLISH_ITERATIONS, ordered, scales=())
    leading = np.argmin(np.where(ordered, squares, np.inf), axis=1)[:, None]
    road, squares = _polished(_chosen(trials, leading), nodes)
    road, squares = _with_added_straights(road, squares, nodes, noise_variance)
    t = np.broadcast_to(nodes.s[:, None, :], nodes.s.shape[:1] + (1,) + nodes.s.shape[1:]).copy()
    node_t = _projected(road, nodes, t, PROJECTION_STEPS)[0][:, 0]
    polished = _along_polyline(road.bounds[:, 0], nodes, node_t)
    knots = road.last[:, 0]
    polished[:, 0] = 0.0
    polished = np.where(np.arange(polished.shape[1])[None, :] > knots[:, None], batch.end[:, None], polished)
    return np.maximum.accumulate(np.clip(polished, 0.0, batch.end[:, None]), axis=1), road.curvature[:, 0], knots


def _sparse_batch_parts(batch: _SparseBatch, nodes: _Nodes, noise_m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Parts of the sparse polylines of a batch: a continuous piecewise-linear fit of their
    heading, polished in the plane.

    Returns the part bounds in each polyline's arc length (``[0, ..., end]``, padded with
    the end), each part's curvature, 1/m, and the number of knots of each polyline.

    A map way has few nodes per curve, so the independent line per part of the dense
    method has too few chords to fit; here the heading is one continuous function
    (the road has no kinks, 3.4-3.8) with free knots, every chord predicted by the
    mean heading over the arc it spans, chords across a knot included. Knots are
    added and dropped by the same significance as the dense method's splits, and a
    part whose curvature is not significant is a straight. The road these parts
    describe is then fitted to the nodes themselves (:func:`_polished_parts`).
    """
    sideways_variance = np.fmax(noise_m, SPARSE_MIN_NOISE_M) ** 2
    noise_variance = 2.0 * sideways_variance
    knot_threshold = _split_threshold(batch.count) - SPLIT_OFFSET + SPARSE_KNOT_OFFSET
    bounds, knots = _knot_fit(batch, knot_threshold * noise_variance)
    bounds, free = _with_straights(batch, _trimmed(bounds, knots), knots, SPARSE_STRAIGHT_THRESHOLD * noise_variance)
    curvature = _fits(batch, bounds[:, None, :], free[:, None, :])[1][:, 0]
    # The polish adds two parts (end straights) to every curved polyline's road; it is
    # done in groups of similar node counts, so that little of its work is padding.
    curved = free.any(axis=1)
    node_count = nodes.real.sum(axis=1)
    group = np.searchsorted(SPARSE_BATCH_CHORDS, node_count - 1)
    bounds = np.concatenate((bounds, np.repeat(bounds[:, -1:], 2, axis=1)), axis=1)
    curvature = np.concatenate((curvature, np.zeros((len(curvature), 2))), axis=1)
    knots = knots.copy()
    for size in np.unique(group[curved]):
        rows = np.flatnonzero(curved & (group == size))
        bounds[rows], curvature[rows], knots[rows] = _polished_parts(
            batch.rows(rows), _nodes_rows(nodes, rows, int(node_count[rows].max())), bounds[rows, :-2], curvature[rows, :-2],
            free[rows], knots[rows], sideways_variance[rows],
        )
    return bounds, curvature, knots


def _merged_straights(bounds: np.ndarray, curvature: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Parts of no length, and knots between two parts of equal curvature (two straights), removed."""
    keep = np.diff(bounds) > 0  # a part of no length at the start leaves its start, 0, to the next
    bounds, curvature = np.append(bounds[:-1][keep], bounds[-1]), curvature[keep]
    keep = np.concatenate(([True], curvature[1:] != curvature[:-1]))
    return np.append(bounds[:-1][keep], bounds[-1]), curvature[keep]


def _without_short_chords(
    start_s: np.ndarray, length_m: np.ndarray, heading: np.ndarray, shortest_m: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Chords of one polyline with the vertices that leave a chord shorter than
    ``shortest_m`` dropped (the first and last vertex are kept): the heading of a chord
    not much longer than the coordinate noise is noise.

    Returns each remaining chord's start arc length, arc length along the polyline and heading.
    """
    if length_m.min() >= shortest_m:
        return start_s, length_m, heading
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


def _padded_batch(polylines: list[tuple[np.ndarray, np.ndarray, np.ndarray]], size: int) -> _SparseBatch:
    """The batch of polylines given by their chords' start arc lengths, lengths and
    headings, padded to ``size`` chords with chords of no weight, 1 m long, beyond the end."""
    count = np.array([len(start_s) for start_s, _, _ in polylines])
    end = np.array([start_s[-1] + length_m[-1] for start_s, length_m, _ in polylines])
    a = end[:, None] + np.arange(size)[None, :] - count[:, None] + 1.0
    length_m, heading = np.ones((len(polylines), size)), np.zeros((len(polylines), size))
    real = np.arange(size)[None, :] < count[:, None]
    a[real] = np.concatenate([start_s for start_s, _, _ in polylines])
    length_m[real] = np.concatenate([length for _, length, _ in polylines])
    heading[real] = np.concatenate([h for _, _, h in polylines])
    return _SparseBatch(a, a + length_m, heading, np.where(real, length_m, 0.0), end, count)


def _sparse_parts(chords: _Chords, noise_m: np.ndarray, polylines: np.ndarray) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """Part bounds (``[0, ..., end]``) and curvatures of the sparse ``polylines``, fitted
    in batches of equal chord count (:func:`_sparse_batch_parts`)."""
    kept, every = {}, {}
    for polyline in polylines:
        first, stop = chords.polyline_first_chord[polyline : polyline + 2]
        every[int(polyline)] = (chords.start_s[first:stop], chords.length_m[first:stop], chords.heading[first:stop])
        kept[int(polyline)] = _without_short_chords(*every[int(polyline)], SHORT_CHORD_NOISE_FACTOR * float(noise_m[polyline]))
    by_size: dict[int, list[int]] = {}
    for polyline, (start_s, _, _) in kept.items():
        size = SPARSE_BATCH_CHORDS[np.searchsorted(SPARSE_BATCH_CHORDS, len(start_s))]
        by_size.setdefault(size, []).append(polyline)
    parts = {}
    for size, members in by_size.items():
        batch, nodes = _padded_batch([kept[p] for p in members], size), _padded_nodes([every[p] for p in members])
        bounds, curvature, knots = _sparse_batch_parts(batch, nodes, noise_m[members])
        for row, polyline in enumerate(members):
            parts[polyline] = _merged_straights(bounds[row, : knots[row] + 2], curvature[row, : knots[row] + 1])
    return parts


# --------------------------------------------------------------------------- profiles


def _straight_profile(vertex_s: np.ndarray) -> RadiusProfile:
    """The profile of a polyline without length: straight at every vertex, no parts."""
    return RadiusProfile(vertex_s.copy(), np.zeros(len(vertex_s)), np.full(len(vertex_s), np.inf), ())


def _polyline_vertex_s(chords: _Chords, polyline: int) -> np.ndarray:
    return chords.vertex_s[chords.polyline_first_vertex[polyline] : chords.polyline_first_vertex[polyline + 1]]


def _profile(vertex_s: np.ndarray, bounds: np.ndarray, curvature_of_part: np.ndarray) -> RadiusProfile:
    """The radius profile of one polyline from its part bounds (``[0, ..., end]``) and curvatures."""
    part = np.searchsorted(bounds[1:-1], vertex_s, side="right")
    curvature = curvature_of_part[part]
    magnitude = np.abs(curvature)
    radius = np.divide(1.0, magnitude, out=np.full(len(magnitude), np.inf), where=magnitude > 1.0 / np.finfo(float).max)
    edges = bounds.tolist()
    parts = tuple(map(ProfilePart, edges[:-1], edges[1:], curvature_of_part.tolist()))
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


def _is_sparse(chords: _Chords, noise_m: np.ndarray) -> np.ndarray:
    """Whether each polyline is a map way, to be fitted as a sparse one: :data:`MIN_SPARSE_CHORDS`
    to :data:`MAX_SPARSE_CHORDS` chords, with a median length of at least :data:`SPARSE_CHORD_M`
    or nodes as noisy as a map's (at least :data:`SPARSE_MIN_NOISE_M`; mappers put nodes
    closer together on a curve, and such chords' headings are mostly noise)."""
    count = np.diff(chords.polyline_first_chord)
    median_m = _group_median(chords.length_m, chords.polyline, len(noise_m))
    sparse = (np.nan_to_num(median_m) >= SPARSE_CHORD_M) | (noise_m >= SPARSE_MIN_NOISE_M)
    return (count >= MIN_SPARSE_CHORDS) & (count <= MAX_SPARSE_CHORDS) & sparse


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
    sparse_parts = _sparse_parts(chords, noise_m, np.flatnonzero(_is_sparse(chords, noise_m)))
    return [
        _profile(_polyline_vertex_s(chords, p), *sparse_parts[p]) if p in sparse_parts else _dense_profile(segmentation, fit, p)
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
