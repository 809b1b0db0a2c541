"""Finds the lanes near positions through a spatial index over the lanes' shapes.

The lane shapes are simplified within :data:`MATCH_TOLERANCE_M` (a dense SUMO shape, a
vertex every 0.5 m, becomes one segment per straight and a few per curve) and their
segments put in a shapely ``STRtree``, built with the :class:`LaneSearch`. A position is
projected onto the nearest segment of every lane within the search radius; its lane
position follows SUMO (shape arc length times ``length / shape length``).

One index may hold the lanes of several road maps (:meth:`LaneShapes.joined`): lanes are
numbered back to back, and a look-up can be confined to a range of lane numbers per
position (the lanes of one map), so that the cost of a look-up depends on the lanes near
the position, not on how many maps there are.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import shapely

__all__ = ["LaneMatch", "LaneMatches", "LaneSearch", "LaneShapes", "MATCH_TOLERANCE_M", "least_per_group"]

#: Lane shapes are simplified within this distance for position look-ups, m.
MATCH_TOLERANCE_M = 0.01
#: From this many rows on, :func:`least_per_group` sorts by integer keys alone: numpy's lexsort with a
#: float key takes 30 ms for 170,000 rows, against 5 ms; below it, one lexsort is fewer calls.
_MANY_ROWS = 1000


def least_per_group(group: np.ndarray, distance: np.ndarray, tiebreak: np.ndarray) -> np.ndarray:
    """The row of least ``distance`` of each value of ``group`` (of equal distances, the one of least
    ``tiebreak``), as row indices in increasing ``group`` order.

    Parameters
    ----------
    group, tiebreak
        ``(n,)`` integers.
    distance
        ``(n,)`` floats, not NaN.
    """
    if group.size < _MANY_ROWS:
        order = np.lexsort((tiebreak, distance, group))
        sorted_group = group[order]
        first = np.ones(order.size, dtype=bool)
        first[1:] = sorted_group[1:] != sorted_group[:-1]
        return order[first]
    order = np.argsort(tiebreak, kind="stable")
    order = order[np.argsort(group[order], kind="stable")]  # by group, then tiebreak
    sorted_group, sorted_distance = group[order], distance[order]
    starts = np.ones(order.size, dtype=bool)
    starts[1:] = sorted_group[1:] != sorted_group[:-1]
    least = np.minimum.reduceat(sorted_distance, np.flatnonzero(starts))
    at_least = np.flatnonzero(sorted_distance == least[np.cumsum(starts) - 1])
    first = np.ones(at_least.size, dtype=bool)
    first[1:] = sorted_group[at_least[1:]] != sorted_group[at_least[:-1]]
    return order[at_least[first]]


@dataclass(frozen=True)
class LaneShapes:
    """The shapes of lanes stored back to back: what a :class:`LaneSearch` indexes.

    Attributes
    ----------
    xy
        Vertices of all lane shapes back to back, ``(n, 2)``, m.
    vertex_start
        Offset of each lane's first vertex in ``xy`` and ``n`` at the end.
    vertex_s
        Arc length of every vertex along its own lane, m.
    lane_ids
        The lanes' ids, an object array.
    position_factor
        Each lane's lane position per metre of shape (SUMO's ``length / shape length``).
    """

    xy: np.ndarray
    vertex_start: np.ndarray
    vertex_s: np.ndarray
    lane_ids: np.ndarray
    position_factor: np.ndarray

    @property
    def lane_count(self) -> int:
        """How many lanes there are."""
        return len(self.vertex_start) - 1

    @classmethod
    def joined(cls, parts: Sequence[LaneShapes]) -> LaneShapes:
        """The lanes of several maps back to back, in order: the lanes of ``parts[k]`` are numbered
        from the sum of the lane counts before it. Each part keeps its own arc lengths."""
        if len(parts) == 1:
            return parts[0]
        vertex_offset = np.cumsum([0] + [len(part.xy) for part in parts])
        vertex_start = [part.vertex_start[:-1] + offset for part, offset in zip(parts, vertex_offset[:-1], strict=True)]
        return cls(
            xy=np.concatenate([part.xy for part in parts]),
            vertex_start=np.concatenate(vertex_start + [vertex_offset[-1:]]).astype(np.int64),
            vertex_s=np.concatenate([part.vertex_s for part in parts]),
            lane_ids=np.concatenate([part.lane_ids for part in parts]),
            position_factor=np.concatenate([part.position_factor for part in parts]),
        )


@dataclass(frozen=True)
class LaneMatch:
    """One lane near a position.

    Attributes
    ----------
    lane_id
        The candidate lane.
    distance_m
        Distance from the position to the lane's shape, m.
    lane_pos_m
        Lane position of the position's projection onto the shape, m.
    heading_rad
        Driving direction of the lane there, radians counter-clockwise from +x
        (the convention of :mod:`csws.geometry`).
    """

    lane_id: str
    distance_m: float
    lane_pos_m: float
    heading_rad: float


@dataclass(frozen=True)
class LaneMatches:
    """Lanes near many positions, as parallel arrays (one row per position-lane pair).

    A position with no lane within the search radius has no row.

    Attributes
    ----------
    point_index
        Index of the position in the query, ``(k,)`` int.
    lane_index
        Number of the candidate lane in the index (:class:`LaneShapes`), ``(k,)`` int.
    lane_id
        Candidate lane ids, ``(k,)`` object array of str.
    distance_m, lane_pos_m, heading_rad
        As in :class:`LaneMatch`, ``(k,)`` float arrays.
    """

    point_index: np.ndarray
    lane_index: np.ndarray
    lane_id: np.ndarray
    distance_m: np.ndarray
    lane_pos_m: np.ndarray
    heading_rad: np.ndarray

    def __len__(self) -> int:
        return len(self.point_index)

    def for_point(self, point_index: int) -> list[LaneMatch]:
        """The candidates of one position, in the order of the rows (nearest first from :meth:`LaneSearch.match`)."""
        rows = np.flatnonzero(self.point_index == point_index)
        return [
            LaneMatch(str(self.lane_id[i]), *map(float, (self.distance_m[i], self.lane_pos_m[i], self.heading_rad[i])))
            for i in rows
        ]


def _vertex_keys(lane: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """One sortable key per vertex, equal exactly when the lane and both coordinates are equal."""
    keys = np.empty((len(lane), 3), dtype=np.int64)
    keys[:, 0] = lane
    keys[:, 1:] = (np.asarray(xy, dtype=float) + 0.0).view(np.int64)  # + 0.0: -0.0 is 0.0
    return keys.view(np.dtype((np.void, keys.itemsize * 3))).ravel()


def _simplified_segments(shapes: LaneShapes) -> tuple[np.ndarray, np.ndarray]:
    """First and last vertex of every indexed segment: the lane shapes simplified within
    :data:`MATCH_TOLERANCE_M`, as indices into the shape vertices.

    A dense SUMO shape (a vertex every 0.5 m) becomes one segment per straight and a
    few per curve, so a fix meets a handful of candidates instead of dozens. The kept
    vertices are original ones, so lane positions stay exact there and are
    interpolated in arc length between them.
    """
    xy = shapes.xy
    lane_of_vertex = np.repeat(np.arange(shapes.lane_count), np.diff(shapes.vertex_start))
    lines = shapely.linestrings(xy, indices=lane_of_vertex)
    simplified = shapely.simplify(lines, MATCH_TOLERANCE_M, preserve_topology=False)
    kept_xy, kept_lane = shapely.get_coordinates(simplified, return_index=True)
    # Each kept vertex is the last vertex of its lane at its coordinates.
    original = _vertex_keys(lane_of_vertex, xy)
    order = np.argsort(original, kind="stable")
    kept = order[np.searchsorted(original[order], _vertex_keys(kept_lane, kept_xy), side="right") - 1]
    # A lane whose kept vertices are not in order (a loop through one point) keeps every vertex.
    disordered = np.unique(kept_lane[1:][(np.diff(kept) <= 0) & (kept_lane[1:] == kept_lane[:-1])])
    if disordered.size:
        keep = ~np.isin(kept_lane, disordered)
        every = np.flatnonzero(np.isin(lane_of_vertex, disordered))
        kept = np.sort(np.concatenate((kept[keep], every)))
    lane = lane_of_vertex[kept]
    segment = (lane[1:] == lane[:-1]) & np.any(xy[kept[1:]] != xy[kept[:-1]], axis=1)
    return kept[:-1][segment], kept[1:][segment]


class LaneSearch:
    """The lanes near positions: the simplified segments of the lanes' shapes in a spatial index.

    Segments rather than whole lanes: a projection onto two points is a few numpy
    operations, onto a lane of thousands of vertices a search along all of them. What a
    projection needs of a segment (its start, direction, arc lengths, lane, heading) is
    computed here once.

    Parameters
    ----------
    shapes
        The lanes.
    """

    def __init__(self, shapes: LaneShapes) -> None:
        self._lane_ids, self._position_factor = shapes.lane_ids, shapes.position_factor
        start, end = _simplified_segments(shapes)
        self._start_xy = shapes.xy[start]
        self._direction = shapes.xy[end] - self._start_xy
        length_sq = np.einsum("ij,ij->i", self._direction, self._direction)
        self._divisor = np.where(length_sq > 0, length_sq, 1.0)
        self._start_s = shapes.vertex_s[start]
        self._delta_s = shapes.vertex_s[end] - self._start_s
        self._lane = np.searchsorted(shapes.vertex_start, start, side="right") - 1
        self._heading_rad = np.arctan2(self._direction[:, 1], self._direction[:, 0])
        self._tree = shapely.STRtree(shapely.linestrings(np.stack((self._start_xy, shapes.xy[end]), axis=1)))

    def match(self, xy: np.ndarray, radius_m: float) -> LaneMatches:
        """All lanes within ``radius_m`` of each of the positions ``xy`` ``(k, 2)`` (finite,
        in network coordinates, m), each position projected onto each lane; rows sorted by
        position and, for each, by distance."""
        found = self.nearest_per_lane(xy, radius_m)
        order = np.lexsort((found.distance_m, found.point_index))
        return LaneMatches(
            *(
                column[order]
                for column in (
                    found.point_index,
                    found.lane_index,
                    found.lane_id,
                    found.distance_m,
                    found.lane_pos_m,
                    found.heading_rad,
                )
            )
        )

    def nearest_per_lane(
        self,
        xy: np.ndarray,
        radius_m: float,
        lane_range: np.ndarray | None = None,
        point_radius_m: np.ndarray | None = None,
    ) -> LaneMatches:
        """Each position ``xy`` ``(k, 2)`` projected onto each lane within ``radius_m`` (its nearest
        segment); rows by position, then lane.

        Parameters
        ----------
        xy
            Finite positions in network coordinates, m.
        radius_m
            Search radius, m.
        lane_range
            ``(k, 2)``: only lanes numbered from ``lane_range[i, 0]`` up to, not including,
            ``lane_range[i, 1]`` for position ``i``; every lane when None.
        point_radius_m
            ``(k,)``: each position's own search radius, at most ``radius_m``, m; ``radius_m`` for all
            when None (filtered before the nearest segment of each lane is taken: the same lanes as
            filtering after, in one pass).
        """
        # The segments whose bounding box meets the square around each point (cheaper for the tree than
        # a distance predicate), then those within the radius by their own distance.
        x, y = xy[:, 0], xy[:, 1]
        point_index, segment = self._tree.query(shapely.box(x - radius_m, y - radius_m, x + radius_m, y + radius_m))
        lane = self._lane[segment]
        if lane_range is not None:
            inside = (lane >= lane_range[point_index, 0]) & (lane < lane_range[point_index, 1])
            point_index, segment, lane = point_index[inside], segment[inside], lane[inside]
        start_xy, direction, p = self._start_xy[segment], self._direction[segment], xy[point_index]
        along = np.einsum("ij,ij->i", p - start_xy, direction) / self._divisor[segment]
        fraction = np.minimum(np.maximum(along, 0.0), 1.0)  # as np.clip, with less overhead
        distance_m = np.hypot(*(p - (start_xy + fraction[:, None] * direction)).T)
        near = np.flatnonzero(distance_m <= (radius_m if point_radius_m is None else point_radius_m[point_index]))
        point_index, segment, lane, fraction, distance_m = (
            point_index[near],
            segment[near],
            lane[near],
            fraction[near],
            distance_m[near],
        )
        # The nearest segment of each lane for each point; of two at the same distance (a point nearest to
        # the vertex they share), the earlier one along the lane.
        keep = least_per_group(point_index * len(self._lane_ids) + lane, distance_m, segment)
        segment, lane = segment[keep], lane[keep]
        along_shape_m = self._start_s[segment] + fraction[keep] * self._delta_s[segment]
        return LaneMatches(
            point_index=point_index[keep],
            lane_index=lane,
            lane_id=self._lane_ids[lane],
            distance_m=distance_m[keep],
            lane_pos_m=along_shape_m * self._position_factor[lane],
            heading_rad=self._heading_rad[segment],
        )
