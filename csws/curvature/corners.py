"""Applies to sparse ways the rules that keep a fitted profile to what its nodes can say.

A map way's nodes are few: a corner is often one node, and a fit to five noisy nodes
can put an arc of centimetres somewhere. These rules are kept apart from the fit
(:mod:`csws.curvature.polish`) so that each can be stated and checked on its own:

1. **No radius below the physical floor** :data:`FLOOR_RADIUS_M`. A road vehicle turns on
   no smaller radius; a smaller one is a fitting artefact. On a map way the part is
   dropped and its stretch handled as a corner (rule 3); on a dense shape (netconvert's
   stubs of a few metres at junctions) its radius is reported as the floor
   (:func:`with_floor`).
2. **No curve where the nodes do not turn.** A curve of the fit must not turn by more than
   the polyline's vertices over its stretch (those within it and the nearest one beyond
   either end) turn its way, added up, by more than :data:`ANGLE_TOLERANCE_DEG` and what
   node noise can take off that sum (:data:`NOISE_DEVIATIONS` deviations of the noise of
   the headings of the two segments it is measured between): no road through those nodes
   turns more. Node noise moves turning from one vertex to the next (hence the vertex
   beyond either end). A curve that breaks rule 1 or 2 is removed whole. The vertices of
   a map artefact count as one, turning by their net turn (the effective turns of
   :mod:`csws.curvature.artefacts`): the two reversals of a spike of a decimetre turn by
   180 degrees each, which counted as turning would let a curve turn a full circle more
   there, and would make them a loop at the floor radius under rule 3.
3. **A corner gets a radius.** Vertices that no curved part covers (none was fitted there,
   or rule 1 or 2 removed it) and that turn the same way one after another, by
   :data:`CORNER_MIN_DEG` or more together (and by more than node noise makes them
   turn; never next to a segment so short against the noise that it has no heading),
   are a curve the fit missed. Several such vertices are an arc drawn node by
   node: it turns by their turning, at the radius of the segments between them taken as
   chords (the turns at the first and last vertex counted half, the other half being
   onto the road beyond; on nodes evenly spaced on a circle, its radius). One such
   vertex is a corner mapped by one node. It gets the largest arc tangent
   to its two segments that fits within half of each (the other half belongs to the
   next corner), but no larger than an arc through the node that leaves the two segments
   by at most :data:`CORNER_DEVIATION_M` (a way is the road simplified within the mapping
   tolerance, so its nodes lie on the road and its segments within that tolerance of it:
   a corner of radius R turning by D leaves them by R (1 - cos D/2)), and no smaller than
   the floor. The arc is put in the profile with its angle and radius, centred on the node.

What this rule can and cannot promise: one node cannot tell a corner's radius, only
bound it. Both limits are upper bounds of the radius the way leaves room for, and the
smaller is taken: a true corner of larger radius would have needed more nodes to be
mapped within the tolerance. One of smaller radius gets a radius too large, by at most
what the tolerance allows (at 90 degrees, 6.8 m against a true 5 m). What the rule
changes is that the corner exists, with its angle and a radius of the right size,
where before the fit saw a straight and warned of nothing.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "FLOOR_RADIUS_M",
    "CORNER_MIN_DEG",
    "ANGLE_TOLERANCE_DEG",
    "CORNER_DEVIATION_M",
    "with_corner_rules",
    "with_floor",
    "curve_runs",
    "corner_arc",
    "corner_arc_extent",
    "curvature_at",
    "same_sign_runs",
    "cut_at_straights",
]

#: The smallest radius a road curve is given, m: the tightest turning circle of a car is
#: about 5 m (trucks and buses need 10-12 m).
FLOOR_RADIUS_M = 5.0
#: Vertices not covered by a curved part that turn one way by at least this much together are a curve, degrees.
CORNER_MIN_DEG = 20.0
#: How much more a curve may turn than the nodes over its stretch, degrees.
ANGLE_TOLERANCE_DEG = 5.0
#: How many standard deviations of the turning node noise makes a turn must exceed to count.
NOISE_DEVIATIONS = 3.0
#: The node noise the rules allow for is the way's own estimate, but no more than this, m:
#: a way's corners inflate the estimate, and mapped nodes lie within about this of the road.
MAX_NOISE_M = 0.5
#: What rule 2 leaves below its limit, so that the limit holds after rounding, rad.
ROUNDING_RAD = 1e-9
#: How far a corner's arc may pass from its node, m: the mapping tolerance of a way.
CORNER_DEVIATION_M = 2.0


def with_floor(start_k: np.ndarray, end_k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rule 1 alone, for any polyline: curvatures limited to that of :data:`FLOOR_RADIUS_M`."""
    limit = 1.0 / FLOOR_RADIUS_M
    return np.clip(start_k, -limit, limit), np.clip(end_k, -limit, limit)


def _corner_radius_m(turn_rad: float | np.ndarray, before_m: np.ndarray, after_m: np.ndarray) -> np.ndarray:
    """The radius of the arc of a corner turning ``turn_rad`` between segments of the given lengths (rule 3)."""
    half = np.abs(turn_rad) / 2.0
    tangent_room_m = np.minimum(before_m, after_m) / 2.0
    by_room = tangent_room_m / np.tan(half)
    by_deviation = CORNER_DEVIATION_M / (1.0 - np.cos(half))
    return np.maximum(np.minimum(by_room, by_deviation), FLOOR_RADIUS_M)


def _turning_within(
    vertex_s: np.ndarray,
    turn_rad: np.ndarray,
    segment_m: np.ndarray,
    noise_m: float,
    start_s: float,
    end_s: float,
    side: float,
) -> tuple[float, float]:
    """How much the polyline turns to one ``side`` (+1 left, -1 right) at its vertices within
    ``[start_s, end_s]`` and the nearest one beyond either end (the road may begin to turn
    anywhere on the segment before a node): the sum of those vertices' turns that way, and
    the standard deviation node noise gives that sum (:func:`_turn_noise_rad` of the two
    segments it is measured between), radians. No road through the nodes turns more that
    way there than the sum, give or take its noise."""
    first, stop = _window(vertex_s[1:-1], start_s, end_s)
    turning = float(np.clip(side * turn_rad[first:stop], 0.0, None).sum())
    last_segment = min(stop, len(segment_m) - 1)
    return turning, _turn_noise_rad(noise_m, float(segment_m[first]), float(segment_m[last_segment]))


def _turn_noise_rad(noise_m: float, before_m: float, after_m: float) -> float:
    """Standard deviation of the turn that node noise makes between two segments of the
    given lengths, rad. Noise lengthens short segments as often as it turns them, so each
    is taken at the shortest length its ends' relative noise allows (:data:`NOISE_DEVIATIONS`
    deviations of it shorter); ``inf`` where that leaves no length: such a segment has no
    heading at all."""
    relative_m = math.sqrt(2.0) * noise_m
    shortest_before_m, shortest_after_m = (length - NOISE_DEVIATIONS * relative_m for length in (before_m, after_m))
    if min(shortest_before_m, shortest_after_m) <= 0.0:
        return math.inf
    return relative_m * math.sqrt(1.0 / shortest_before_m**2 + 1.0 / shortest_after_m**2)


def _window(inner_s: np.ndarray, start_s: float, end_s: float) -> tuple[int, int]:
    """The inner vertices on ``[start_s, end_s]`` and the nearest one beyond either end, as a slice's start and stop."""
    first = max(int(np.searchsorted(inner_s, start_s, side="left")) - 1, 0)
    return first, int(np.searchsorted(inner_s, end_s, side="right")) + 1


def curve_runs(start_k: np.ndarray, end_k: np.ndarray) -> list[np.ndarray]:
    """The parts of each run of curved parts turning one way (a curve of the fit)."""
    side = np.sign(start_k + end_k)
    runs: list[list[int]] = []
    for part in np.flatnonzero(side != 0):
        if runs and runs[-1][-1] == part - 1 and side[part - 1] == side[part]:
            runs[-1].append(int(part))
        else:
            runs.append([int(part)])
    return [np.array(run) for run in runs]


def with_corner_rules(
    chord_start_s: np.ndarray,
    chord_length_m: np.ndarray,
    turn_rad: np.ndarray,
    noise_m: float,
    bounds: np.ndarray,
    start_k: np.ndarray,
    end_k: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One map way's fitted parts with rules 1-3 applied.

    Parameters
    ----------
    chord_start_s, chord_length_m
        Its chords (segments between vertices, repeated vertices dropped): arc length of
        their starts and lengths, m.
    turn_rad
        The turn of each vertex between two chords, left positive, with the way's map
        artefacts netted (:func:`csws.curvature.artefacts.netted_turns`): a spike's two
        reversals, which turn by 180 degrees each, turn the road by nothing, and rules 2
        and 3 count a vertex's turning only as far as the road can turn there.
    noise_m
        The coordinate noise of its nodes, m: a turn counts only beyond what it makes.
    bounds, start_k, end_k
        Its fitted parts: bounds from 0 to its length, and each part's curvature at its
        start and end, 1/m.

    Returns
    -------
    bounds, start_k, end_k
        The parts after the rules.
    """
    noise_m = min(noise_m, MAX_NOISE_M)
    vertex_s = np.append(chord_start_s, chord_start_s[-1] + chord_length_m[-1])
    bounds, start_k, end_k = _within_turning(vertex_s, turn_rad, chord_length_m, noise_m, bounds, start_k, end_k)
    return _with_missed_corners(vertex_s, turn_rad, chord_length_m, noise_m, bounds, start_k, end_k)


def _within_turning(
    vertex_s: np.ndarray,
    turn_rad: np.ndarray,
    segment_m: np.ndarray,
    noise_m: float,
    bounds: np.ndarray,
    start_k: np.ndarray,
    end_k: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rules 1 and 2: each fitted curve turned back to what the nodes turn (within node noise),
    or dropped where it is not the nodes' or sharper than the floor radius allows."""
    angle_rad = (start_k + end_k) / 2.0 * np.diff(bounds)
    start_k, end_k = start_k.copy(), end_k.copy()
    keep = np.ones(len(start_k), dtype=bool)
    for parts in curve_runs(start_k, end_k):
        angle = float(angle_rad[parts].sum())
        turn, turn_noise = _turning_within(
            vertex_s, turn_rad, segment_m, noise_m, bounds[parts[0]], bounds[parts[-1] + 1], math.copysign(1.0, angle)
        )
        allowed = turn + math.radians(ANGLE_TOLERANCE_DEG) - ROUNDING_RAD
        if abs(angle) > allowed:
            # Within what node noise can take off the turning, the fit's extent is kept and its
            # turn cut back; beyond it the curve is not the nodes' and goes whole.
            scale = allowed / abs(angle) if abs(angle) <= allowed + NOISE_DEVIATIONS * turn_noise else 0.0
            start_k[parts] *= scale
            end_k[parts] *= scale
        keep[parts] = np.fmax(np.abs(start_k[parts]), np.abs(end_k[parts])).max() * FLOOR_RADIUS_M <= 1.0
    return _merged(bounds, np.where(keep, start_k, 0.0), np.where(keep, end_k, 0.0))


def _with_missed_corners(
    vertex_s: np.ndarray,
    turn_rad: np.ndarray,
    segment_m: np.ndarray,
    noise_m: float,
    bounds: np.ndarray,
    start_k: np.ndarray,
    end_k: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rule 3: the turning no part covers, by vertices that turn the same way, made an arc
    (several vertices) or a corner's arc (one)."""
    covered = _covered(vertex_s[1:-1], bounds, start_k, end_k, turn_rad)
    for first, last in _turning_runs(turn_rad, covered):
        total = float(turn_rad[first : last + 1].sum())
        deviation = _turn_noise_rad(noise_m, float(segment_m[first]), float(segment_m[last + 1]))
        if abs(total) < max(math.radians(CORNER_MIN_DEG), NOISE_DEVIATIONS * deviation):
            continue
        if first == last:
            radius = float(_corner_radius_m(total, segment_m[first], segment_m[first + 1]))
        else:
            # The segments between the run's vertices are chords of its arc; the turns at
            # its first and last vertex are half on the arc, half onto the road beyond.
            inner_turn = abs(total) - (abs(turn_rad[first]) + abs(turn_rad[last])) / 2.0
            radius = max(segment_m[first + 1 : last + 1].sum() / max(inner_turn, 1e-9), FLOOR_RADIUS_M)
        centre_s = (vertex_s[first + 1] + vertex_s[last + 1]) / 2.0
        bounds, start_k, end_k = _with_arc(bounds, start_k, end_k, centre_s, radius, total)
    return bounds, start_k, end_k


def _turning_runs(turn_rad: np.ndarray, covered: np.ndarray) -> list[tuple[int, int]]:
    """First and last index of each maximal run of inner vertices that no curved part covers
    and that turn the same way."""
    return same_sign_runs(np.where(covered, 0, np.sign(turn_rad)))


def same_sign_runs(side: np.ndarray) -> list[tuple[int, int]]:
    """First and last index of each maximal run of equal non-zero entries of ``side``."""
    runs: list[tuple[int, int]] = []
    for index in np.flatnonzero(side != 0).tolist():
        if runs and runs[-1][1] == index - 1 and side[index - 1] == side[index]:
            runs[-1] = (runs[-1][0], index)
        else:
            runs.append((index, index))
    return runs


def cut_at_straights(first: int, last: int, vertex_s: np.ndarray, longest_m: float) -> list[tuple[int, int]]:
    """A run of vertices ``first`` to ``last`` (arc lengths ``vertex_s``) cut at each segment longer than
    ``longest_m``, as first and last index of each piece in order.

    Vertices turning one way one after another with such a segment between them (the corners of a
    block, of a loop round it) are corners joined by a straight that no corner spans, not one corner.
    """
    cuts = (first + np.flatnonzero(np.diff(vertex_s[first : last + 1]) > longest_m)).tolist()
    return list(zip([first, *(cut + 1 for cut in cuts)], [*cuts, last], strict=True))


def _covered(
    inner_s: np.ndarray, bounds: np.ndarray, start_k: np.ndarray, end_k: np.ndarray, turn_rad: np.ndarray
) -> np.ndarray:
    """Whether each inner vertex's turning belongs to a curve of the profile: the vertex turns
    the curve's way and lies within the stretch whose turning rule 2 gave the curve (on
    it, or the nearest vertex beyond either end)."""
    covered = np.zeros(len(inner_s), dtype=bool)
    for parts in curve_runs(start_k, end_k):
        first, stop = _window(inner_s, bounds[parts[0]], bounds[parts[-1] + 1])
        covered[first:stop] |= np.sign(start_k[parts[0]] + end_k[parts[0]]) * turn_rad[first:stop] > 0
    return covered


def _merged(bounds: np.ndarray, start_k: np.ndarray, end_k: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The parts with neighbours of one constant curvature joined (straights left by rule 1 or 2)."""
    constant = start_k == end_k
    same = constant[1:] & constant[:-1] & (start_k[1:] == start_k[:-1])
    keep = np.concatenate(([True], ~same))
    return np.append(bounds[:-1][keep], bounds[-1]), start_k[keep], end_k[keep]


def _with_arc(
    bounds: np.ndarray, start_k: np.ndarray, end_k: np.ndarray, centre_s: float, radius_m: float, turn_rad: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The parts with an arc of ``radius_m`` turning ``turn_rad`` centred on ``centre_s`` laid into
    the straight there, shortened to that straight where it is shorter."""
    part = int(np.clip(np.searchsorted(bounds, centre_s, side="right") - 1, 0, len(start_k) - 1))
    if start_k[part] != 0 or end_k[part] != 0:
        return bounds, start_k, end_k
    half_m = radius_m * abs(turn_rad) / 2.0
    low, high = max(float(bounds[part]), centre_s - half_m), min(float(bounds[part + 1]), centre_s + half_m)
    if high <= low:
        return bounds, start_k, end_k
    curvature = math.copysign(1.0 / radius_m, turn_rad)
    before, after = start_k[: part + 1], start_k[part:]
    new_bounds = np.concatenate((bounds[: part + 1], [low, high], bounds[part + 1 :]))
    new_start = np.concatenate((before, [curvature], after))
    new_end = np.concatenate((end_k[: part + 1], [curvature], end_k[part:]))
    # A straight the arc begins or ends at keeps no piece of no length.
    length = np.diff(new_bounds)
    kept = length > 0
    return np.append(new_bounds[:-1][kept], new_bounds[-1]), new_start[kept], new_end[kept]


def corner_arc(
    corner: tuple[float, float, float],
    arms_m: tuple[float, float],
    inner_chords_m: float,
    vertices: int,
    bounds: np.ndarray,
    start_k: np.ndarray,
    end_k: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The parts with an arc turning a polyline corner's net turn laid over whatever was fitted there.

    ``corner`` is the arc length of its first and last vertex (m) and its net turn (rad, left
    positive); ``arms_m`` how far the polyline runs without turning before and after it (m),
    ``inner_chords_m`` the length between its first and last vertex and ``vertices`` their number.
    Its radius is rule 3's: for a corner of one vertex the largest arc tangent to its arms within
    half of each and the mapping tolerance; for several vertices the radius of the segments
    between them taken as chords. It is centred between the corner's first and last vertex and
    kept within half of its arms: where that is shorter, it turns the corner on a smaller
    radius, but none below the floor.
    """
    low, high = corner_arc_extent(corner, arms_m, inner_chords_m, vertices)
    if high <= low:
        return bounds, start_k, end_k
    turn_rad = corner[2]
    curvature = math.copysign(min(abs(turn_rad) / (high - low), 1.0 / FLOOR_RADIUS_M), turn_rad)
    return _laid_over(bounds, start_k, end_k, low, high, curvature)


def corner_arc_extent(
    corner: tuple[float, float, float], arms_m: tuple[float, float], inner_chords_m: float, vertices: int
) -> tuple[float, float]:
    """Where :func:`corner_arc` lays a corner's arc (its arguments alike), from and to arc length, m: the stretch
    over which the map lets the road turn the corner (rule 3)."""
    start_s, end_s, turn_rad = corner
    turn = abs(turn_rad)
    if vertices == 1:
        radius = float(_corner_radius_m(turn, np.array(arms_m[0]), np.array(arms_m[1])))
    else:
        inner_turn = max(turn * (vertices - 1) / vertices, 1e-9)
        radius = max(inner_chords_m / inner_turn, FLOOR_RADIUS_M)
    half_m = radius * turn / 2.0
    room_low, room_high = start_s - arms_m[0] / 2.0, end_s + arms_m[1] / 2.0
    high = min(room_high, max(room_low, (start_s + end_s) / 2.0 - half_m) + 2.0 * half_m)
    return float(max(room_low, high - 2.0 * half_m)), float(high)


def _laid_over(
    bounds: np.ndarray, start_k: np.ndarray, end_k: np.ndarray, low: float, high: float, curvature: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The parts with ``[low, high]`` replaced by one arc of ``curvature``; parts it cuts keep their curvature there."""
    at_low, at_high = (curvature_at(bounds, start_k, end_k, s) for s in (low, high))
    before = bounds[:-1] < low
    after = bounds[1:] > high
    new_bounds = np.concatenate((bounds[:-1][before], [low, high], bounds[1:][after]))
    new_start = np.concatenate((start_k[before], [curvature], [at_high] * bool(after.any()), start_k[after][1:]))
    new_end = np.concatenate((end_k[before][:-1], [at_low] * bool(before.any()), [curvature], end_k[after]))
    kept = np.diff(new_bounds) > 0
    return np.append(new_bounds[:-1][kept], new_bounds[-1]), new_start[kept], new_end[kept]


def curvature_at(bounds: np.ndarray, start_k: np.ndarray, end_k: np.ndarray, s: float) -> float:
    """The parts' curvature at arc length ``s`` (linear within a part), 1/m."""
    part = int(np.clip(np.searchsorted(bounds, s, side="right") - 1, 0, len(start_k) - 1))
    fraction = (s - bounds[part]) / max(float(bounds[part + 1] - bounds[part]), 1e-12)
    return float(start_k[part] + (end_k[part] - start_k[part]) * fraction)
