"""Matches GNSS fixes to the lane of a road map they are on.

A fix (x, y in network metres, an optional heading) is matched to the nearest lane
within a tolerance whose driving direction agrees with the heading, so that the lane
of the opposite direction and crossing roads are rejected. Consecutive fixes of one
vehicle keep their continuity: a lane that continues the vehicle's previous lane (the
previous lane itself, a lane of the same edge, or a lane reached from it within a few
links) is preferred to any other candidate, so a parallel road or a crossing road
close by does not make the match jump.

Several road maps may be matched against at once (a service serving several
networks): the best candidate over all maps wins, ties going to the first map. A fix
may also be confined to one map (a query naming its network), and a fix given in
lon/lat is placed on each geo-referenced map in that map's own projection: each such
placement is a :class:`Probes` row.

The lanes of all maps sit in one spatial index (:class:`csws.road.search.LaneSearch`),
built with the matcher, so a fix costs what the lanes near it cost, however many maps
there are. Fixes are matched in two vectorised passes: first each fix of a vehicle with
a previous match on its previous map alone, where a lane that continues the previous one
decides; then every other fix on all the maps it may be on. A fix that matches nothing
is an answer too: it gets no lane and the reason why.

The matcher is also the spatial index of the sequence matcher (:mod:`csws.road.hmm`), which
weighs each vehicle's fixes over their sequence with a hidden-Markov model: what the service
places fixes with (:meth:`MapMatcher.nearby`, :meth:`MapMatcher.lane_number`).

Headings follow GNSS: degrees clockwise from north. Lane headings in
:mod:`csws.road.roadmap` are radians counter-clockwise from +x (east).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from itertools import chain
from typing import NamedTuple

import numpy as np

from csws.geometry import wrap_angle_rad
from csws.road.match_settings import DEFAULT_MATCH_SETTINGS, MatchSettings
from csws.road.roadmap import RoadMap
from csws.road.search import LaneMatches, LaneSearch, LaneShapes, least_per_group

__all__ = [
    "MapPosition",
    "Probes",
    "FixMatches",
    "MapMatcher",
    "compass_to_math_rad",
    "points_along",
    "lane_point",
    "lane_points",
]


class MapPosition(NamedTuple):
    """A lane of one of the matched road maps: where a vehicle was last matched (a named tuple:
    a batch has thousands).

    Attributes
    ----------
    map_index
        Index of the road map in the matcher's list.
    lane_id
        The lane.
    """

    map_index: int
    lane_id: str


@dataclass(frozen=True)
class Probes:
    """Where to look for each of ``count`` fixes: one or more positions per fix, each matched
    on one map or on every map.

    Attributes
    ----------
    count
        How many fixes there are.
    fix
        ``(p,)`` the fix each probe belongs to.
    xy
        ``(p, 2)`` the probe's position in the coordinates of the map(s) it is matched on,
        finite, m.
    map_index
        ``(p,)`` the map the probe is matched on, -1 for every map (network metres, shared
        by the maps).
    """

    count: int
    fix: np.ndarray
    xy: np.ndarray
    map_index: np.ndarray

    @classmethod
    def everywhere(cls, xy: np.ndarray) -> Probes:
        """Fixes ``(k, 2)`` in network metres, each matched on every map; rows not finite are
        matched nowhere (their fix matches nothing)."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        placed = np.flatnonzero(np.isfinite(xy).all(axis=1))
        return cls(len(xy), placed, xy[placed], np.full(placed.size, -1, dtype=np.intp))


@dataclass(frozen=True)
class FixMatches:
    """The match of each of many fixes, as parallel arrays.

    Attributes
    ----------
    map_index
        ``(k,)`` index of the matched road map, -1 where the fix matched nothing.
    lane_id
        The matched lane of each fix, None where it matched nothing.
    lane_pos_m, distance_m
        ``(k,)`` lane position of the fix's projection and its distance from the lane,
        m; NaN where it matched nothing.
    continued
        ``(k,)`` whether the lane continues the vehicle's previous lane.
    reason
        Why a fix matched nothing, None where it matched.
    """

    map_index: np.ndarray
    lane_id: list[str | None]
    lane_pos_m: np.ndarray
    distance_m: np.ndarray
    continued: np.ndarray
    reason: list[str | None]

    def __len__(self) -> int:
        return len(self.lane_id)


def compass_to_math_rad(heading_deg: np.ndarray) -> np.ndarray:
    """GNSS headings (degrees clockwise from north) as radians counter-clockwise from east."""
    return np.radians(90.0 - np.asarray(heading_deg, dtype=float))


def points_along(xy: np.ndarray, s: np.ndarray, vertex_s: np.ndarray | None = None) -> np.ndarray:
    """Points at arc lengths ``s`` along a polyline ``xy`` (clamped to its ends), ``(len(s), 2)``, m.

    ``vertex_s``, the arc length at each vertex, is computed from ``xy`` unless given
    (e.g. a :class:`~csws.curvature.RadiusProfile`'s ``s``).
    """
    xy = np.asarray(xy, dtype=float)
    if vertex_s is None:
        vertex_s = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))))
    s = np.asarray(s, dtype=float)
    return np.column_stack((np.interp(s, vertex_s, xy[:, 0]), np.interp(s, vertex_s, xy[:, 1])))


def lane_points(road_map: RoadMap, lane_id: str, lane_pos_m: np.ndarray) -> np.ndarray:
    """The points of a lane at SUMO lane positions, ``(k, 2)``, m (:attr:`csws.road.network.Lane.position_factor`)."""
    shape_s = np.asarray(lane_pos_m, dtype=float) / road_map.lane(lane_id).position_factor
    return points_along(road_map.lane_shape(lane_id), shape_s)


def lane_point(road_map: RoadMap, lane_id: str, lane_pos_m: float) -> tuple[float, float]:
    """The point of a lane at a SUMO lane position, m (see :func:`lane_points`)."""
    x, y = lane_points(road_map, lane_id, np.array([lane_pos_m]))[0]
    return float(x), float(y)


class _Candidates:
    """The lanes near some probes, each with its fix, its lane's map and its direction check."""

    def __init__(self, fix: np.ndarray, found: LaneMatches, agrees: np.ndarray) -> None:
        self.fix, self.found, self.agrees = fix, found, agrees


class _Chosen:
    """Per fix, the candidate chosen so far (filled pass by pass)."""

    def __init__(self, count: int) -> None:
        self.lane_index = np.empty(count, dtype=np.intp)
        self.lane_index.fill(-1)
        self.lane_pos_m = np.empty(count)
        self.lane_pos_m.fill(np.nan)
        self.distance_m = self.lane_pos_m.copy()
        self.continued = np.zeros(count, dtype=bool)
        self.near = np.zeros(count, dtype=bool)

    def choose(self, candidates: _Candidates, continued: np.ndarray | None, decided: np.ndarray) -> None:
        """For the fixes ``decided`` (a mask over fixes): the nearest agreeing candidate that
        ``continued`` the previous lane if any (None: none does), else the nearest agreeing one; ties
        to the lower lane number (the first map)."""
        fix, found = candidates.fix, candidates.found
        mine = decided[fix]
        self.near[fix[mine]] = True
        eligible = candidates.agrees & mine
        if continued is not None and continued.any():
            continuing = np.zeros(len(decided), dtype=bool)
            continuing[fix[eligible & continued]] = True
            eligible &= continued | ~continuing[fix]
        rows = eligible.nonzero()[0]
        first = rows[least_per_group(fix[rows], found.distance_m[rows], found.lane_index[rows])]
        chosen = fix[first]
        self.lane_index[chosen] = found.lane_index[first]
        self.lane_pos_m[chosen] = found.lane_pos_m[first]
        self.distance_m[chosen] = found.distance_m[first]
        if continued is not None:
            self.continued[chosen] = continued[first]


class MapMatcher:
    """Matches fixes to the lanes of one or more road maps.

    The spatial index over every map's lanes and the lanes of every edge are built here,
    at start-up, so that no fix waits for them.

    Parameters
    ----------
    road_maps
        The maps, in order of preference when two match equally well.
    settings
        Tolerances.
    """

    def __init__(self, road_maps: Sequence[RoadMap], settings: MatchSettings = DEFAULT_MATCH_SETTINGS) -> None:
        if not road_maps:
            raise ValueError("map matching needs at least one road map")
        self.road_maps = tuple(road_maps)
        self.settings = settings
        lane_counts = [len(road_map.lane_ids) for road_map in self.road_maps]
        first_lane = np.concatenate(([0], np.cumsum(lane_counts))).astype(np.intp)
        #: The lanes (from, up to) of each map by its index, and of all maps in the last row (for index -1).
        self._lane_range = np.array(
            [*zip(first_lane[:-1], first_lane[1:], strict=False), (0, first_lane[-1])], dtype=np.intp
        )
        self._lane_map = np.repeat(np.arange(len(self.road_maps), dtype=np.intp), lane_counts)
        self._lane_ids = np.concatenate([road_map.lane_shapes.lane_ids for road_map in self.road_maps])
        #: The same as Python lists: a look-up of one lane's is cheaper in a list than in an array.
        self._lane_map_list: list[int] = self._lane_map.tolist()
        self._lane_id_list: list[str] = [str(lane_id) for lane_id in self._lane_ids.tolist()]
        self._search = LaneSearch(LaneShapes.joined([road_map.lane_shapes for road_map in self.road_maps]))
        self._edge_lanes = [
            self._lanes_by_edge(map_index, int(first_lane[map_index])) for map_index in range(len(self.road_maps))
        ]
        self._continuations = lru_cache(maxsize=65536)(self._continuation_lanes)
        self._heading_tolerance_rad = math.radians(settings.heading_tolerance_deg)

    def match(
        self,
        probes: Probes,
        heading_deg: np.ndarray | None = None,
        previous: Sequence[MapPosition | None] | None = None,
    ) -> FixMatches:
        """Match ``probes.count`` fixes.

        Parameters
        ----------
        probes
            Where to look for each fix (:meth:`Probes.everywhere` for fixes in network
            metres that may be on any map).
        heading_deg
            ``(count,)`` GNSS headings, degrees clockwise from north; NaN where unknown (the
            direction is then not checked).
        previous
            Each fix's vehicle's previous match, or None.
        """
        count = probes.count
        heading = np.full(count, np.nan) if heading_deg is None else np.asarray(heading_deg, dtype=float)
        chosen = _Chosen(count)
        if previous is not None and any(p is not None for p in previous):
            decided = self._match_on_previous_maps(probes, heading, previous, chosen)
            rows = (~decided[probes.fix]).nonzero()[0]
        else:
            decided = np.zeros(count, dtype=bool)
            rows = np.arange(len(probes.fix))
        if rows.size:
            confined = probes.map_index[rows]
            lane_range = None if (confined < 0).all() else self._lane_range[confined]
            chosen.choose(self._candidates(probes, rows, lane_range, heading), None, ~decided)
        return self._fix_matches(chosen, heading)

    @property
    def lane_ids(self) -> np.ndarray:
        """The id of each lane numbered over all maps (:meth:`lane_number`), an object array."""
        return self._lane_ids

    @property
    def lane_map(self) -> np.ndarray:
        """The map index of each lane numbered over all maps (:meth:`lane_number`)."""
        return self._lane_map

    def lane_number(self, map_index: int, lane_id: str) -> int:
        """The number of a lane of map ``map_index`` over all maps (-1 when the map has no such lane)."""
        road_map = self.road_maps[map_index]
        return road_map.lane_index(lane_id) + int(self._lane_range[map_index, 0]) if road_map.has_lane(lane_id) else -1

    def lane_name(self, number: int) -> tuple[int, str]:
        """The map index and lane id of a lane numbered over all maps (:meth:`lane_number`)."""
        return self._lane_map_list[number], self._lane_id_list[number]

    def nearby(self, probes: Probes, radius_m: np.ndarray) -> LaneMatches:
        """Every lane within each fix's ``radius_m`` (``(probes.count,)``, m) of its probes, each probe
        on its map or on every map: ``point_index`` is the probe's row, ``lane_index`` the lane's number
        over all maps; rows by probe, then lane."""
        confined = probes.map_index
        lane_range = None if (confined < 0).all() else self._lane_range[confined]
        return self._search.nearest_per_lane(
            probes.xy, float(radius_m.max(initial=0.0)), lane_range, radius_m[probes.fix]
        )

    def _match_on_previous_maps(
        self, probes: Probes, heading: np.ndarray, previous: Sequence[MapPosition | None], chosen: _Chosen
    ) -> np.ndarray:
        """The first pass: the fixes of vehicles with a previous match, on their previous map alone.

        A fix is decided here when a lane that continues its previous one agrees with it
        (such a lane wins over any other), or when the previous map is the only one it may
        be on. Returns the decided fixes, a mask.
        """
        previous_map = np.array([-1 if p is None else p.map_index for p in previous], dtype=np.intp)
        probe_previous = previous_map[probes.fix]
        if len(self.road_maps) == 1:  # every probe is on the one map
            rows, lane_range = (probe_previous >= 0).nonzero()[0], None
            elsewhere = np.zeros(probes.count, dtype=bool)
        else:
            here = probes.map_index == probe_previous  # confined to the previous map
            rows = ((probe_previous >= 0) & (here | (probes.map_index < 0))).nonzero()[0]
            lane_range = self._lane_range[probe_previous[rows]]
            elsewhere = np.bincount(probes.fix[~here], minlength=probes.count) > 0
        candidates = self._candidates(probes, rows, lane_range, heading)
        continued = self._continued(candidates, previous)
        decided = (previous_map >= 0) & ~elsewhere
        decided[candidates.fix[continued & candidates.agrees]] = True
        chosen.choose(candidates, continued, decided)
        return decided

    def _candidates(
        self, probes: Probes, rows: np.ndarray, lane_range: np.ndarray | None, heading_deg: np.ndarray
    ) -> _Candidates:
        """Every lane within the tolerance of the probes ``rows`` (each confined to its lane range when
        given), with the direction check of its fix's heading."""
        found = self._search.nearest_per_lane(probes.xy[rows], self.settings.tolerance_m, lane_range)
        fix = probes.fix[rows][found.point_index]
        off_rad = wrap_angle_rad(found.heading_rad - compass_to_math_rad(heading_deg[fix]))
        return _Candidates(fix, found, ~(np.abs(off_rad) > self._heading_tolerance_rad))  # a NaN heading agrees

    def _continued(self, candidates: _Candidates, previous: Sequence[MapPosition | None]) -> np.ndarray:
        """Whether each candidate (on its fix's previous map) continues the fix's previous lane."""
        return np.array(
            [
                lane in self._continuations(previous[fix].map_index, previous[fix].lane_id)
                for fix, lane in zip(candidates.fix.tolist(), candidates.found.lane_index.tolist(), strict=False)
            ],
            dtype=bool,
        )

    def _fix_matches(self, chosen: _Chosen, heading_deg: np.ndarray) -> FixMatches:
        matched = chosen.lane_index >= 0
        lane_ids = np.full(len(matched), None, dtype=object)
        lane_ids[matched] = self._lane_ids[chosen.lane_index[matched]]
        map_index = np.where(matched, self._lane_map[chosen.lane_index], -1)
        reasons = [
            None if is_matched else self._reason(is_near, h)
            for is_matched, is_near, h in zip(
                matched.tolist(), chosen.near.tolist(), heading_deg.tolist(), strict=False
            )
        ]
        return FixMatches(
            map_index=map_index,
            lane_id=lane_ids.tolist(),
            lane_pos_m=chosen.lane_pos_m,
            distance_m=chosen.distance_m,
            continued=chosen.continued,
            reason=reasons,
        )

    def _reason(self, near: bool, heading_deg: float) -> str:
        """Why a fix matched nothing."""
        tolerance = f"{self.settings.tolerance_m:g} m"
        if not near:
            return f"no lane within {tolerance}"
        return (
            f"no lane within {tolerance} runs within {self.settings.heading_tolerance_deg:g} deg"
            f" of the heading {heading_deg:g} deg"
        )

    def _continuation_lanes(self, map_index: int, lane_id: str) -> frozenset[int]:
        """Lanes that continue ``lane_id`` (by number in the joined index): its edge's lanes and those
        reached within a few links, with their edges'."""
        road_map = self.road_maps[map_index]
        try:
            reached, frontier = {lane_id}, [lane_id]
            for _ in range(self.settings.continuation_links):
                frontier = [s for lane in frontier for s in road_map.successors(lane) if s not in reached]
                reached.update(frontier)
        except KeyError:
            return frozenset()
        edge_lanes = self._edge_lanes[map_index]
        return frozenset(chain.from_iterable(edge_lanes[road_map.lane(lane).edge_id] for lane in reached))

    def _lanes_by_edge(self, map_index: int, first_lane: int) -> dict[str, tuple[int, ...]]:
        """The lanes of each edge of one map, by number in the joined index (from ``first_lane``)."""
        road_map = self.road_maps[map_index]
        edge_lanes: dict[str, list[int]] = {}
        for number, lane_id in enumerate(road_map.lane_ids, start=first_lane):
            edge_lanes.setdefault(road_map.lane(lane_id).edge_id, []).append(number)
        return {edge: tuple(lanes) for edge, lanes in edge_lanes.items()}
