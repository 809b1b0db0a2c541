"""Cuts the heading of dense polylines (SUMO lane shapes) against arc length into parts of constant curvature.

Binary segmentation, knot refinement and merging for all polylines of a network at once;
see :mod:`csws.curvature` for the method."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .chords import _Chords, _group_median

#: Fewest chords a part of constant curvature is fitted over.
MIN_PART_CHORDS = 2
#: A split (or a knot kept) must reduce the normalised residual by PENALTY * ln(chords) + OFFSET.
SPLIT_PENALTY = 2.0
SPLIT_OFFSET = 15.0
#: Knot refinement passes between two merge tests.
REFINE_PASSES = 4
#: A chord straddles a knot when the knot lies more than this fraction of it from either end.
STRADDLE_FRACTION = 0.05
#: A polyline whose median chord is at least this long is a sparse one (a map way), m.
SPARSE_CHORD_M = 3.0
#: Fewest and most chords a polyline is fitted as a sparse one with (the sparse fit's work
#: grows steeply with the chords and knots of a polyline; longer ones take the dense path).
MIN_SPARSE_CHORDS = 4
MAX_SPARSE_CHORDS = 80
#: Lower bound of the coordinate noise of a sparse polyline, m: a map way's nodes are not
#: placed more precisely than this, and the fit's own approximation stays below it.
SPARSE_MIN_NOISE_M = 0.05


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
        gain = whole - _residual(prefix, first[part], split) - _residual(prefix, split, stop[part])
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
        self.knot_s = np.concatenate((np.delete(self.knot_s, step), self.start_s[self.starts[-2 * len(step) :]]))
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
        chord = np.clip(
            np.searchsorted(from_g, knot_g, side="right") - 1, self.chords.polyline_first_chord[polyline], None
        )
        fraction = np.clip((knot_g - from_g[chord]) / from_length[chord], 0.0, 1.0)
        return to_start[chord] + fraction * to_length[chord]


def _polyline_vertex_s(chords: _Chords, polyline: int) -> np.ndarray:
    return chords.vertex_s[chords.polyline_first_vertex[polyline] : chords.polyline_first_vertex[polyline + 1]]


def _dense_parts(segmentation: _Segmentation, fit: _Fit, polyline: int) -> tuple[np.ndarray, np.ndarray] | None:
    """Part bounds (``[0, ..., length]``) and curvatures of one polyline from the network's
    segmentation and part fits; None for a polyline without chords."""
    chords = segmentation.chords
    first_chord, stop_chord = chords.polyline_first_chord[polyline : polyline + 2]
    if first_chord == stop_chord:
        return None
    first_part, stop_part = np.searchsorted(segmentation.starts, (first_chord, stop_chord))
    bounds = np.append(segmentation.knot_s[first_part:stop_part], _polyline_vertex_s(chords, polyline)[-1])
    bounds[0] = 0.0
    return bounds, fit.curvature[first_part:stop_part]


def _is_mapped(chords: _Chords, noise_m: np.ndarray) -> np.ndarray:
    """Whether each polyline is a map way rather than a dense shape: a median chord of at
    least :data:`SPARSE_CHORD_M`, or nodes as noisy as a map's (at least
    :data:`SPARSE_MIN_NOISE_M`; mappers put nodes closer together on a curve, and such
    chords' headings are mostly noise)."""
    median_m = _group_median(chords.length_m, chords.polyline, len(noise_m))
    return (np.nan_to_num(median_m) >= SPARSE_CHORD_M) | (noise_m >= SPARSE_MIN_NOISE_M)


def _is_sparse(chords: _Chords, noise_m: np.ndarray) -> np.ndarray:
    """Whether each polyline is a map way to be fitted as a sparse one: :func:`_is_mapped`,
    with :data:`MIN_SPARSE_CHORDS` to :data:`MAX_SPARSE_CHORDS` chords."""
    count = np.diff(chords.polyline_first_chord)
    return (count >= MIN_SPARSE_CHORDS) & (count <= MAX_SPARSE_CHORDS) & _is_mapped(chords, noise_m)
