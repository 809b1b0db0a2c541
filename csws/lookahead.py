"""The path ahead of a vehicle and its curvature points of interest (3.9, 3.11).

From a lane and a position along it, :class:`LookAhead` follows the road for the
look-ahead distance S_LAD and returns the CPOIs on that stretch: the first point of
every constant-radius part of every curve (3.3-3.8) closer than S_LAD, with its
distance from the vehicle along the path.

Which way the path goes:

* with a route (SUMO: the vehicle's edges; HTTP: a list of edge ids) it follows the
  route, through the junctions' internal lanes; where the route ends or leaves the
  network, the path ends;
* without one it follows the most probable path: at each junction the successor
  that keeps the road, i.e. the one on an edge with the same street name, then the
  same road type, then the smallest change of heading. Such a path is marked
  ``predicted``.

The lanes of a path are stitched and profiled as one polyline (so a curve that runs
across an edge boundary is one curve). Junction manoeuvres, a turn inside a junction
or a drive round a roundabout, are not curves of the road and offer no CPOI unless
:attr:`LookAheadSettings.warn_at_junctions` is set
(:meth:`csws.roadmap.PathProfile.road_curves`): the driver takes them at junction
speed, and a warning at every turn would teach the driver to ignore the system. Paths recur, from one step to the next and
from one vehicle to another, so their profiles and curves are kept in a bounded cache
and a query costs a walk over the lanes ahead and a look-up.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .roadmap import Lane, PathProfile, RoadMap
from .standard import DEFAULT_WARNING_RADIUS_M, Category, Level, kmh_to_mps, warning_distance_m
from .warning import CurvaturePointOfInterest, PathKind, WarningSettings

__all__ = ["LookAheadSettings", "PathAhead", "LookAhead", "lookahead_distance_m"]


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
        How many stitched paths to keep.
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
        if self.fixed_distance_m is not None and not (math.isfinite(self.fixed_distance_m) and self.fixed_distance_m > 0):
            raise ValueError(f"fixed_distance_m must be a positive number of metres, got {self.fixed_distance_m!r}")


def lookahead_distance_m(
    speed_kmh: float,
    category: "str | Category",
    warning_settings: WarningSettings = WarningSettings(),
    floor_m: float = LookAheadSettings.floor_m,
) -> float:
    """The look-ahead distance S_LAD (3.9) a vehicle needs at ``speed_kmh``.

    Long enough for the largest warning distance the speed can need: formula (1) with
    the smallest warning speed of the category's column, plus the distance driven during
    the system latency; never below ``floor_m``.
    """
    column = Category.parse(category).column
    smallest_kmh = min(warning_settings.policy.speeds_kmh[(column, Level.LEVEL_1)])
    speed_mps = kmh_to_mps(speed_kmh)
    needed_m = float(warning_distance_m(speed_mps, kmh_to_mps(smallest_kmh), warning_settings.g_mps2))
    return max(floor_m, needed_m + speed_mps * warning_settings.latency_s)


@dataclass(frozen=True)
class _PathCurves:
    """A stitched path with its curve parts as flat arrays (what a query needs)."""

    path: PathProfile
    part_start_s: np.ndarray
    part_end_s: np.ndarray
    part_radius_m: np.ndarray
    part_index: np.ndarray
    part_curve_id: tuple[str, ...]


@dataclass(frozen=True)
class PathAhead:
    """The road ahead of one vehicle and the CPOIs on it.

    Attributes
    ----------
    path
        The stitched path (lanes in driving order, polyline, radius profile).
    kind
        ``route`` when the path follows the vehicle's route, else ``predicted``.
    vehicle_s
        The vehicle's arc length along ``path``, m.
    lookahead_m
        S_LAD used, m.
    cpoi_distance_m, cpoi_radius_m, cpoi_part_index, cpoi_curve_id
        The CPOIs, nearest first: distance S from the vehicle (0 inside a part), radius,
        part index within its curve, and the curve's id (``lane@position`` of its start).
    """

    path: PathProfile
    kind: PathKind
    vehicle_s: float
    lookahead_m: float
    cpoi_distance_m: np.ndarray
    cpoi_radius_m: np.ndarray
    cpoi_part_index: np.ndarray
    cpoi_curve_id: tuple[str, ...]

    @property
    def cpois(self) -> tuple[CurvaturePointOfInterest, ...]:
        """The CPOIs as objects, nearest first."""
        return tuple(
            CurvaturePointOfInterest(curve_id, int(part), float(distance), float(radius))
            for curve_id, part, distance, radius in zip(
                self.cpoi_curve_id, self.cpoi_part_index, self.cpoi_distance_m, self.cpoi_radius_m
            )
        )


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
        self._paths: OrderedDict[tuple[str, ...], _PathCurves] = OrderedDict()

    def __call__(
        self,
        lane_id: str,
        lane_pos_m: float,
        speed_kmh: float,
        category: "str | Category",
        route_edges: Sequence[str] | None = None,
    ) -> PathAhead:
        """The path ahead of a vehicle at ``lane_pos_m`` on ``lane_id`` and its CPOIs.

        Raises
        ------
        KeyError
            If ``lane_id`` is not a lane of the map.
        """
        lookahead_m = self._lookahead_m(speed_kmh, category)
        lane = self.road_map.lane(lane_id)
        lane_pos_m = min(max(float(lane_pos_m), 0.0), lane.length_m)
        lanes, kind = self._lanes_ahead(lane_id, lane.length_m - lane_pos_m, lookahead_m, route_edges)
        curves = self._path_curves(lanes)
        vehicle_s = curves.path.path_s(lane_id, lane_pos_m)
        ahead = (curves.part_end_s > vehicle_s) & (curves.part_start_s < vehicle_s + lookahead_m)
        selected = np.flatnonzero(ahead)
        return PathAhead(
            path=curves.path,
            kind=kind,
            vehicle_s=vehicle_s,
            lookahead_m=lookahead_m,
            cpoi_distance_m=np.maximum(curves.part_start_s[selected] - vehicle_s, 0.0),
            cpoi_radius_m=curves.part_radius_m[selected],
            cpoi_part_index=curves.part_index[selected],
            cpoi_curve_id=tuple(curves.part_curve_id[i] for i in selected),
        )

    def _lookahead_m(self, speed_kmh: float, category: "str | Category") -> float:
        """S_LAD: the fixed distance if one is set, else the speed-dependent one."""
        if self.settings.fixed_distance_m is not None:
            return self.settings.fixed_distance_m
        return lookahead_distance_m(speed_kmh, category, self.warning_settings, self.settings.floor_m)

    def _lanes_ahead(
        self, lane_id: str, remaining_m: float, lookahead_m: float, route_edges: Sequence[str] | None
    ) -> tuple[tuple[str, ...], PathKind]:
        """Lanes from ``lane_id`` on until S_LAD plus the context is covered, and the path kind."""
        route_next = _route_successors(route_edges, self.road_map.lane(lane_id))
        kind = PathKind.ROUTE if route_next is not None else PathKind.PREDICTED
        lanes = [lane_id]
        needed_m = lookahead_m + self.settings.context_m
        while remaining_m < needed_m and len(lanes) < self.settings.max_lanes:
            following = self._following_lane(lanes[-1], route_next)
            if following is None:
                break
            lanes.append(following)
            remaining_m += self.road_map.lane(following).length_m
        return tuple(lanes), kind

    def _following_lane(self, lane_id: str, route_next: dict[str, str] | None) -> str | None:
        """The lane after ``lane_id``: along the route if there is one, else the most probable."""
        successors = self.road_map.successors(lane_id)
        if not successors:
            return None
        lane = self.road_map.lane(lane_id)
        if route_next is None:
            return self._predicted_successor(lane_id, successors)
        if lane.is_internal:
            return successors[0] if len(successors) == 1 else self._predicted_successor(lane_id, successors)
        next_edge = route_next.get(lane.edge_id)
        if next_edge is None:
            return None
        leading = [s for s in successors if self._leads_to_edge(s, next_edge)]
        return self._predicted_successor(lane_id, leading) if leading else None

    def _leads_to_edge(self, lane_id: str, edge_id: str) -> bool:
        """Whether ``lane_id`` is on ``edge_id`` or is an internal lane whose chain ends on it."""
        for _ in range(self.settings.max_lanes):
            lane = self.road_map.lane(lane_id)
            if not lane.is_internal:
                return lane.edge_id == edge_id
            successors = self.road_map.successors(lane_id)
            if len(successors) != 1:
                return False
            lane_id = successors[0]
        return False

    def _predicted_successor(self, lane_id: str, successors: Sequence[str]) -> str:
        """The successor that keeps the road: same street name, then road type, then least turning."""
        if len(successors) == 1:
            return successors[0]
        current = self.road_map.lane(lane_id)
        heading_out = _end_heading(self.road_map.lane_shape(lane_id))

        def preference(candidate: str) -> tuple[bool, bool, float]:
            destination = self.road_map.lane(self._destination(candidate))
            turning = abs(_wrap(_start_heading(self.road_map.lane_shape(candidate)) - heading_out))
            return (
                not (current.street_name and destination.street_name == current.street_name),
                not (current.road_type and destination.road_type == current.road_type),
                turning,
            )

        return min(successors, key=preference)

    def _destination(self, lane_id: str) -> str:
        """The first normal lane reached from ``lane_id`` (itself when it is normal)."""
        for _ in range(self.settings.max_lanes):
            if not self.road_map.lane(lane_id).is_internal:
                return lane_id
            successors = self.road_map.successors(lane_id)
            if not successors:
                return lane_id
            lane_id = successors[0]
        return lane_id

    def _path_curves(self, lanes: tuple[str, ...]) -> _PathCurves:
        """The stitched, profiled path of ``lanes`` and its curve parts, cached."""
        cached = self._paths.get(lanes)
        if cached is not None:
            self._paths.move_to_end(lanes)
            return cached
        path = self.road_map.path_profile(lanes)
        starts, ends, radii, indices, ids = [], [], [], [], []
        curves_of_path = path.curves if self.settings.warn_at_junctions else path.road_curves
        for curve in curves_of_path(self.settings.warning_radius_m):
            start_lane, start_pos_m = path.lane_position(curve.start_s)
            curve_id = f"{start_lane}@{start_pos_m:.0f}"
            for index, part in enumerate(curve.parts):
                starts.append(part.start_s)
                ends.append(part.end_s)
                radii.append(part.radius_m)
                indices.append(index)
                ids.append(curve_id)
        curves = _PathCurves(
            path=path,
            part_start_s=np.array(starts, dtype=float),
            part_end_s=np.array(ends, dtype=float),
            part_radius_m=np.array(radii, dtype=float),
            part_index=np.array(indices, dtype=np.intp),
            part_curve_id=tuple(ids),
        )
        self._paths[lanes] = curves
        if len(self._paths) > self.settings.cache_size:
            self._paths.popitem(last=False)
        return curves


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
    for edge, next_edge in zip(route_edges[start:], route_edges[start + 1:]):
        following.setdefault(edge, next_edge)
    return following


def _wrap(angle_rad: float) -> float:
    """An angle wrapped to [-pi, pi)."""
    return (angle_rad + math.pi) % (2 * math.pi) - math.pi


def _end_heading(shape: np.ndarray) -> float:
    """Heading of a lane's last segment, radians."""
    dx, dy = shape[-1] - shape[-2] if len(shape) > 1 else (1.0, 0.0)
    return math.atan2(dy, dx)


def _start_heading(shape: np.ndarray) -> float:
    """Heading of a lane's first segment, radians."""
    dx, dy = shape[1] - shape[0] if len(shape) > 1 else (1.0, 0.0)
    return math.atan2(dy, dx)
