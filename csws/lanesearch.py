"""Finding the lanes near positions: a spatial index over the lanes' shapes.

The lane shapes are simplified within :data:`MATCH_TOLERANCE_M` (a dense SUMO shape, a
vertex every 0.5 m, becomes one segment per straight and a few per curve) and their
segments put in a shapely ``STRtree``, built on the first look-up. A position is
projected onto the nearest segment of every lane within the search radius; its lane
position follows SUMO (shape arc length times ``length / shape length``).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import shapely

__all__ = ["LaneMatch", "LaneMatches", "LaneSearch", "MATCH_TOLERANCE_M"]

#: Lane shapes are simplified within this distance for position look-ups, m.
MATCH_TOLERANCE_M = 0.01


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

    Rows are sorted by ``point_index`` and, for each point, by ``distance_m``; a point
    with no lane within the search radius has no row.

    Attributes
    ----------
    point_index
        Index of the position in the query, ``(k,)`` int.
    lane_id
        Candidate lane ids, ``(k,)`` object array of str.
    distance_m, lane_pos_m, heading_rad
        As in :class:`LaneMatch`, ``(k,)`` float arrays.
    """

    point_index: np.ndarray
    lane_id: np.ndarray
    distance_m: np.ndarray
    lane_pos_m: np.ndarray
    heading_rad: np.ndarray

    def __len__(self) -> int:
        return len(self.point_index)

    def for_point(self, point_index: int) -> list[LaneMatch]:
        """The candidates of one position, nearest first."""
        rows = np.flatnonzero(self.point_index == point_index)
        return [
            LaneMatch(str(self.lane_id[i]), *map(float, (self.distance_m[i], self.lane_pos_m[i], self.heading_rad[i])))
            for i in rows
        ]


class LaneSearch:
    """The lanes near positions, for lanes stored back to back.

    Parameters
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

    def __init__(self, xy: np.ndarray, vertex_start: np.ndarray, vertex_s: np.ndarray, lane_ids: np.ndarray,
                 position_factor: np.ndarray) -> None:
        self._xy, self._vertex_start, self._vertex_s = xy, vertex_start, vertex_s
        self._lane_ids, self._position_factor = lane_ids, position_factor

    def match(self, xy: np.ndarray, radius_m: float) -> LaneMatches:
        """All lanes within ``radius_m`` of each of the positions ``xy`` ``(k, 2)`` (finite,
        in network coordinates, m), each position projected onto each lane."""
        point_index, segment_index = self._segment_tree.query(shapely.points(xy), predicate="dwithin",
                                                              distance=radius_m)
        start, end = self._segments[0][segment_index], self._segments[1][segment_index]
        a, b, p = self._xy[start], self._xy[end], xy[point_index]
        direction = b - a
        length_sq = np.einsum("ij,ij->i", direction, direction)
        fraction = np.clip(np.einsum("ij,ij->i", p - a, direction) / np.where(length_sq > 0, length_sq, 1.0), 0, 1)
        nearest = a + fraction[:, None] * direction
        distance_m = np.hypot(*(p - nearest).T)
        lane_index = self._segment_lane[segment_index]
        # The nearest segment of each lane for each point: sort by point, lane, distance; keep the first.
        order = np.lexsort((distance_m, lane_index, point_index))
        first = np.ones(order.size, dtype=bool)
        first[1:] = (np.diff(point_index[order]) != 0) | (np.diff(lane_index[order]) != 0)
        keep = order[first]
        keep = keep[np.lexsort((distance_m[keep], point_index[keep]))]
        start, end = start[keep], end[keep]
        along_shape_m = self._vertex_s[start] + fraction[keep] * (self._vertex_s[end] - self._vertex_s[start])
        lane_index = lane_index[keep]
        return LaneMatches(
            point_index=point_index[keep],
            lane_id=self._lane_ids[lane_index],
            distance_m=distance_m[keep],
            lane_pos_m=along_shape_m * self._position_factor[lane_index],
            heading_rad=np.arctan2(direction[keep, 1], direction[keep, 0]),
        )

    @cached_property
    def _segments(self) -> tuple[np.ndarray, np.ndarray]:
        """First and last vertex of every indexed segment: the lane shapes simplified within
        :data:`MATCH_TOLERANCE_M`, as indices into the shape vertices.

        A dense SUMO shape (a vertex every 0.5 m) becomes one segment per straight and a
        few per curve, so a fix meets a handful of candidates instead of dozens. The kept
        vertices are original ones, so lane positions stay exact there and are
        interpolated in arc length between them.
        """
        lane_of_vertex = np.repeat(np.arange(len(self._vertex_start) - 1), np.diff(self._vertex_start))
        lines = shapely.linestrings(self._xy, indices=lane_of_vertex)
        simplified = shapely.simplify(lines, MATCH_TOLERANCE_M, preserve_topology=False)
        kept_xy, kept_lane = shapely.get_coordinates(simplified, return_index=True)
        position = {(lane, x, y): i for i, (lane, (x, y)) in enumerate(zip(lane_of_vertex.tolist(), self._xy.tolist()))}
        kept = np.array([position[(lane, x, y)] for lane, (x, y) in zip(kept_lane.tolist(), kept_xy.tolist())])
        # A lane whose kept vertices are not in order (a loop through one point) keeps every vertex.
        disordered = np.unique(kept_lane[1:][(np.diff(kept) <= 0) & (kept_lane[1:] == kept_lane[:-1])])
        if disordered.size:
            keep = ~np.isin(kept_lane, disordered)
            every = np.flatnonzero(np.isin(lane_of_vertex, disordered))
            kept = np.sort(np.concatenate((kept[keep], every)))
        lane = lane_of_vertex[kept]
        segment = (lane[1:] == lane[:-1]) & np.any(self._xy[kept[1:]] != self._xy[kept[:-1]], axis=1)
        return kept[:-1][segment], kept[1:][segment]

    @cached_property
    def _segment_lane(self) -> np.ndarray:
        """The lane of every indexed segment."""
        return np.searchsorted(self._vertex_start, self._segments[0], side="right") - 1

    @cached_property
    def _segment_tree(self) -> shapely.STRtree:
        """Spatial index over the simplified shape segments, built on the first position look-up.

        Segments rather than whole lanes: a projection onto two points is a few numpy
        operations, onto a lane of thousands of vertices a search along all of them.
        """
        start, end = self._segments
        return shapely.STRtree(shapely.linestrings(np.stack((self._xy[start], self._xy[end]), axis=1)))
