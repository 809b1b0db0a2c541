"""Finds map artefacts and corners on a polyline, and keeps a fitted profile to the polyline's net turn.

A road polyline drawn from a map carries shapes no road has: a node placed twice with a
few centimetres of back-and-forth between the copies, a junction shape that runs back over
its own lane and forward again, a sideways jog of less than a metre, a string of nodes
zig-zagging by degrees about a straight line. A fit honours them: it bends the road by
up to 180 degrees at a radius of the floor, or sums the wiggles into a long curve. These
rules read the polyline alone (its vertices' turns, wrapped to (-180, 180] degrees), not
the fit:

* **back-and-forth** (``spike`` when the segment between the two reversals is at most
  :data:`SPIKE_M` long, else ``fold``): two vertices joined by one segment of at most
  :data:`FOLD_M`, each turning by :data:`REVERSAL_DEG` or more: the polyline runs back
  along that segment and then forward again;
* **jog**: two vertices joined by a segment of at most :data:`JOG_M`, turning opposite
  ways by :data:`JOG_DEG` or more each (the road turns by their net turn there, if at all);
* **zig-zag**: a run of at least three vertices turning alternately left and right, each
  by at least :data:`ZIGZAG_VERTEX_DEG`, whose turns add up in absolute value to at least
  :data:`ZIGZAG_SUM_DEG` while netting less than :data:`ARTEFACT_NET_DEG`.

An artefact's vertices count as one turn, their net turn wrapped to (-180, 180] (a spike
nets nothing, a fold what its lane really turns): the **effective turns**. From them:

* the **net turn** of a stretch one way is the sum of the effective turns of the vertices
  inside it, and of the nearest one at or beyond either end where that turns that way (the road
  may begin to turn anywhere on the segment before a node; a vertex on an end turns onto the
  road beyond as much as onto the stretch);
* a **corner** is a run of consecutive vertices turning the same way by at least
  :data:`CORNER_VERTEX_DEG` each, each between segments longer than :data:`JOG_M` or
  continued straight beyond (a shorter one turning on has no heading of its own: a junction
  stub, a jog), no more than :data:`CORNER_SPAN_M`
  from first to last, whose effective turns add up to :data:`CORNER_MIN_DEG` or more (a
  hairpin drawn by two, three or four nodes is one corner); a run of such vertices is first
  cut at each segment longer than :data:`CORNER_SPAN_M`, a straight no corner spans (the
  corners of a block one after another: :func:`csws.curvature.corners.cut_at_straights`).

:func:`kept_to_polyline` applies two rules to a fitted profile: no curve turns more than
the net turn of its stretch by more than :data:`ANGLE_TOLERANCE_DEG`, nor does any part of
a curve (either is turned back to that net turn, and removed where the net turn is below
the tolerance: a curve at a spike or a zig-zag); and every corner is covered by curves
turning its net turn within the tolerance near it (from the second vertex before it to the
second after, or over its arc where that is longer, but only halfway to the corners beside
it, whose turning is theirs: a long gentle curve run through a corner does not cover it, nor
does the arc of the corner next to it; :mod:`csws.curvature.coverage`), else an arc turning
that net turn is laid over it (:func:`csws.curvature.corners.corner_arc`), in place of what the
curves turned its way there.
The first rule is applied once more to what the arcs leave, so that no remnant of a curve
beside an arc claims the corner's turn again. :func:`kept_to_net_turn` applies the first rule
alone (to a lane's borrowed profile, :mod:`csws.road.sharing`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .corners import ANGLE_TOLERANCE_DEG, corner_arc, curve_runs, cut_at_straights, same_sign_runs
from .coverage import corner_window, halfway_to_neighbours, is_covered, without_curves_at
from .profile import RadiusProfile, profile_from_parts

__all__ = [
    "SPIKE_M",
    "JOG_M",
    "FOLD_M",
    "REVERSAL_DEG",
    "JOG_DEG",
    "ZIGZAG_VERTEX_DEG",
    "ZIGZAG_SUM_DEG",
    "ARTEFACT_NET_DEG",
    "CORNER_VERTEX_DEG",
    "CORNER_SPAN_M",
    "CORNER_MIN_DEG",
    "Artefact",
    "PolylineTurns",
    "Corner",
    "polyline_turns",
    "netted_turns",
    "kept_to_polyline",
    "kept_to_net_turn",
    "turned_back_scale",
]

#: The longest segment between the two reversals of a spike, m.
SPIKE_M = 1.0
#: The longest segment of a jog, m; a vertex next to a segment no longer than this is no corner: netconvert's
#: junction shapes end in stubs of a metre or two whose heading is the junction's, not the road's.
JOG_M = 2.0
#: The longest segment between the two reversals of a junction shape folding back, m.
FOLD_M = 10.0
#: A vertex turning this much or more reverses the polyline, degrees.
REVERSAL_DEG = 120.0
#: Each vertex of a jog turns at least this much, degrees.
JOG_DEG = 20.0
#: Each vertex of a zig-zag turns at least this much, degrees.
ZIGZAG_VERTEX_DEG = 2.0
#: A zig-zag's turns add up to at least this much in absolute value, degrees.
ZIGZAG_SUM_DEG = 20.0
#: A zig-zag's turns net less than this, degrees.
ARTEFACT_NET_DEG = 10.0
#: Each vertex of a corner turns at least this much, degrees.
CORNER_VERTEX_DEG = 10.0
#: A corner's first and last vertex lie at most this far apart, m.
CORNER_SPAN_M = 50.0
#: A corner's vertices turn at least this much together, degrees.
CORNER_MIN_DEG = 20.0


@dataclass(frozen=True)
class Artefact:
    """A map artefact on a polyline: its ``kind`` (spike, fold, jog, zigzag), the arc lengths of
    its first and last vertex (m), and its size: the length of its back-and-forth or jog segment,
    or the absolute turning of a zig-zag in degrees."""

    kind: str
    start_s: float
    end_s: float
    size: float


@dataclass(frozen=True)
class Corner:
    """A corner of a polyline: its first and last vertex's arc length (m), and its net turn (rad, left positive)."""

    start_s: float
    end_s: float
    turn_rad: float


@dataclass(frozen=True)
class PolylineTurns:
    """A polyline read for its turns (repeated vertices dropped).

    Attributes
    ----------
    vertex_s
        Arc length of each vertex, m.
    segment_m
        Length of each segment, m.
    turn_rad
        Each inner vertex's turn, wrapped to (-pi, pi], left positive.
    effective_rad
        Each inner vertex's effective turn: an artefact's net turn at its first vertex, 0 at its others.
    artefacts
        The artefacts found.
    """

    vertex_s: np.ndarray
    segment_m: np.ndarray
    turn_rad: np.ndarray
    effective_rad: np.ndarray
    artefacts: tuple[Artefact, ...]

    def net_turn_rad(self, start_s: float, end_s: float, side: float) -> float:
        """The net turn of the stretch ``[start_s, end_s]`` towards ``side`` (+1 left, -1 right), rad: the effective
        turns of the vertices inside it, and of the nearest one at or beyond either end where that turns ``side``'s
        way (a vertex on an end turns onto the road beyond as much as onto the stretch)."""
        inner_s = self.vertex_s[1:-1]
        first = int(np.searchsorted(inner_s, start_s, side="right"))
        stop = int(np.searchsorted(inner_s, end_s, side="left"))
        beyond = self.effective_rad[[index for index in {first - 1, stop} if 0 <= index < len(inner_s)]]
        return side * float(self.effective_rad[first:stop].sum()) + float(np.clip(side * beyond, 0.0, None).sum())

    def corner_vertices(self, least_deg: float) -> np.ndarray:
        """Whether each inner vertex turns by ``least_deg`` or more (effective turn), with a heading of its own on
        either side: a segment longer than :data:`JOG_M`, or a shorter one continued straight (a next vertex
        turning less than :data:`CORNER_VERTEX_DEG`)."""
        long_enough = self.segment_m > JOG_M
        straight_on = np.abs(self.turn_rad) < math.radians(CORNER_VERTEX_DEG)
        before = long_enough[:-1] | np.concatenate(([False], straight_on[:-1]))
        after = long_enough[1:] | np.concatenate((straight_on[1:], [False]))
        return (np.abs(self.effective_rad) >= math.radians(least_deg)) & before & after

    def arms(self, corner: Corner) -> tuple[tuple[float, float], float, int]:
        """How far the polyline runs before and after a corner to the nearest vertex turning by
        :data:`CORNER_VERTEX_DEG` or more (or its end), m; the length from its first to its last vertex, m;
        and its number of vertices."""
        inner_s = self.vertex_s[1:-1]
        turning_s = inner_s[np.abs(self.effective_rad) >= math.radians(CORNER_VERTEX_DEG)]
        before_s = turning_s[turning_s < corner.start_s]
        after_s = turning_s[turning_s > corner.end_s]
        previous_s = float(before_s[-1]) if len(before_s) else float(self.vertex_s[0])
        next_s = float(after_s[0]) if len(after_s) else float(self.vertex_s[-1])
        first, last = np.searchsorted(inner_s, (corner.start_s, corner.end_s))
        arms_m = (corner.start_s - previous_s, next_s - corner.end_s)
        return arms_m, corner.end_s - corner.start_s, int(last - first) + 1

    def reach(self, corner: Corner) -> tuple[float, float]:
        """The arc length of the vertices before and after a corner (the polyline's ends where it has none), m: a
        curve running into the segments between them counts the corner's turn (:meth:`net_turn_rad`)."""
        before = int(np.searchsorted(self.vertex_s, corner.start_s, side="left")) - 1
        after = int(np.searchsorted(self.vertex_s, corner.end_s, side="right"))
        return float(self.vertex_s[max(before, 0)]), float(self.vertex_s[min(after, len(self.vertex_s) - 1)])

    def corners(self) -> list[Corner]:
        """The corners of the polyline (see the module)."""
        inner_s = self.vertex_s[1:-1]
        side = np.where(self.corner_vertices(CORNER_VERTEX_DEG), np.sign(self.effective_rad), 0)
        found = []
        runs = [piece for run in same_sign_runs(side) for piece in cut_at_straights(*run, inner_s, CORNER_SPAN_M)]
        for first, last in runs:
            turn = float(self.effective_rad[first : last + 1].sum())
            span_m = float(inner_s[last] - inner_s[first])
            if abs(turn) >= math.radians(CORNER_MIN_DEG) and span_m <= CORNER_SPAN_M:
                found.append(Corner(float(inner_s[first]), float(inner_s[last]), turn))
        return found


def _wrapped(angle_rad: np.ndarray | float) -> np.ndarray:
    """Angles wrapped to (-pi, pi]."""
    return -(np.remainder(-np.asarray(angle_rad) + np.pi, 2.0 * np.pi) - np.pi)


def polyline_turns(xy: np.ndarray) -> PolylineTurns:
    """The turns, artefacts and effective turns of a polyline (see the module)."""
    step = np.diff(np.asarray(xy, dtype=float), axis=0)
    length = np.hypot(step[:, 0], step[:, 1])
    step, length = step[length > 0], length[length > 0]
    vertex_s = np.concatenate(([0.0], np.cumsum(length)))
    turn = _wrapped(np.diff(np.arctan2(step[:, 1], step[:, 0]))) if len(step) > 1 else np.zeros(0)
    effective, found = netted_turns(turn, length)
    artefacts = (
        Artefact(kind, float(vertex_s[first + 1]), float(vertex_s[last + 1]), size) for kind, first, last, size in found
    )
    return PolylineTurns(vertex_s, length, turn, effective, tuple(artefacts))


def netted_turns(turn_rad: np.ndarray, segment_m: np.ndarray) -> tuple[np.ndarray, list[tuple[str, int, int, float]]]:
    """The effective turn of each inner vertex of a polyline, and its artefacts (see the module).

    Parameters
    ----------
    turn_rad
        Each inner vertex's turn, wrapped to (-pi, pi], left positive.
    segment_m
        The length of each segment (none of them 0), m.

    Returns
    -------
    effective_rad, artefacts
        Each inner vertex's effective turn (an artefact's net turn at its first vertex, 0 at its others), rad; and
        each artefact's kind, first and last inner vertex and size, in order.
    """
    effective = np.array(turn_rad, dtype=float)
    taken = np.zeros(len(effective), dtype=bool)
    artefacts = []
    for kind, first, last, size in _artefact_vertices(np.asarray(turn_rad), segment_m):
        if taken[first : last + 1].any():
            continue  # a jog inside a zig-zag, a spike next to another: one artefact
        if kind in ("spike", "fold") and not _comes_back(turn_rad[first : last + 1]):
            continue  # two reversals the same way round: a tight loop, whose turn is real, not a back-and-forth
        taken[first : last + 1] = True
        artefacts.append((kind, first, last, size))
        effective[first] = _wrapped(float(turn_rad[first : last + 1].sum()))
        effective[first + 1 : last + 1] = 0.0
    return effective, artefacts


def _comes_back(reversals_rad: np.ndarray) -> bool:
    """Whether two reversals make a back-and-forth: they come back to within 180 - :data:`REVERSAL_DEG` degrees of
    the heading before them (a spike drawn out and back, a shape folded over itself), rather than turning on the
    same way round (two reversals of 120 degrees or more one way sum to 240 or more: wrapped, that would read as
    a turn the other way)."""
    return bool(abs(_wrapped(float(reversals_rad.sum()))) < math.radians(180.0 - REVERSAL_DEG))


def _artefact_vertices(turn: np.ndarray, segment_m: np.ndarray) -> list[tuple[str, int, int, float]]:
    """Kind, first and last inner vertex and size of each artefact (see the module), in order."""
    found = []
    between_m = segment_m[1:-1]  # the segment between inner vertices i and i + 1
    reversal = np.abs(turn) >= math.radians(REVERSAL_DEG)
    for vertex in np.flatnonzero(reversal[:-1] & reversal[1:] & (between_m <= FOLD_M)).tolist():
        kind = "spike" if between_m[vertex] <= SPIKE_M else "fold"
        found.append((kind, vertex, vertex + 1, float(between_m[vertex])))
    jog = (
        (np.abs(turn[:-1]) >= math.radians(JOG_DEG))
        & (np.abs(turn[1:]) >= math.radians(JOG_DEG))
        & (np.sign(turn[:-1]) != np.sign(turn[1:]))
        & (between_m <= JOG_M)
        & ~(reversal[:-1] & reversal[1:])
    )
    found += [("jog", vertex, vertex + 1, float(between_m[vertex])) for vertex in np.flatnonzero(jog).tolist()]
    found += _zigzags(turn)
    return sorted(found, key=lambda item: item[1])


def _zigzags(turn: np.ndarray) -> list[tuple[str, int, int, float]]:
    """The zig-zags among the vertices (see the module): kind, first and last vertex, absolute turning in degrees."""
    strong = np.abs(turn) >= math.radians(ZIGZAG_VERTEX_DEG)
    alternating = strong[:-1] & strong[1:] & (turn[:-1] * turn[1:] < 0)  # vertex i and i + 1 zig and zag
    edges = np.diff(np.concatenate(([0], alternating.astype(np.int8), [0])))
    found = []
    for first, stop in zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist(), strict=True):
        last = stop  # the run of pairs first..stop-1 spans vertices first..stop
        absolute_deg = math.degrees(float(np.abs(turn[first : last + 1]).sum()))
        net_deg = abs(math.degrees(float(turn[first : last + 1].sum())))
        if last - first >= 2 and absolute_deg >= ZIGZAG_SUM_DEG and net_deg < ARTEFACT_NET_DEG:
            found.append(("zigzag", first, last, absolute_deg))
    return found


def kept_to_polyline(xy: np.ndarray, profile: RadiusProfile) -> RadiusProfile:
    """A fitted profile of polyline ``xy`` with no curve beyond the polyline's net turn and every corner a curve.

    A straight fit of a polyline none of whose vertices turns by :data:`CORNER_VERTEX_DEG` (no corner, no
    artefact that turns it) is returned as it is without reading the polyline further, as is any profile the
    rules leave unchanged: most chains of a city are such, and loading it stays fast.
    """
    if not profile.parts:
        return profile
    start_k = np.array([part.curvature for part in profile.parts])
    end_k = np.array([part.final_curvature for part in profile.parts])
    if not (start_k.any() or end_k.any()) and _turns_less_than(xy, math.radians(CORNER_VERTEX_DEG)):
        return profile
    turns = polyline_turns(xy)
    if len(turns.turn_rad) == 0:
        return profile
    bounds = np.array([part.start_s for part in profile.parts] + [profile.parts[-1].end_s])
    fitted = bounds, start_k, end_k
    start_k, end_k = _within_net_turn(turns, bounds, start_k, end_k)
    corners = turns.corners()
    for index, corner in enumerate(corners):
        reach, window = turns.reach(corner), corner_window(turns, corner, halfway_to_neighbours(corners, index))
        if not is_covered(corner, reach, window, bounds, start_k, end_k):
            bounds, start_k, end_k = without_curves_at(corner, reach, window, bounds, start_k, end_k)
            arms_m, inner_m, vertices = turns.arms(corner)
            bounds, start_k, end_k = corner_arc(
                (corner.start_s, corner.end_s, corner.turn_rad), arms_m, inner_m, vertices, bounds, start_k, end_k
            )
    if all(np.array_equal(before, after) for before, after in zip(fitted, (bounds, start_k, end_k), strict=True)):
        return profile
    start_k, end_k = _within_net_turn(turns, bounds, start_k, end_k)
    return profile_from_parts(profile.s, bounds, start_k, end_k)


def kept_to_net_turn(xy: np.ndarray, profile: RadiusProfile) -> RadiusProfile:
    """A profile laid on polyline ``xy`` with no curve, nor part of one, turning more than the polyline's net turn
    over its stretch (the first rule of :func:`kept_to_polyline` alone): a lane that borrows its road's profile
    (:mod:`csws.road.sharing`) keeps only the turn its own polyline makes."""
    start_k = np.array([part.curvature for part in profile.parts])
    end_k = np.array([part.final_curvature for part in profile.parts])
    if not (start_k.any() or end_k.any()):
        return profile
    bounds = np.array([part.start_s for part in profile.parts] + [profile.parts[-1].end_s])
    kept_start_k, kept_end_k = _within_net_turn(polyline_turns(xy), bounds, start_k, end_k)
    if np.array_equal(kept_start_k, start_k) and np.array_equal(kept_end_k, end_k):
        return profile
    return profile_from_parts(profile.s, bounds, kept_start_k, kept_end_k)


def _turns_less_than(xy: np.ndarray, limit_rad: float) -> bool:
    """Whether every vertex of the polyline turns by less than ``limit_rad`` (repeated vertices skipped)."""
    step = np.diff(np.asarray(xy, dtype=float), axis=0)
    step = step[(step[:, 0] != 0) | (step[:, 1] != 0)]
    if len(step) < 2:
        return True
    heading = np.arctan2(step[:, 1], step[:, 0])
    return bool(np.all(np.abs(_wrapped(np.diff(heading))) < limit_rad))


def _within_net_turn(
    turns: PolylineTurns, bounds: np.ndarray, start_k: np.ndarray, end_k: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Curvatures with each curve, then each part of a curve, turned back to its stretch's net turn (removed below
    :data:`ANGLE_TOLERANCE_DEG`)."""
    start_k, end_k = start_k.copy(), end_k.copy()
    angle_rad = (start_k + end_k) / 2.0 * np.diff(bounds)
    runs = curve_runs(start_k, end_k)
    for parts in runs + [part[None] for run in runs if len(run) > 1 for part in run]:
        scale = turned_back_scale(
            turns, float(bounds[parts[0]]), float(bounds[parts[-1] + 1]), float(angle_rad[parts].sum())
        )
        start_k[parts] *= scale
        end_k[parts] *= scale
        angle_rad[parts] *= scale
    return start_k, end_k


def turned_back_scale(turns: PolylineTurns, start_s: float, end_s: float, angle_rad: float) -> float:
    """The factor that keeps a curve turning ``angle_rad`` (left positive) over ``[start_s, end_s]`` to the
    polyline's net turn its way there: 1 where it turns no more than that net turn and :data:`ANGLE_TOLERANCE_DEG`,
    else the net turn over its angle, and 0 (no curve) where the net turn is below the tolerance."""
    tolerance = math.radians(ANGLE_TOLERANCE_DEG)
    net = turns.net_turn_rad(start_s, end_s, math.copysign(1.0, angle_rad))
    if abs(angle_rad) <= net + tolerance:
        return 1.0
    return net / abs(angle_rad) if net >= tolerance else 0.0
