"""Finds the path ahead of vehicles and its curvature points of interest within S_LAD (3.9, 3.11).

From a lane and a position along it, :class:`LookAhead` follows the road for the
look-ahead distance S_LAD and returns the CPOIs on that stretch: the first point of
every constant-radius part of every curve (3.3-3.8) closer than S_LAD, with its
distance from the vehicle along the path.

Which way the path goes:

* with a route (SUMO: the vehicle's edges; HTTP: a list of edge ids) it follows the
  route, through the junctions' internal lanes; where the route ends or leaves the
  network, the path ends. The route is taken from the first time it passes the
  vehicle's edge: a route that passes an edge twice should be given from the vehicle's
  position on (SUMO's route index tells where that is);
* without one it follows the most probable path: at each junction a successor whose way
  on keeps to the road, the road's continuation (:mod:`csws.road.continuations`), over the
  path's reach, so that at a lane split the path goes on with the road rather than into the
  lane that leads off it onto a ramp further on; then the road's continuation through the
  junction, then the one on an edge with the same street name, then the same road type, then
  the smallest change of heading (:mod:`csws.ahead.successors`). Such a path is marked ``predicted``.

A path reads the profiles and curves of the road chains it runs along, each fitted once
for the whole map (:mod:`csws.road.chains`), so a curve that runs across an edge boundary
or a node is one curve, the one the curve index lists. Junction manoeuvres, a turn from
one road into another at a junction or a drive round a roundabout, are not curves of the
road and offer no CPOI unless :attr:`LookAheadSettings.warn_at_junctions` is set
(:meth:`csws.road.path.PathProfile.road_curves`): the driver takes them at junction
speed, and a warning at every turn would teach the driver to ignore the system. Paths
recur, from one step to the next and from one vehicle to another, so their curves are
kept in a bounded cache
and a query costs a walk over the lanes ahead and a look-up.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import pairwise

import numpy as np

from csws.ahead.horizon import (
    BatchAhead,
    Horizon,
    PartPool,
    PathAhead,
    is_cpoi,
    radius_at_end,
    radius_under,
)
from csws.ahead.successors import SuccessorChoice
from csws.curvature import Curve
from csws.road.path import PathProfile
from csws.road.roadmap import Lane, RoadMap
from csws.standard import DEFAULT_WARNING_RADIUS_M, Category, formula_1_m, kmh_to_mps
from csws.warning.rules import PathKind, WarningSettings, column_index

__all__ = [
    "LookAheadSettings",
    "LookAhead",
    "lookahead_distances_m",
]


@dataclass(frozen=True)
class LookAheadSettings:
    """How far ahead to look and what counts as a curve.

    Attributes
    ----------
    floor_m
        S_LAD is never shorter than this, m.
    fixed_distance_m
        A fixed S_LAD in metres instead of the speed-dependent one; None for the default.
    context_m
        Road profiled beyond S_LAD so that a curve near the horizon is seen whole, m.
    warning_radius_m
        The warning curvature radius R_c (3.2), m.
    cache_size
        How many stitched paths to keep at least (a batch of more vehicles raises it to
        :data:`HORIZONS_PER_VEHICLE` per vehicle).
    max_lanes
        A path never has more lanes than this (guards against loops of tiny lanes).
    warn_at_junctions
        Offer the CPOIs of junction manoeuvres too (turns on internal lanes,
        roundabouts); by default only the curves of the road are offered.
    """

    floor_m: float = 250.0
    fixed_distance_m: float | None = None
    context_m: float = 50.0
    warning_radius_m: float = DEFAULT_WARNING_RADIUS_M
    cache_size: int = 4096
    max_lanes: int = 200
    warn_at_junctions: bool = False

    def __post_init__(self) -> None:
        for name in ("floor_m", "context_m", "warning_radius_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be a non-negative number of metres, got {value!r}")
        if self.fixed_distance_m is not None and not (
            math.isfinite(self.fixed_distance_m) and self.fixed_distance_m > 0
        ):
            raise ValueError(f"fixed_distance_m must be a positive number of metres, got {self.fixed_distance_m!r}")


def lookahead_distances_m(
    speed_kmh,
    warning_settings: WarningSettings = WarningSettings(),
    floor_m: float = LookAheadSettings.floor_m,
    update_period_s=None,
    age_s=0.0,
):
    """The look-ahead distance S_LAD (3.9) each vehicle needs at its speed, m (a float or an array).

    Long enough for the largest warning distance its speed can need (formula (1) with
    V_w = 0, plus the distance driven during the latency: each vehicle's own update period
    and fix age where given, as the warning allows for them); never below ``floor_m``.
    With V_w = 0 because below the table radii the warning speed falls with the radius, so
    no positive speed bounds it.
    """
    speed_mps = kmh_to_mps(speed_kmh if isinstance(speed_kmh, float) else np.asarray(speed_kmh, dtype=float))
    allowance_m = warning_settings.allowance_m(speed_mps, update_period_s, age_s)
    required_m = formula_1_m(speed_mps, 0.0, warning_settings.g_mps2) + allowance_m
    return max(floor_m, required_m) if isinstance(required_m, float) else np.maximum(floor_m, required_m)


#: Horizons are built for S_LAD rounded up to a multiple of this, so that they are shared, m.
HORIZON_STEP_M = 250.0
#: A batch of vehicles keeps at least this many horizons per vehicle cached: the one each
#: vehicle needs now, and the one it needs after its next lane change or junction.
HORIZONS_PER_VEHICLE = 2
#: The part pool is emptied when it holds this many horizons per cached one (those evicted from
#: the caches stay in the pool until then, so this bounds what evicted horizons keep alive).
POOLED_PER_CACHED = 1.25
#: A path's stretch of a curve that starts on a part's end (the path starts there) starts within this of it
#: once carried back into its road chain's arc length, m.
_CUT_TOLERANCE_M = 1e-6


class LookAhead:
    """Finds the path ahead of vehicles on one road map (3.9, 3.11).

    Parameters
    ----------
    road_map
        The map.
    settings
        Look-ahead distance, R_c and cache size.
    warning_settings
        Policy and latency, which set the speed-dependent S_LAD.
    """

    def __init__(
        self,
        road_map: RoadMap,
        settings: LookAheadSettings = LookAheadSettings(),
        warning_settings: WarningSettings = WarningSettings(),
    ) -> None:
        self.road_map = road_map
        self.settings = settings
        self.warning_settings = warning_settings
        self._horizons: OrderedDict[tuple, Horizon] = OrderedDict()
        self._by_lanes: OrderedDict[tuple, Horizon] = OrderedDict()
        self._by_query: dict[tuple, int] = {}
        self._pool = PartPool()
        self._successors = SuccessorChoice(road_map, _successor_reach_m(settings), settings.max_lanes)
        self._capacity = settings.cache_size

    def __call__(
        self,
        lane_id: str,
        lane_pos_m: float,
        speed_kmh: float,
        category: str | Category,
        route_edges: Sequence[str] | None = None,
        update_period_s: float | None = None,
        age_s: float = 0.0,
    ) -> PathAhead:
        """The path ahead of a vehicle at ``lane_pos_m`` on ``lane_id`` and its CPOIs, as far as
        S_LAD at its speed, update period and fix age (the configured period where None).

        Raises
        ------
        KeyError
            If ``lane_id`` is not a lane of the map.
        """
        column_index(category)  # an unknown category is refused, whatever S_LAD it would need
        lookahead_m = self.lookahead_m(float(speed_kmh), update_period_s, age_s)
        horizon = self.horizon(lane_id, route_edges, lookahead_m)
        return PathAhead(horizon, horizon.vehicle_s(float(lane_pos_m)), lookahead_m)

    def many(
        self,
        lane_ids: Sequence[str],
        lane_pos_m: np.ndarray,
        speed_kmh: np.ndarray,
        routes: Sequence[Sequence[str] | None],
        update_period_s: np.ndarray | None = None,
        age_s: np.ndarray | float = 0.0,
    ) -> BatchAhead:
        """The roads ahead of many vehicles and all their CPOIs, selected in one vectorised step
        (S_LAD from each one's speed, update period and fix age; the configured period where None).

        Raises
        ------
        KeyError
            If a lane id is not a lane of the map.
        """
        lookahead_m = self.lookahead_m(np.asarray(speed_kmh, dtype=float), update_period_s, age_s)
        # A fleet larger than the cache would evict at every step what the next step needs again.
        self._capacity = max(self._capacity, HORIZONS_PER_VEHICLE * len(lane_ids))
        slots = self._horizon_slots(lane_ids, routes, lookahead_m)
        pool = self._pool
        pool.join()
        horizons = [pool.horizons[slot] for slot in slots.tolist()]
        vehicle_s = np.clip(
            np.asarray(lane_pos_m, dtype=float) / pool.position_factor[slots], 0.0, pool.shape_length_m[slots]
        )
        # Every (vehicle, part of its horizon) pair, then the pairs that are CPOIs.
        per_vehicle = pool.count[slots]
        vehicle = np.repeat(np.arange(len(horizons)), per_vehicle)
        part = np.arange(per_vehicle.sum()) - np.repeat(np.cumsum(per_vehicle) - per_vehicle, per_vehicle)
        part += np.repeat(pool.first[slots], per_vehicle)
        start, end, radius, index, curve, end_radius = pool.parts
        s = vehicle_s[vehicle]
        keep = is_cpoi(start[part], end[part], s, lookahead_m[vehicle])
        vehicle, part, s = vehicle[keep], part[keep], s[keep]
        return BatchAhead(
            horizons=horizons,
            vehicle_s=vehicle_s,
            lookahead_m=lookahead_m,
            cpoi_vehicle=vehicle,
            cpoi_distance_m=np.maximum(start[part] - s, 0.0),
            cpoi_radius_m=radius_under(start[part], end[part], radius[part], end_radius[part], s),
            cpoi_part_index=index[part].astype(np.intp),
            cpoi_curve_id=curve[part],
            cpoi_passed=end[part] <= s,
        )

    def _horizon_slots(
        self, lane_ids: Sequence[str], routes: Sequence[Sequence[str] | None], lookahead_m: np.ndarray
    ) -> np.ndarray:
        """The slot in the part pool of each vehicle's horizon.

        A (lane, route, reach) query remembers its slot, so that vehicles keeping their
        route objects from step to step (the co-simulation's) find it with one look-up.
        """
        if len(self._pool.horizons) > POOLED_PER_CACHED * self._capacity:
            self._pool.clear()
            self._by_query.clear()
        by_query, slots = self._by_query, []
        reaches_m = _reach_m(lookahead_m, self.settings.context_m).tolist()
        for lane_id, route, reach_m, lad_m in zip(lane_ids, routes, reaches_m, lookahead_m.tolist(), strict=False):
            key = (lane_id, route if route is None or isinstance(route, tuple) else tuple(route), reach_m)
            slot = by_query.get(key)
            if slot is None:
                if len(by_query) >= self._capacity:
                    by_query.clear()
                slot = by_query[key] = self._pool.slot(self.horizon(lane_id, route, lad_m))
            slots.append(slot)
        return np.array(slots, dtype=np.intp)

    def lookahead_m(self, speed_kmh, update_period_s=None, age_s=0.0):
        """S_LAD of a vehicle (a float) or of each of many (an array): the fixed distance if one is set,
        else the one its speed, update period and fix age need (:func:`lookahead_distances_m`), m."""
        fixed_m = self.settings.fixed_distance_m
        if fixed_m is not None:
            return fixed_m if isinstance(speed_kmh, float) else np.full(np.shape(speed_kmh), fixed_m)
        return lookahead_distances_m(speed_kmh, self.warning_settings, self.settings.floor_m, update_period_s, age_s)

    def horizon(self, lane_id: str, route_edges: Sequence[str] | None, lookahead_m: float) -> Horizon:
        """The road ahead from the start of ``lane_id`` long enough for ``lookahead_m`` anywhere on it (cached).

        Raises
        ------
        KeyError
            If ``lane_id`` is not a lane of the map.
        """
        reach_m = float(_reach_m(lookahead_m, self.settings.context_m))
        lane = self.road_map.lane(lane_id)
        remaining = _remaining_route(route_edges, lane)
        key = (lane_id, remaining, reach_m)
        cached = self._horizons.get(key)
        if cached is not None:
            self._horizons.move_to_end(key)
            return cached
        lanes, kind = self.lanes_ahead(lane_id, lane.length_m, lane.length_m + reach_m, remaining)
        # Vehicles on different routes share a horizon while their lanes ahead are the same.
        horizon = self._by_lanes.get((lanes, kind))
        if horizon is not None:
            self._by_lanes.move_to_end((lanes, kind))
        else:
            horizon = _remember(self._by_lanes, (lanes, kind), self._build_horizon(lanes, kind), self._capacity)
        return _remember(self._horizons, key, horizon, self._capacity)

    def lanes_ahead(
        self, lane_id: str, remaining_m: float, needed_m: float, route_edges: Sequence[str] | None
    ) -> tuple[tuple[str, ...], PathKind]:
        """Lanes from ``lane_id`` on (``remaining_m`` of it ahead) until ``needed_m`` is covered, and the path kind:
        along the route, else the most probable path (:class:`csws.ahead.successors.SuccessorChoice`)."""
        route_next = _route_successors(route_edges, self.road_map.lane(lane_id))
        kind = PathKind.ROUTE if route_next is not None else PathKind.PREDICTED
        lanes = [lane_id]
        while remaining_m < needed_m and len(lanes) < self.settings.max_lanes:
            following = self._successors.following(lanes[-1], route_next)
            if following is None:
                break
            lanes.append(following)
            remaining_m += self.road_map.lane(following).length_m
        return tuple(lanes), kind

    def _build_horizon(self, lanes: tuple[str, ...], kind: PathKind) -> Horizon:
        """The stitched, profiled path of ``lanes`` and the parts of its curves (junction manoeuvres aside)."""
        path = self.road_map.path_profile(lanes)
        starts, ends, radii, end_radii, indices, ids = [], [], [], [], [], []
        warning_radius_m = self.settings.warning_radius_m
        for curve, chain, whole in path.curve_sources(warning_radius_m, self.settings.warn_at_junctions):
            curve_id, first_index = self.road_map.curve_id(chain, whole.start_s, warning_radius_m)
            first_index += _parts_cut_off(path, curve, chain, whole)
            for index, part in enumerate(curve.parts, start=first_index):
                starts.append(part.start_s)
                ends.append(part.end_s)
                radii.append(part.radius_m)
                end_radii.append(radius_at_end(path.profile, part.end_s) if part.spiral else part.radius_m)
                indices.append(index)
                ids.append(curve_id)
        return Horizon(
            path=path,
            kind=kind,
            part_start_s=np.array(starts, dtype=float),
            part_end_s=np.array(ends, dtype=float),
            part_radius_m=np.array(radii, dtype=float),
            part_index=np.array(indices, dtype=np.intp),
            part_curve_id=np.array(ids, dtype=object),
            part_end_radius_m=np.array(end_radii, dtype=float),
        )


def _parts_cut_off(path: PathProfile, curve: Curve, chain: int, whole: Curve) -> int:
    """How many parts of a chain's curve ``whole`` lie before the stretch ``curve`` of it a path sees (a path that
    starts inside the curve sees the rest of it), so that a part keeps its index wherever a path starts."""
    runs = np.flatnonzero((path.run_chain == chain) & (path.run_path_start_s <= curve.start_s + _CUT_TOLERANCE_M))
    if not len(runs):
        return 0
    run = int(runs[-1])
    chain_start_s = curve.start_s - float(path.run_path_start_s[run] - path.run_chain_start_s[run])
    return sum(part.end_s <= chain_start_s + _CUT_TOLERANCE_M for part in whole.parts)


def _successor_reach_m(settings: LookAheadSettings) -> float:
    """How far a successor's way on is followed to choose the lane a path goes on to: the S_LAD floor (or the fixed
    S_LAD) and the context profiled beyond it, the stretch a warning looks along at most speeds, m."""
    return max(settings.floor_m, settings.fixed_distance_m or 0.0) + settings.context_m


def _remember(cache: OrderedDict, key: tuple, horizon: Horizon, capacity: int) -> Horizon:
    """Keep ``horizon`` as the newest entry of an LRU cache of ``capacity`` entries."""
    cache[key] = horizon
    if len(cache) > capacity:
        cache.popitem(last=False)
    return horizon


def _reach_m(lookahead_m, context_m: float):
    """How far a horizon reaches beyond its first lane for S_LAD ``lookahead_m``: S_LAD plus the context,
    rounded up to a multiple of :data:`HORIZON_STEP_M` so that horizons are shared, m (floats or arrays, the
    same to the bit: the multiple is a whole number, exact in a float)."""
    if isinstance(lookahead_m, float) and math.isfinite(lookahead_m):
        return math.ceil((lookahead_m + context_m) / HORIZON_STEP_M) * HORIZON_STEP_M
    return np.ceil((np.asarray(lookahead_m, dtype=float) + context_m) / HORIZON_STEP_M) * HORIZON_STEP_M


def _remaining_route(route_edges: Sequence[str] | None, lane: Lane) -> tuple[str, ...] | None:
    """The part of the route still ahead of a vehicle on ``lane``: from the lane's edge on.

    Vehicles whose routes differ only in the edges already driven share their horizons.
    None without a route, or when the vehicle's (normal) edge is not on it (the path is
    then predicted); inside a junction (an internal lane) the whole route.
    """
    if not route_edges:
        return None
    if lane.is_internal:
        return tuple(route_edges)
    try:
        return tuple(route_edges[list(route_edges).index(lane.edge_id) :])
    except ValueError:
        return None


def _route_successors(route_edges: Sequence[str] | None, lane: Lane) -> dict[str, str] | None:
    """``edge -> next edge`` along the route from the vehicle's edge on.

    None when there is no route or the vehicle's (normal) edge is not on it: the path is
    then predicted. Inside a junction (an internal lane) the whole route applies.
    """
    if not route_edges:
        return None
    if lane.is_internal:
        start = 0
    elif lane.edge_id in route_edges:
        start = list(route_edges).index(lane.edge_id)
    else:
        return None
    following: dict[str, str] = {}
    for edge, next_edge in pairwise(route_edges[start:]):
        following.setdefault(edge, next_edge)
    return following
