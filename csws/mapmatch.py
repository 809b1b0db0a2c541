"""Map matching: which lane of which road map a GNSS fix is on.

A fix (x, y in network metres, an optional heading) is matched to the nearest lane
within a tolerance whose driving direction agrees with the heading, so that the lane
of the opposite direction and crossing roads are rejected. Consecutive fixes of one
vehicle keep their continuity: a lane that continues the vehicle's previous lane (the
previous lane itself, a lane of the same edge, or a lane reached from it within a few
links) is preferred to any other candidate, so a parallel road or a crossing road
close by does not make the match jump.

Several road maps may be matched against at once (a service serving several
networks): the best candidate over all maps wins, ties going to the first map.

Every fix is matched in one vectorised pass per map (:meth:`RoadMap.match_points`).
A fix that matches nothing is an answer too: it gets no lane and the reason why.

Headings follow GNSS: degrees clockwise from north. Lane headings in
:mod:`csws.roadmap` are radians counter-clockwise from +x (east).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from itertools import chain
from typing import Sequence

import numpy as np

from .geometry import wrap_angle_rad
from .roadmap import RoadMap

__all__ = [
    "MatchSettings",
    "MapPosition",
    "FixMatches",
    "MapMatcher",
    "compass_to_math_rad",
    "points_along",
    "lane_point",
]


@dataclass(frozen=True)
class MatchSettings:
    """How far from a lane and how far off its direction a fix may be.

    Attributes
    ----------
    tolerance_m
        A fix matches lanes within this distance, m (GNSS error plus map error).
    heading_tolerance_deg
        A fix with a heading matches only lanes whose direction differs from it by at
        most this, degrees: the opposite direction (180) and crossing roads (90) are out.
    continuation_links
        How many links ahead of the previous lane a lane still counts as its continuation.
    """

    tolerance_m: float = 10.0
    heading_tolerance_deg: float = 45.0
    continuation_links: int = 4

    def __post_init__(self) -> None:
        if not (math.isfinite(self.tolerance_m) and self.tolerance_m > 0):
            raise ValueError(f"tolerance_m must be a positive number of metres, got {self.tolerance_m!r}")
        if not (0 < self.heading_tolerance_deg <= 180):
            raise ValueError(f"heading_tolerance_deg must lie in (0, 180], got {self.heading_tolerance_deg!r}")
        if self.continuation_links < 0:
            raise ValueError(f"continuation_links must not be negative, got {self.continuation_links!r}")


@dataclass(frozen=True)
class MapPosition:
    """A lane of one of the matched road maps: where a vehicle was last matched.

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


def lane_point(road_map: RoadMap, lane_id: str, lane_pos_m: float) -> tuple[float, float]:
    """The point of a lane at a SUMO lane position, m (see :attr:`csws.roadmap.Lane.position_factor`)."""
    lane = road_map.lane(lane_id)
    x, y = points_along(road_map.lane_shape(lane_id), np.array([lane_pos_m / lane.position_factor]))[0]
    return float(x), float(y)


class MapMatcher:
    """Matches fixes to the lanes of one or more road maps.

    Parameters
    ----------
    road_maps
        The maps, in order of preference when two match equally well.
    settings
        Tolerances.
    """

    def __init__(self, road_maps: Sequence[RoadMap], settings: MatchSettings = MatchSettings()) -> None:
        if not road_maps:
            raise ValueError("map matching needs at least one road map")
        self.road_maps = tuple(road_maps)
        self.settings = settings
        self._continuations = lru_cache(maxsize=65536)(self._continuation_lanes)
        self._edge_lanes: dict[int, dict[str, tuple[str, ...]]] = {}

    def match(
        self,
        xy_per_map: Sequence[np.ndarray],
        heading_deg: np.ndarray | None = None,
        previous: Sequence[MapPosition | None] | None = None,
    ) -> FixMatches:
        """Match ``k`` fixes.

        Parameters
        ----------
        xy_per_map
            For each road map, the fixes in its coordinates, ``(k, 2)``, m; rows of NaN
            where a fix cannot be placed on that map (e.g. lon/lat on a map without a
            projection).
        heading_deg
            ``(k,)`` GNSS headings, degrees clockwise from north; NaN where unknown (the
            direction is then not checked).
        previous
            Each fix's vehicle's previous match, or None.
        """
        count = len(xy_per_map[0])
        heading = np.full(count, np.nan) if heading_deg is None else np.asarray(heading_deg, dtype=float)
        previous = [None] * count if previous is None else list(previous)
        rows = [self._candidates(m, xy, heading, previous) for m, xy in enumerate(xy_per_map)]
        point, map_index, lane_id, distance_m, lane_pos_m, agrees, continued = (
            np.concatenate(column) for column in zip(*rows)
        )
        return self._best(count, heading, point, map_index, lane_id, distance_m, lane_pos_m, agrees, continued)

    def _candidates(
        self, map_index: int, xy: np.ndarray, heading_deg: np.ndarray, previous: Sequence[MapPosition | None]
    ) -> tuple[np.ndarray, ...]:
        """Every lane of one map within the tolerance of each fix, with its direction check and continuity."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        placed = np.flatnonzero(np.isfinite(xy).all(axis=1))
        found = self.road_maps[map_index].match_points(xy[placed], self.settings.tolerance_m)
        point = placed[found.point_index]
        off_rad = wrap_angle_rad(found.heading_rad - compass_to_math_rad(heading_deg[point]))
        agrees = ~(np.abs(off_rad) > math.radians(self.settings.heading_tolerance_deg))  # NaN heading agrees
        continued = np.array(
            [
                (before := previous[p]) is not None
                and before.map_index == map_index
                and lane in self._continuations(map_index, before.lane_id)
                for p, lane in zip(point.tolist(), found.lane_id.tolist())
            ],
            dtype=bool,
        )
        return (
            point,
            np.full(len(point), map_index, dtype=np.intp),
            found.lane_id,
            found.distance_m,
            found.lane_pos_m,
            agrees,
            continued,
        )

    def _best(self, count, heading, point, map_index, lane_id, distance_m, lane_pos_m, agrees, continued) -> FixMatches:
        """Per fix the continuing lane if any, else the nearest; then the first map."""
        near = np.bincount(point, minlength=count) > 0
        keep = np.flatnonzero(agrees)
        order = keep[np.lexsort((map_index[keep], distance_m[keep], ~continued[keep], point[keep]))]
        first = order[np.concatenate(([True], point[order][1:] != point[order][:-1]))] if order.size else order
        chosen = np.full(count, -1, dtype=np.intp)
        chosen[point[first]] = first
        matched = chosen >= 0

        def pick(values: np.ndarray, missing) -> np.ndarray:
            out = np.full(count, missing, dtype=values.dtype)
            out[matched] = values[chosen[matched]]
            return out

        lane_ids = pick(lane_id.astype(object), None).tolist()
        reasons = [
            None if is_matched else self._reason(is_near, h)
            for is_matched, is_near, h in zip(matched.tolist(), near.tolist(), heading.tolist())
        ]
        return FixMatches(
            map_index=pick(map_index, -1),
            lane_id=lane_ids,
            lane_pos_m=pick(lane_pos_m.astype(float), np.nan),
            distance_m=pick(distance_m.astype(float), np.nan),
            continued=pick(continued, False),
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

    def _continuation_lanes(self, map_index: int, lane_id: str) -> frozenset[str]:
        """Lanes that continue ``lane_id``: its edge's lanes and those reached within a few links, with their edges'."""
        road_map = self.road_maps[map_index]
        try:
            reached, frontier = {lane_id}, [lane_id]
            for _ in range(self.settings.continuation_links):
                frontier = [s for lane in frontier for s in road_map.successors(lane) if s not in reached]
                reached.update(frontier)
        except KeyError:
            return frozenset()
        edge_lanes = self._lanes_by_edge(map_index)
        return frozenset(chain(reached, *(edge_lanes[road_map.lane(lane).edge_id] for lane in reached)))

    def _lanes_by_edge(self, map_index: int) -> dict[str, tuple[str, ...]]:
        """The lanes of each edge of one map, built on first use."""
        if map_index not in self._edge_lanes:
            road_map = self.road_maps[map_index]
            edge_lanes: dict[str, list[str]] = {}
            for lane_id in road_map.lane_ids:
                edge_lanes.setdefault(road_map.lane(lane_id).edge_id, []).append(lane_id)
            self._edge_lanes[map_index] = {edge: tuple(lanes) for edge, lanes in edge_lanes.items()}
        return self._edge_lanes[map_index]
