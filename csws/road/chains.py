"""Stitches every road of a network into one polyline (a road chain), fitted once, and finds its curves.

A road is a chain of lanes through the nodes where it continues (a way split, a side
road joining, the straight-ahead or priority continuation: :mod:`csws.road.continuations`), each
lane handing on to the lane its road continues on (:attr:`csws.road.network.Lane.continues_into`).
Each chain is stitched into one polyline and fitted once, all chains of a network
together (:func:`csws.curvature.radius_profiles`); its curves (3.3-3.8) are found once. A lane
beside another of its edge borrows that lane's fit instead of its own, so that the lanes of one
road have one curve (:mod:`csws.road.sharing`).
The curve index, the path ahead of a vehicle (the horizon, the CPOIs of the look-ahead,
the warning) all read these fits (:mod:`csws.road.path`): the answer for a point of a road
does not depend on the lane a path starts from or on how far back it was stitched.
"""

from __future__ import annotations

import bisect
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from csws.curvature import Curve, ProfilePart, RadiusProfile, cached_radius_profiles, curves_from_profile
from csws.road.offsets_cache import cached_lateral_offsets_m
from csws.road.sharing import (
    JOINT_TOLERANCE_M,
    Run,
    chain_runs,
    clip_curve,
    joined_at_run_joints,
    kept_to_own_turn,
    moved_curve,
    read_profile,
    reference_lanes,
    run_at,
)
from csws.standard import WarningSpeedPolicy

from .stitching import cut_where_straight, road_chains, stitch

__all__ = [
    "GivenProfile",
    "JOINT_TOLERANCE_M",
    "curve_id_of",
    "LaneCurve",
    "RoadChains",
    "clip_curve",
    "fit_road_chains",
    "index_curves",
    "road_curve_id",
]

#: A borrowed curve's start, mapped back onto the fit it comes from, lies this close to the end of a
#: part of that fit's curve where the borrowing lanes begin at that part's end, m: the run's linear
#: map rounds.
_MAPPED_TOLERANCE_M = 1e-6

#: A chain's profile given whole instead of fitted (the exact κ of a network imported from OpenDRIVE), or None
#: to fit it: called with the chain's lanes in driving order, its stitched polyline, and each of those lanes'
#: start and length along it, m.
GivenProfile = Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], RadiusProfile | None]


def curve_id_of(place_id: str, lane_pos_m: float) -> str:
    """A curve's id, ``PLACE@POS``: where it starts (3.4), an edge (or lane) and the lane position to the metre.

    The warning, the horizon and the curve index name a road's curve by its edge
    (:func:`road_curve_id`): the lanes of an edge share their lane positions, so the id is the
    same on every lane of the road.
    """
    return f"{place_id}@{lane_pos_m:.0f}"


@dataclass(frozen=True)
class LaneCurve:
    """A curve (3.3-3.8) of a road, with its ends as SUMO lane positions.

    Attributes
    ----------
    lane_id, start_pos_m
        The lane and lane position of the curve start (3.4), m.
    end_lane_id, end_pos_m
        The lane and lane position of the curve end (3.5), m: another lane of the same
        road when the curve runs through a node.
    curve
        The curve itself, in arc length along its road chain.
    chain
        The index of the road chain it belongs to.
    curve_id
        The road's curve this is: the same on every lane of the road (:func:`road_curve_id`).
    first_part_index
        The index of its first part among the parts of the road's curve: more than 0 where this
        lane begins inside a curve it borrows from its road (:mod:`csws.road.sharing`).
    """

    lane_id: str
    start_pos_m: float
    end_lane_id: str
    end_pos_m: float
    curve: Curve
    chain: int
    curve_id: str
    first_part_index: int = 0


@dataclass(frozen=True)
class RoadChains:
    """Every road chain of a network, its stitched polyline, its fitted profile and its curves.

    Attributes
    ----------
    lanes
        The lane indices of each chain, in driving order.
    xy
        The stitched polyline of each chain, ``(n, 2)``, m.
    profiles
        The radius profile of each chain: its own fit, or where lanes of it borrow their road's
        (:mod:`csws.road.sharing`), pieced together from the fits they borrow.
    runs
        Each chain's runs (:class:`csws.road.sharing.Run`): where it reads its own fit and where a
        reference chain's.
    fitted
        The own fit of each chain that has one (a chain all of whose lanes borrow has none).
    is_junction
        Whether each chain is a junction manoeuvre (a turn's internal lane, a roundabout lane).
    lane_chain
        The chain of each lane.
    lane_start_s
        Arc length along its chain at each lane's first point, m.
    lane_road_length_m
        Length of each lane's stretch of its chain, m.
    lane_position_factor
        Lane position per metre of each lane's stretch of its chain: SUMO's lane length
        over that length (1 where it has none).
    naming_runs
        Where some chains were given their profile (:data:`GivenProfile`): the runs their lanes would
        borrow their road's curves by, which name those chains' own curves after the road's
        (:meth:`curve_origin`); None where every chain reads its ``runs``.
    """

    lanes: tuple[np.ndarray, ...]
    xy: tuple[np.ndarray, ...]
    profiles: tuple[RadiusProfile, ...]
    runs: tuple[tuple[Run, ...], ...]
    fitted: tuple[RadiusProfile | None, ...]
    is_junction: np.ndarray
    lane_chain: np.ndarray
    lane_start_s: np.ndarray
    lane_road_length_m: np.ndarray
    lane_position_factor: np.ndarray
    _curves: dict[tuple[int, float, int, bool], tuple[WarningSpeedPolicy, list[Curve]]] = field(
        default_factory=dict, repr=False, compare=False
    )
    naming_runs: tuple[tuple[Run, ...], ...] | None = None
    _part_end_s: dict[int, list[float]] = field(default_factory=dict, repr=False, compare=False)

    @cached_property
    def lane_chain_and_start(self) -> tuple[list[int], list[float]]:
        """:attr:`lane_chain` and :attr:`lane_start_s` as plain lists, read lane by lane as a path is cut into runs."""
        return self.lane_chain.tolist(), self.lane_start_s.tolist()

    def profile_parts_between(self, chain: int, start_s: float, end_s: float) -> Sequence[ProfilePart]:
        """The parts of a chain's profile that overlap ``(start_s, end_s)``, in order: found by bisection,
        as a path reads a short stretch of a long chain."""
        parts = self.profiles[chain].parts
        part_end_s = self._part_end_s.get(chain)
        if part_end_s is None:
            part_end_s = self._part_end_s[chain] = [part.end_s for part in parts]
        first = bisect.bisect_right(part_end_s, start_s)
        last = first
        while last < len(parts) and parts[last].start_s < end_s:
            last += 1
        return parts[first:last]

    def curves(self, chain: int, warning_radius_m: float, policy: WarningSpeedPolicy) -> list[Curve]:
        """The curves of one chain for R_c ``warning_radius_m``, clothoids cut by ``policy``, found once and kept.

        A chain that reads only its own fit has the curves of that fit; one whose lanes borrow their
        road's has the curves of the fits it reads, moved onto it run by run (:mod:`csws.road.sharing`).
        """
        runs = self.runs[chain]
        if len(runs) == 1 and runs[0].is_own:
            return self._fitted_curves(chain, warning_radius_m, policy)
        return self._kept(
            (chain, float(warning_radius_m), id(policy), False),
            policy,
            lambda: kept_to_own_turn(
                self._moved_curves(runs, warning_radius_m, policy),
                self.xy[chain],
                warning_radius_m,
                runs,
                self.fitted,
            ),
        )

    def _fitted_curves(self, chain: int, warning_radius_m: float, policy: WarningSpeedPolicy) -> list[Curve]:
        """The curves of a chain's own fit (see :meth:`curves`)."""
        fitted = self.fitted[chain]
        if fitted is None:
            raise RuntimeError(f"road chain {chain} has no fit of its own")
        return self._kept(
            (chain, float(warning_radius_m), id(policy), True),
            policy,
            lambda: curves_from_profile(fitted, warning_radius_m, policy=policy),
        )

    def _moved_curves(self, runs: Sequence[Run], warning_radius_m: float, policy: WarningSpeedPolicy) -> list[Curve]:
        """The curves of the fits a chain's runs read, moved onto the chain, in driving order."""
        moved = (
            moved_curve(curve, run)
            for run in runs
            for curve in self._fitted_curves(run.source, warning_radius_m, policy)
        )
        return joined_at_run_joints([curve for curve in moved if curve is not None])

    def _kept(
        self, key: tuple[int, float, int, bool], policy: WarningSpeedPolicy, find: Callable[[], list[Curve]]
    ) -> list[Curve]:
        """Curves found once per key and kept with the policy, whose id is then not reused."""
        kept = self._curves.get(key)
        if kept is None or kept[0] is not policy:
            kept = self._curves[key] = (policy, find())
        return kept[1]

    def curve_origin(
        self, chain: int, start_s: float, warning_radius_m: float, policy: WarningSpeedPolicy
    ) -> tuple[int, float, int]:
        """Where the curve that starts at ``start_s`` of ``chain`` starts on the fit it is read from: the lane,
        its lane position, and how many parts of that fit's curve lie before ``start_s``.

        A chain's own curve starts where it starts. A curve a chain borrows from its road's reference
        (:mod:`csws.road.sharing`) is the reference's curve: it starts where that one starts, also where
        the borrowing lanes begin inside it, so that every lane of a road names the curve alike. A chain
        given its own profile (:attr:`naming_runs`) names its curves after the reference's curve they
        overlap, the same rule: a lane change keeps the curve.
        """
        if self.naming_runs is not None and self.naming_runs[chain] is not self.runs[chain]:
            named = self._given_origin(chain, start_s, warning_radius_m, policy)
            if named is not None:
                return named
        run = run_at(self.runs[chain], start_s)
        if run.is_own:
            return (*self.lane_position(chain, start_s), 0)
        source_s = run.to_source(start_s)
        for curve in self._fitted_curves(run.source, warning_radius_m, policy):
            if curve.start_s - _MAPPED_TOLERANCE_M <= source_s < curve.end_s:
                before = sum(part.end_s <= source_s + _MAPPED_TOLERANCE_M for part in curve.parts)
                return (*self.lane_position(run.source, curve.start_s), before)
        return (*self.lane_position(run.source, source_s), 0)

    def _given_origin(
        self, chain: int, start_s: float, warning_radius_m: float, policy: WarningSpeedPolicy
    ) -> tuple[int, float, int] | None:
        """The origin (:meth:`curve_origin`) of a curve of a chain given its profile: the start of the reference's
        curve overlapping it most where its lanes' naming run borrows, None where they are the reference.

        The chain's curve is mapped onto the reference by the run's lane joints (a lane's stretch scaled
        linearly, within metres of the true place): the reference's curve it overlaps most is the road's.
        Its parts are numbered from 0, or, where the chain begins inside that curve, from the reference's
        parts before the chain's start.
        """
        assert self.naming_runs is not None
        run = run_at(self.naming_runs[chain], start_s)
        if run.is_own:
            return None
        own = [curve for curve in self.curves(chain, warning_radius_m, policy) if abs(curve.start_s - start_s) < 1e-9]
        end_s = own[0].end_s if own else start_s
        low, high = run.to_source(start_s), run.to_source(end_s)
        source_curves = self._fitted_curves(run.source, warning_radius_m, policy)
        overlaps = [min(high, curve.end_s) - max(low, curve.start_s) for curve in source_curves]
        if not overlaps or max(overlaps) <= 0:
            return None
        curve = source_curves[int(np.argmax(overlaps))]
        before = 0
        if start_s <= JOINT_TOLERANCE_M:
            before = sum(part.end_s <= low + _MAPPED_TOLERANCE_M for part in curve.parts)
        return (*self.lane_position(run.source, curve.start_s), before)

    def lane_at(self, chain: int, s: float, end: bool = False) -> int:
        """The lane of ``chain`` at chain arc length ``s``; on a joint, the lane starting there, or
        with ``end`` the lane ending there (where a curve that ends on the joint lies)."""
        members = self.lanes[chain]
        position = int(np.searchsorted(self.lane_start_s[members], s, side="left" if end else "right")) - 1
        return int(members[min(max(position, 0), len(members) - 1)])

    def lane_position(self, chain: int, s: float, end: bool = False) -> tuple[int, float]:
        """The lane and SUMO lane position of chain arc length ``s`` (``end``: see :meth:`lane_at`)."""
        lane = self.lane_at(chain, s, end)
        return lane, float((s - self.lane_start_s[lane]) * self.lane_position_factor[lane])


def road_curve_id(
    chains: RoadChains,
    edge_ids: Sequence[str],
    chain: int,
    start_s: float,
    warning_radius_m: float,
    policy: WarningSpeedPolicy,
) -> tuple[str, int]:
    """The id of the road's curve that starts at ``start_s`` of ``chain``, and the index of its first part there.

    The id is :func:`curve_id_of` the edge and lane position where the curve starts on the fit it is
    read from (:meth:`RoadChains.curve_origin`): one id for the lanes of a road, so that the release
    rule (:mod:`csws.warning.release`), which holds a warning per curve and part, holds it through a
    lane change. ``edge_ids`` gives each lane's edge.
    """
    lane, lane_pos_m, first_part_index = chains.curve_origin(chain, start_s, warning_radius_m, policy)
    return curve_id_of(edge_ids[lane], lane_pos_m), first_part_index


def fit_road_chains(
    continues_into: np.ndarray,
    road_shapes: Sequence[np.ndarray],
    lane_length_m: np.ndarray,
    is_junction: np.ndarray,
    cache_dir: Path | None = None,
    *,
    edge_ids: Sequence[str] | None = None,
    lane_index: Sequence[int] | None = None,
    given: GivenProfile | None = None,
) -> RoadChains:
    """Group lanes into road chains (:func:`road_chains`), stitch each chain's road shapes
    and fit every chain that has a lane of its own at once (:func:`csws.curvature.radius_profiles`),
    or read the fit from ``cache_dir`` where these chains were fitted before
    (:func:`csws.curvature.cached_radius_profiles`); lanes of one edge share their road's fit
    (:mod:`csws.road.sharing`).

    Parameters
    ----------
    continues_into
        For each lane, the lane its road continues on, -1 for none.
    road_shapes
        The shape each lane gives its road, ``(n, 2)``, m.
    lane_length_m
        SUMO's length of each lane, m: lane positions run from 0 to it.
    is_junction
        Whether each lane is a junction manoeuvre; a chain is one when its lanes are.
    cache_dir
        The folder of fitted profiles; ``None`` fits without a cache.
    edge_ids, lane_index
        Each lane's edge and its index in it; None fits every lane on its own.
    given
        The profile of the chains that have one given (:data:`GivenProfile`): those are not fitted, read
        only their own profile, and name their curves after their road's (:attr:`RoadChains.naming_runs`).
    """
    members = [stretch for chain in road_chains(continues_into) for stretch in cut_where_straight(chain, road_shapes)]
    lane_chain = np.empty(len(road_shapes), dtype=np.int64)
    bounds_s = np.empty((len(road_shapes), 2))
    road_length_m = np.array([np.hypot(*np.diff(shape, axis=0).T).sum() for shape in road_shapes])
    chain_xy = []
    for chain, lanes in enumerate(members):
        xy, start_s = stitch([road_shapes[lane] for lane in lanes.tolist()])
        chain_xy.append(xy)
        lane_chain[lanes] = chain
        bounds_s[lanes, 0] = start_s
        bounds_s[lanes, 1] = np.append(start_s[1:], _arc_length(xy)[-1])
    if edge_ids is None or lane_index is None:
        reference, offset_m = np.arange(len(road_shapes)), np.zeros(len(road_shapes))
    else:
        reference = reference_lanes(edge_ids, lane_index, _chain_lengths(chain_xy)[lane_chain])
        offset_m = cached_lateral_offsets_m(road_shapes, reference, cache_dir)
    runs = tuple(
        tuple(chain_runs(lanes, chain, reference, offset_m, lane_chain, bounds_s))
        for chain, lanes in enumerate(members)
    )
    given_profiles = {}
    if given is not None:
        for chain, lanes in enumerate(members):
            profile = given(lanes, chain_xy[chain], bounds_s[lanes, 0], road_length_m[lanes])
            if profile is not None:
                given_profiles[chain] = profile
    read_runs = tuple(
        (_own_run(chain, given_profiles[chain]),) if chain in given_profiles else chain_runs_
        for chain, chain_runs_ in enumerate(runs)
    )
    fitted = _fit_sources(chain_xy, read_runs, cache_dir, given_profiles)
    return RoadChains(
        lanes=tuple(members),
        xy=tuple(chain_xy),
        profiles=tuple(
            read_profile(chain, chain_xy[chain], chain_runs_, fitted) for chain, chain_runs_ in enumerate(read_runs)
        ),
        runs=read_runs,
        fitted=fitted,
        is_junction=np.array([bool(np.all(is_junction[lanes])) for lanes in members], dtype=bool),
        lane_chain=lane_chain,
        lane_start_s=bounds_s[:, 0].copy(),
        lane_road_length_m=road_length_m,
        lane_position_factor=np.divide(
            lane_length_m, road_length_m, out=np.ones(len(road_length_m)), where=road_length_m > 0
        ),
        naming_runs=runs if given_profiles else None,
    )


def _own_run(chain: int, profile: RadiusProfile) -> Run:
    """The one run of a chain that reads its own profile from end to end."""
    ends = np.array([0.0, float(profile.s[-1])])
    return Run(chain, ends, ends, np.zeros(1), is_own=True)


def _arc_length(xy: np.ndarray) -> np.ndarray:
    """Arc length at each vertex of a polyline, m."""
    return np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))))


def _chain_lengths(chain_xy: Sequence[np.ndarray]) -> np.ndarray:
    """Each chain's length, m."""
    return np.array([_arc_length(xy)[-1] for xy in chain_xy])


def _fit_sources(
    chain_xy: Sequence[np.ndarray],
    runs: Sequence[Sequence[Run]],
    cache_dir: Path | None,
    given: dict[int, RadiusProfile],
) -> tuple[RadiusProfile | None, ...]:
    """The own fit of every chain some run reads (its own lanes, or lanes borrowing from it), None for the others,
    kept to its polyline's net turn and corners (:func:`csws.curvature.artefacts.kept_to_polyline`: map artefacts
    are no curves, corners are), and kept so on disk; a chain whose profile is ``given`` has that, unfitted."""
    sources = sorted({run.source for chain_runs_ in runs for run in chain_runs_} - given.keys())
    fits = cached_radius_profiles([chain_xy[chain] for chain in sources], cache_dir, kept_to_polylines=True)
    fitted: list[RadiusProfile | None] = [None] * len(chain_xy)
    for chain, fit in zip(sources, fits, strict=True):
        fitted[chain] = fit
    for chain, profile in given.items():
        fitted[chain] = profile
    return tuple(fitted)


def index_curves(
    chains: RoadChains,
    lane_ids: Sequence[str],
    edge_ids: Sequence[str],
    warning_radius_m: float,
    policy: WarningSpeedPolicy,
) -> list[list[LaneCurve]]:
    """The curves of every chain with their ends as lane positions and the road's curve id
    (:func:`road_curve_id`): the curve index, chain by chain."""
    index = []
    for chain in range(len(chains.lanes)):
        lane_curves = []
        for curve in chains.curves(chain, warning_radius_m, policy):
            start_lane, start_pos_m = chains.lane_position(chain, curve.start_s)
            end_lane, end_pos_m = chains.lane_position(chain, curve.end_s, end=True)
            name = road_curve_id(chains, edge_ids, chain, curve.start_s, warning_radius_m, policy)
            ends = (lane_ids[start_lane], start_pos_m, lane_ids[end_lane], end_pos_m)
            lane_curves.append(LaneCurve(*ends, curve, chain, *name))
        index.append(lane_curves)
    return index
