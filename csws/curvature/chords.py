"""Computes a polyline's chords (heading against arc length) and the coordinate noise estimated from them."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

#: Chords shorter than this are treated as repeated vertices, m. With coordinates rounded
#: to the centimetre such a chord's heading is off by more than 10 degrees, and netconvert
#: leaves centimetre-long backward chords at junctions that would read as a U-turn.
MIN_CHORD_M = 0.05
#: Lower bound of the coordinate noise, m: that of rounding to the centimetre, as SUMO
#: writes shapes. Rounding a regularly spaced line can leave errors too regular for
#: :func:`_coordinate_noise_m` to see, yet they still bend short chords.
MIN_NOISE_M = 0.01 / math.sqrt(12.0)
#: Fewest noise samples a polyline's noise is taken as their median from (else their RMS).
MIN_MEDIAN_SAMPLES = 10
#: Converts the median absolute deviation of a normal sample into its standard deviation.
MAD_TO_SIGMA = 1.4826


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
