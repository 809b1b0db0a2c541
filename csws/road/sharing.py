"""Gives the lanes of one road the road's curves: fitted once, each lane's radius offset by its distance.

Each lane of an edge is its own road chain (:mod:`csws.road.chains`): it continues into
its own lanes and is stitched on its own shape. Fitted each on its own, the lanes of one
bend disagree where the curve starts by tens of metres (the fit places its knots on each
polyline's own vertices), and with it on V_w: a vehicle matched to the neighbouring lane
would be warned for another curve. A road has one curve, so here:

* each edge (a normal edge, or an internal edge of parallel connections) has a
  **reference lane**: the lane of its edge whose chain runs the longest, so that
  consecutive edges share one reference chain where the road goes on;
* every other lane of the edge lying parallel to it (its shape within
  :data:`PARALLEL_TOLERANCE_M` of one lateral offset) **borrows** the reference's stretch:
  its profile and curves are the reference's, their positions carried over at the same
  SUMO lane position (the lanes of an edge share their lane positions, as SUMO's lane
  changes do) and each radius moved by the lateral offset ``d`` (left positive): a
  signed curvature k becomes ``k / (1 - k d)``, so R - d on the inside of a turn, R + d
  on the outside;
* what a lane borrows keeps to its own polyline's net turn (:func:`kept_to_own_turn`,
  :func:`csws.curvature.artefacts.kept_to_net_turn`): a curve of the reference that runs
  across the joint where the reference lane begins carries the turn the reference chain
  makes there, which a lane beside it entered from elsewhere does not make; a curve that
  lies parallel to its reference all along is kept as moved (:func:`inside_parallel_run`);
* a chain that has no lane of its own is not fitted at all.

Lanes borrowing from one reference chain in order form a **run**: a curve that crosses
their joints stays one curve. A run ends where a chain changes between its own lanes and
borrowed ones, or between reference chains; a curve across such a joint is cut there.

A borrowed curve keeps the name of the curve it was borrowed from: its id is where that curve
starts on its reference lane, as an edge and lane position (:func:`csws.road.chains.road_curve_id`),
and its parts are counted from that curve's first part, so a vehicle that changes lane on one
road is warned of the same curve, part for part.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import shapely

from csws.curvature import ConstantRadiusPart, Curve, ProfilePart, RadiusProfile, profile_along, profile_from_parts
from csws.curvature.artefacts import kept_to_net_turn, polyline_turns, turned_back_scale
from csws.curvature.corners import curve_runs

__all__ = [
    "JOINT_TOLERANCE_M",
    "PARALLEL_TOLERANCE_M",
    "Run",
    "chain_runs",
    "clip_curve",
    "inside_parallel_run",
    "joined_at_run_joints",
    "kept_to_own_turn",
    "lateral_offsets_m",
    "moved_curve",
    "moved_parts",
    "read_profile",
    "reference_lanes",
    "run_at",
]

#: Two consecutive lanes of a path whose joint points are closer than this are joined
#: at one vertex, m. SUMO writes coordinates to the centimetre and makes the lanes of a
#: connection meet exactly; a few-centimetre segment at the joint would otherwise read
#: as a spurious sharp bend.
JOINT_TOLERANCE_M = 0.1
#: A lane shares its edge's reference lane's curves only if its lateral offset from that lane
#: varies by at most this along it, m: lanes of an edge are parallel in SUMO unless given a shape
#: of their own.
PARALLEL_TOLERANCE_M = 0.5
#: A segment within this of a point's nearest (as the spatial index measures) is measured again, m: the
#: index's distances and this module's differ in the last bits, never by this much.
_NEAR_MARGIN_M = 1e-6
#: A lane with at most this many (point, segment) pairs is measured against every segment: cheaper than an
#: index (so is a shape with a coordinate that is not a finite number, which an index leaves out).
_ALL_PAIRS = 4096
#: A curve within this of a run's end counts as reaching it, m (arc lengths of one chain, summed segment by segment).
_RUN_END_M = 1e-6
#: A moved curvature's denominator 1 - k d is never below this: a lane far inside a tight turn
#: (a junction's double turn) keeps a tenth of the reference's radius at least.
_MIN_SCALE = 0.1


def reference_lanes(edge_ids: Sequence[str], lane_index: Sequence[int], chain_length_m: np.ndarray) -> np.ndarray:
    """Each lane's edge's reference lane: the lane of the edge whose chain is the longest
    (``chain_length_m`` per lane), the rightmost of equals."""
    best: dict[str, int] = {}
    for lane, edge in enumerate(edge_ids):
        held = best.get(edge)
        if held is None or (chain_length_m[lane], -lane_index[lane]) > (chain_length_m[held], -lane_index[held]):
            best[edge] = lane
    return np.array([best[edge] for edge in edge_ids], dtype=np.int64)


def _signed_offsets_m(points: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Each point's signed distance across ``reference`` (left positive), measured square to the
    reference's segment nearest it (the first of equals), m."""
    start, end = reference[:-1], reference[1:]
    direction = end - start
    length = np.hypot(direction[:, 0], direction[:, 1])
    keep = length > 0
    start, end, direction, length = start[keep], end[keep], direction[keep], length[keep]
    if not len(length):
        return np.full(len(points), np.nan)
    finite = bool(np.isfinite(points).all() and np.isfinite(reference).all())
    if len(points) * len(start) <= _ALL_PAIRS or not finite:  # every point against every segment
        point = np.arange(len(points))
        segment = np.argmin(_gaps_m(points[:, None, :], start[None], direction[None], length[None]), axis=1)
    else:
        point, candidate = _near_pairs(points, start, end)
        gap = _gaps_m(points[point], start[candidate], direction[candidate], length[candidate])
        order = np.lexsort((candidate, gap, point))
        first = order[np.flatnonzero(np.diff(point[order], prepend=-1))]
        point, segment = point[first], candidate[first]
    relative = points[point] - start[segment]
    cross = direction[segment, 0] * relative[:, 1] - direction[segment, 1] * relative[:, 0]
    offsets = np.full(len(points), np.nan)
    offsets[point] = cross / length[segment]
    return offsets


def _gaps_m(points: np.ndarray, start: np.ndarray, direction: np.ndarray, length: np.ndarray) -> np.ndarray:
    """The distance of each point from its segment (``start``, ``direction``, ``length``; arrays that broadcast,
    coordinates on the last axis), m."""
    relative = points - start
    dot = relative[..., 0] * direction[..., 0] + relative[..., 1] * direction[..., 1]
    along = np.clip(dot / length**2, 0.0, 1.0)
    away = points - (start + along[..., None] * direction)
    return np.hypot(away[..., 0], away[..., 1])


def _near_pairs(points: np.ndarray, start: np.ndarray, end: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The (point, segment) pairs to measure for each point's nearest segment: every segment within its nearest
    one's distance plus :data:`_NEAR_MARGIN_M` (a spatial index's answer, so that a lane of a thousand points is
    not measured against every segment of its reference), by point."""
    tree = shapely.STRtree(shapely.linestrings(np.stack((start, end), axis=1)))
    probes = shapely.points(points)
    (point, _), distance_m = tree.query_nearest(probes, return_distance=True)
    nearest_m = np.full(len(points), np.inf)
    np.minimum.at(nearest_m, point, distance_m)
    point, segment = tree.query(probes, predicate="dwithin", distance=nearest_m + _NEAR_MARGIN_M)
    return point.astype(np.intp), segment.astype(np.intp)


def lateral_offsets_m(road_shapes: Sequence[np.ndarray], reference: np.ndarray) -> np.ndarray:
    """Each lane's lateral offset from its reference lane, m (left positive; 0 for a reference);
    NaN where the lane is not parallel to it (:data:`PARALLEL_TOLERANCE_M`)."""
    offsets = np.zeros(len(road_shapes))
    for lane, ref in enumerate(reference.tolist()):
        if ref == lane:
            continue
        across = _signed_offsets_m(np.asarray(road_shapes[lane], dtype=float), np.asarray(road_shapes[ref]))
        parallel = np.isfinite(across).all() and float(np.ptp(across)) <= PARALLEL_TOLERANCE_M
        offsets[lane] = float(np.median(across)) if parallel else math.nan
    return offsets


@dataclass(frozen=True)
class Run:
    """Consecutive lanes of a chain read from one source chain: their own, or a reference's.

    Attributes
    ----------
    source
        The chain the profile and curves come from.
    source_s, target_s
        The lanes' joints (and the run's two ends) in the source's and in this chain's arc
        length, m: a position maps linearly between them.
    offset_m
        Each lane's lateral offset from the source (0 for its own lanes), m.
    is_own
        Whether the run reads its own chain's own lanes (nothing to move).
    """

    source: int
    source_s: np.ndarray
    target_s: np.ndarray
    offset_m: np.ndarray
    is_own: bool = False

    def to_target(self, s: float) -> float:
        """A source arc length in this chain's arc length, m."""
        return float(np.interp(s, self.source_s, self.target_s))

    def to_source(self, s: float) -> float:
        """An arc length of this chain in the source's arc length, m (the inverse of :meth:`to_target`)."""
        return float(np.interp(s, self.target_s, self.source_s))

    def offset_at(self, source_s: float) -> float:
        """The lateral offset of the lane at source arc length ``source_s``, m."""
        lane = int(np.searchsorted(self.source_s[1:-1], source_s, side="right"))
        return float(self.offset_m[lane])


def run_at(runs: Sequence[Run], s: float) -> Run:
    """The run of a chain (its ``runs``, in order) that arc length ``s`` lies on; on a joint, the run starting there."""
    return runs[max(bisect_right([float(run.target_s[0]) for run in runs], s) - 1, 0)]


def chain_runs(
    members: np.ndarray,
    chain: int,
    reference: np.ndarray,
    offset_m: np.ndarray,
    lane_chain: np.ndarray,
    lane_bounds_s: np.ndarray,
) -> list[Run]:
    """The runs of one chain's lanes (``members``, in driving order).

    ``lane_bounds_s`` is ``(n_lanes, 2)``: each lane's stretch of its chain, from its first
    point to the next lane's (or the chain's end). A lane reads its reference where that is
    another lane it lies parallel to, else itself.
    """
    runs: list[Run] = []
    pending: list[tuple[int, int, float]] = []  # (lane, source lane, offset)
    for lane in members.tolist():
        ref = int(reference[lane])
        source_lane, offset = (
            (ref, float(offset_m[lane])) if ref != lane and math.isfinite(offset_m[lane]) else (lane, 0.0)
        )
        if pending and not _continues(pending[-1][1], source_lane, lane_chain, lane_bounds_s):
            runs.append(_run(pending, chain, lane_chain, lane_bounds_s))
            pending = []
        pending.append((lane, source_lane, offset))
    if pending:
        runs.append(_run(pending, chain, lane_chain, lane_bounds_s))
    return runs


def _continues(previous_source: int, source: int, lane_chain: np.ndarray, lane_bounds_s: np.ndarray) -> bool:
    """Whether ``source`` is the lane after ``previous_source`` on one chain (their stretches meet)."""
    return bool(
        lane_chain[source] == lane_chain[previous_source]
        and lane_bounds_s[source, 0] == lane_bounds_s[previous_source, 1]
    )


def _run(pending: list[tuple[int, int, float]], chain: int, lane_chain: np.ndarray, bounds_s: np.ndarray) -> Run:
    """A run of ``(lane, source lane, offset)`` rows reading one source chain in order."""
    lanes, sources, offsets = zip(*pending, strict=True)
    source_chain = int(lane_chain[sources[0]])
    own = source_chain == chain and list(lanes) == list(sources)
    return Run(
        source_chain,
        np.array([bounds_s[lane, 0] for lane in sources] + [bounds_s[sources[-1], 1]]),
        np.array([bounds_s[lane, 0] for lane in lanes] + [bounds_s[lanes[-1], 1]]),
        np.zeros(len(lanes)) if own else np.array(offsets),
        own,
    )


def clip_curve(curve: Curve, start_s: float, end_s: float, offset_m: float = 0.0) -> Curve | None:
    """The stretch of ``curve`` on ``[start_s, end_s]``, shifted by ``offset_m``; None if it lies outside.

    A path that starts inside a curve or leaves the road in one sees that much of it.
    Each part keeps its radius (a piece of a clothoid cut at the path's start keeps the
    radius of its own start: the nearer the curve's apex, the smaller), and the angle is
    that of the parts kept, length over radius.
    """
    kept = [
        ConstantRadiusPart(
            max(part.start_s, start_s) + offset_m, min(part.end_s, end_s) + offset_m, part.radius_m, part.spiral
        )
        for part in curve.parts
        if part.end_s > start_s and part.start_s < end_s
    ]
    if not kept:
        return None
    if curve.start_s >= start_s and curve.end_s <= end_s:
        return Curve(
            curve.start_s + offset_m,
            curve.end_s + offset_m,
            curve.angle_deg,
            curve.direction,
            curve.min_radius_m,
            tuple(kept),
        )
    return Curve(
        start_s=kept[0].start_s,
        end_s=kept[-1].end_s,
        angle_deg=math.degrees(sum((part.end_s - part.start_s) / part.radius_m for part in kept)),
        direction=curve.direction,
        min_radius_m=min(part.radius_m for part in kept),
        parts=tuple(kept),
    )


def _moved_curvature(curvature: float, offset_m: float) -> float:
    """A signed curvature moved ``offset_m`` to the left: k / (1 - k d)."""
    return curvature / max(1.0 - curvature * offset_m, _MIN_SCALE)


def moved_parts(parts: Sequence[ProfilePart], run: Run) -> list[tuple[float, float, float]]:
    """The source profile's parts on the run, in this chain's arc length: ``(end_s, start k, end k)``."""
    start_s, end_s = float(run.source_s[0]), float(run.source_s[-1])
    moved = []
    for part in parts:
        if part.end_s <= start_s or part.start_s >= end_s:
            continue
        a, b = max(part.start_s, start_s), min(part.end_s, end_s)
        offset = run.offset_at(a)
        k0, k1 = part.curvature_at_one(a), part.curvature_at_one(b)
        moved.append((run.to_target(b), _moved_curvature(k0, offset), _moved_curvature(k1, offset)))
    return moved


def moved_curve(curve: Curve, run: Run) -> Curve | None:
    """The stretch of a source chain's curve on the run (:func:`csws.road.chains.clip_curve`), in this
    chain's arc length with its radii moved by the lanes' offsets; None where it lies outside the run."""
    clipped = clip_curve(curve, float(run.source_s[0]), float(run.source_s[-1]))
    if clipped is None:
        return None
    sign = 1.0 if clipped.direction == "left" else -1.0
    parts = tuple(
        ConstantRadiusPart(
            run.to_target(part.start_s),
            run.to_target(part.end_s),
            abs(1.0 / _moved_curvature(sign / part.radius_m, run.offset_at(part.start_s))),
            part.spiral,
        )
        for part in clipped.parts
    )
    return Curve(
        run.to_target(clipped.start_s),
        run.to_target(clipped.end_s),
        clipped.angle_deg,
        clipped.direction,
        min(part.radius_m for part in parts),
        parts,
    )


def joined_at_run_joints(curves: list[Curve]) -> list[Curve]:
    """Curves in driving order with each pair that meets at a run joint turning the same way made one: the curve
    of a road does not end where a chain switches from its own lanes' fit to a borrowed one (or back), so the
    joint leaves no short fragment of it. Two curves of one fit never meet turning the same way (a curve is a
    maximal stretch), so any that meet, within :data:`JOINT_TOLERANCE_M`, were cut by a joint."""
    joined: list[Curve] = []
    for curve in curves:
        previous = joined[-1] if joined else None
        if (
            previous is not None
            and previous.direction == curve.direction
            and abs(curve.start_s - previous.end_s) <= JOINT_TOLERANCE_M
        ):
            joined[-1] = Curve(
                previous.start_s,
                curve.end_s,
                previous.angle_deg + curve.angle_deg,
                curve.direction,
                min(previous.min_radius_m, curve.min_radius_m),
                previous.parts + curve.parts,
            )
        else:
            joined.append(curve)
    return joined


def read_profile(
    chain: int, xy: np.ndarray, runs: Sequence[Run], fitted: Sequence[RadiusProfile | None]
) -> RadiusProfile:
    """A chain's profile: its own fit where it reads only that, else the fits its runs read, moved onto it."""
    if len(runs) == 1 and runs[0].is_own:
        own = fitted[chain]
        assert own is not None  # a chain reading itself was fitted
        return own
    moved: list[tuple[float, float, float]] = []
    for run in runs:
        source = fitted[run.source]
        assert source is not None  # every source was fitted
        moved += moved_parts(source.parts, run)
    profile = profile_along(xy, moved)
    return _parallel_kept_as_moved(profile, kept_to_net_turn(xy, profile), runs, fitted)


def _parallel_kept_as_moved(
    moved: RadiusProfile, kept: RadiusProfile, runs: Sequence[Run], fitted: Sequence[RadiusProfile | None]
) -> RadiusProfile:
    """``kept`` (the ``moved`` profile turned back to the chain's own net turn, on the same parts) with each curve
    that lies parallel to its source all along (:func:`inside_parallel_run`) as moved, as :func:`kept_to_own_turn`
    keeps the chain's curves."""
    if kept is moved:
        return kept
    bounds = np.array([part.start_s for part in moved.parts] + [moved.parts[-1].end_s])
    start_k = np.array([part.curvature for part in moved.parts])
    end_k = np.array([part.final_curvature for part in moved.parts])
    kept_start_k = np.array([part.curvature for part in kept.parts])
    kept_end_k = np.array([part.final_curvature for part in kept.parts])
    restored = False
    for parts in curve_runs(start_k, end_k):
        if inside_parallel_run(float(bounds[parts[0]]), float(bounds[parts[-1] + 1]), runs, fitted):
            kept_start_k[parts], kept_end_k[parts] = start_k[parts], end_k[parts]
            restored = True
    return profile_from_parts(moved.s, bounds, kept_start_k, kept_end_k) if restored else kept


def kept_to_own_turn(
    curves: Sequence[Curve],
    xy: np.ndarray,
    warning_radius_m: float,
    runs: Sequence[Run] = (),
    fitted: Sequence[RadiusProfile | None] = (),
) -> list[Curve]:
    """Curves a chain borrows, each turned back to the net turn of the chain's own polyline ``xy`` over its stretch
    (:func:`csws.curvature.artefacts.turned_back_scale`: its radii widened, or the curve dropped where that turns
    less than the tolerance, or where its smallest radius so widened exceeds R_c ``warning_radius_m``: 3.4); a
    curve that lies parallel to its source all along (:func:`inside_parallel_run`, by the chain's ``runs`` and the
    ``fitted`` profiles of every chain) is kept as moved.

    A curve of the reference lane that runs across the joint where the reference lane begins (or ends) carries the
    turn the reference chain makes there, into its own lane; a lane beside it entered from elsewhere makes no such
    turn, so a borrowed curve is kept only as far as the lane's own polyline turns, as its own fit would be.
    """
    if not curves:
        return []
    turns = polyline_turns(xy)
    kept = []
    for curve in curves:
        if inside_parallel_run(curve.start_s, curve.end_s, runs, fitted):
            kept.append(curve)
            continue
        side = 1.0 if curve.direction == "left" else -1.0
        scale = turned_back_scale(turns, curve.start_s, curve.end_s, side * math.radians(curve.angle_deg))
        if scale == 1.0:
            kept.append(curve)
        elif scale > 0.0 and curve.min_radius_m / scale <= warning_radius_m:
            kept.append(_widened(curve, scale))
    return kept


def inside_parallel_run(
    start_s: float, end_s: float, runs: Sequence[Run], fitted: Sequence[RadiusProfile | None]
) -> bool:
    """Whether a borrowed curve on ``[start_s, end_s]`` of a chain lies inside one of its ``runs`` that reads
    another chain, and touches no end of the run where that chain (its profile in ``fitted``) goes on.

    Inside such a run every lane lies parallel to the lane it reads (:data:`PARALLEL_TOLERANCE_M`), so it turns as
    its source does, and the curve is its source's, moved. The lane's own polyline would say otherwise only by the
    difference of a few degrees its vertices make: enough to widen a curve that its source's fit turns as far as
    the tolerance allows, so that lanes of one road had one curve at two radii. Where the source goes on beyond
    the run, a curve cut at the run's end carries the turn the source makes there, which the lane need not.
    """
    for run in runs:
        run_start_s, run_end_s = float(run.target_s[0]), float(run.target_s[-1])
        source = fitted[run.source] if not run.is_own else None
        if source is None or not (run_start_s - _RUN_END_M <= start_s and end_s <= run_end_s + _RUN_END_M):
            continue
        goes_on_before = float(run.source_s[0]) > _RUN_END_M
        goes_on_after = float(run.source_s[-1]) < float(source.s[-1]) - _RUN_END_M
        cut_at_start = goes_on_before and start_s <= run_start_s + _RUN_END_M
        cut_at_end = goes_on_after and end_s >= run_end_s - _RUN_END_M
        return not (cut_at_start or cut_at_end)
    return False


def _widened(curve: Curve, scale: float) -> Curve:
    """A curve turning ``scale`` times its angle over the same stretch, each radius divided by ``scale``."""
    parts = tuple(
        ConstantRadiusPart(part.start_s, part.end_s, part.radius_m / scale, part.spiral) for part in curve.parts
    )
    return Curve(
        curve.start_s, curve.end_s, curve.angle_deg * scale, curve.direction, curve.min_radius_m / scale, parts
    )
