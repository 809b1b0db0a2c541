"""Holds every lane of a SUMO network with its shape and links, and finds the lanes near a position: the lane map.

A :class:`LaneMap` answers what the lanes are, without their curves (the road map,
:class:`csws.road.roadmap.RoadMap`, adds those): each lane's SUMO attributes and polyline,
the lanes a vehicle can drive onto from its end, the internal lanes that join two lanes of a
path, and which lanes lie near a position, where along them and heading which way.

Storage is columnar: the vertices of all lanes sit in one ``(n, 2)`` array with an offset
per lane (read by :mod:`csws.road.network`), the successors in compressed rows, and
positions are looked up in a spatial index of the lane shapes (:mod:`csws.road.search`).

Lane positions follow SUMO: a lane position runs from 0 to the lane's ``length``
attribute, which may differ from the length of its shape (outer lanes of a curve,
internal lanes, edges with a custom length); SUMO maps between them by the factor
``length / shape length``, and so does this module.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import cached_property
from itertools import chain

import numpy as np
import sumolib

from csws.road.georef import GeoReferenced, finite_pairs
from csws.road.network import Lane, vertex_arc_length
from csws.road.search import LaneMatch, LaneMatches, LaneSearch, LaneShapes

__all__ = ["LaneMap"]


def _compressed_rows(rows: Sequence[Sequence[int]]) -> tuple[np.ndarray, np.ndarray]:
    """Ragged integer rows as (row start offsets, concatenated values)."""
    start = np.concatenate(([0], np.cumsum([len(row) for row in rows]))).astype(np.int64)
    return start, np.fromiter(chain.from_iterable(rows), dtype=np.int64, count=int(start[-1]))


class LaneMap(GeoReferenced):
    """Every lane of a SUMO network: attributes, shape and successors, with a spatial index of the shapes.

    Lanes are addressed by their SUMO id.

    Attributes
    ----------
    has_projection
        Whether the network is geo-referenced (see :meth:`xy_to_lonlat`).
    geo
        A sumolib net holding only the network's location, whose
        ``convertXY2LonLat`` / ``convertLonLat2XY`` do the geo-conversions.
    """

    def __init__(
        self,
        lanes: Sequence[Lane],
        xy: np.ndarray,
        vertex_start: np.ndarray,
        successors: Sequence[Sequence[int]],
        geo: sumolib.net.Net,
    ) -> None:
        """Hold the lanes in arrays.

        Parameters
        ----------
        lanes
            The lanes' attributes.
        xy
            Vertices of all lanes back to back, ``(n, 2)``, m.
        vertex_start
            Offset of each lane's first vertex in ``xy`` and ``n`` at the end, ``(len(lanes) + 1,)``.
        successors
            For each lane, the indices of the lanes a vehicle can drive onto from its end.
        geo
            A sumolib net carrying the network's location.
        """
        self.geo = geo
        self.has_projection = bool(geo.hasGeoProj())
        self._lanes = tuple(lanes)
        self._index = {lane.lane_id: i for i, lane in enumerate(self._lanes)}
        self._xy = np.ascontiguousarray(xy, dtype=float)
        self._vertex_start = np.asarray(vertex_start, dtype=np.int64)
        self._vertex_s = vertex_arc_length(self._xy, self._vertex_start)
        self._successor_start, self._successor_index = _compressed_rows(successors)
        self._successor_tables()

    # ----------------------------------------------------------------- lanes
    @cached_property
    def lane_ids(self) -> tuple[str, ...]:
        """Ids of all lanes, internal lanes included, in network order."""
        return tuple(lane.lane_id for lane in self._lanes)

    @property
    def vertex_count(self) -> int:
        """Number of shape vertices over all lanes."""
        return len(self._xy)

    @property
    def total_length_m(self) -> float:
        """Sum of the SUMO lengths of all lanes, m (lane-km x 1000)."""
        return float(sum(lane.length_m for lane in self._lanes))

    @cached_property
    def lane_shapes(self) -> LaneShapes:
        """The lanes' shapes back to back, in the order of :attr:`lane_ids`, as a spatial index of
        lanes takes them (:class:`csws.road.search.LaneSearch`; the arrays are the map's own)."""
        return LaneShapes(self._xy, self._vertex_start, self._vertex_s, self._lane_id_array, self._position_factor)

    def lane_index(self, lane_id: str) -> int:
        """The position of ``lane_id`` in :attr:`lane_ids`."""
        return self._lane_index(lane_id)

    def has_lane(self, lane_id: str) -> bool:
        """Whether ``lane_id`` is a lane of the map."""
        return lane_id in self._index

    def lane(self, lane_id: str) -> Lane:
        """The SUMO attributes of a lane (:class:`Lane`)."""
        return self._lanes[self._lane_index(lane_id)]

    def lane_shape(self, lane_id: str) -> np.ndarray:
        """The lane's polyline in driving direction, ``(n, 2)``, m (a read-only view)."""
        return self._shape(self._lane_index(lane_id))

    def successors(self, lane_id: str) -> tuple[str, ...]:
        """Lanes a vehicle can drive onto from the end of ``lane_id``.

        From a normal lane these are the internal via lanes of its connections (or the
        next normal lanes where a connection has no via lane); from an internal lane,
        the next internal lane or the normal lane it leads to.
        """
        try:
            return self._successors_by_id[lane_id]
        except KeyError:
            raise KeyError(f"no lane {lane_id!r} in the network") from None

    def _successor_tables(self) -> None:
        """Make the tables every path built reads with the map, so that its first look-ahead does not (some 20 ms on
        a city): each lane's successors by index (plain ints: a path's lanes are checked against them) and by id,
        the successors by lane id (one lookup at every step of every path built, for the map's lifetime), and
        whether each lane is internal."""
        ids = [lane.lane_id for lane in self._lanes]
        starts, indices = self._successor_start.tolist(), self._successor_index.tolist()
        self._successor_indices = tuple(tuple(indices[a:b]) for a, b in zip(starts[:-1], starts[1:], strict=False))
        self._successors_by_id = {
            lane_id: tuple(ids[i] for i in following)
            for lane_id, following in zip(ids, self._successor_indices, strict=True)
        }
        self._is_internal = tuple(lane.is_internal for lane in self._lanes)

    # ----------------------------------------------------------------- paths
    def expand_path(self, lane_ids: Sequence[str]) -> tuple[str, ...]:
        """The lanes of a path with the internal via lanes between consecutive lanes filled in.

        ``lane_ids`` may list only normal lanes (as a route does); where a lane does not
        lead directly to the next one, the chain of internal lanes of the connection
        between them is inserted.

        Raises
        ------
        ValueError
            If the path is empty or two consecutive lanes are not connected.
        """
        lane_ids_by_index = self.lane_ids
        return tuple(lane_ids_by_index[i] for i in self._expanded_indices(lane_ids))

    def _expanded_indices(self, lane_ids: Sequence[str]) -> list[int]:
        """The indices of the lanes of :meth:`expand_path`."""
        if not lane_ids:
            raise ValueError("a path needs at least one lane")
        indices = [self._lane_index(lane_ids[0])]
        for following_id in lane_ids[1:]:
            following = self._lane_index(following_id)
            via = self._via_chain(indices[-1], following)
            if via is None:
                raise ValueError(f"lane {following_id!r} does not follow lane {self._lanes[indices[-1]].lane_id!r}")
            indices += via + [following]
        return indices

    # ----------------------------------------------------------------- positions
    def match_points(self, xy: np.ndarray, radius_m: float) -> LaneMatches:
        """All lanes within ``radius_m`` of each of many positions, projected onto each lane.

        Parameters
        ----------
        xy
            Positions in network coordinates, ``(k, 2)``, m.
        radius_m
            Search radius, m (> 0).
        """
        if not (math.isfinite(radius_m) and radius_m > 0):
            raise ValueError(f"search radius must be a positive number of metres, got {radius_m!r}")
        return self._lane_search.match(finite_pairs(xy, "positions"), radius_m)

    def nearest_lanes(self, x: float, y: float, radius_m: float) -> list[LaneMatch]:
        """The lanes within ``radius_m`` of (x, y), nearest first (see :meth:`match_points`)."""
        return self.match_points(np.array([[x, y]]), radius_m).for_point(0)

    # ----------------------------------------------------------------- internals
    def _lane_index(self, lane_id: str) -> int:
        try:
            return self._index[lane_id]
        except KeyError:
            raise KeyError(f"no lane {lane_id!r} in the network") from None

    def _shape(self, lane: int) -> np.ndarray:
        view = self._xy[self._vertex_start[lane] : self._vertex_start[lane + 1]]
        view.flags.writeable = False
        return view

    def _via_chain(self, lane: int, following: int) -> list[int] | None:
        """Internal lanes leading from the end of ``lane`` to ``following`` ([] if adjacent, None if unreachable)."""
        successor_indices, is_internal = self._successor_indices, self._is_internal
        if following in successor_indices[lane]:
            return []
        frontier: list[tuple[int, list[int]]] = [(lane, [])]
        seen = {lane}
        while frontier:
            current, chain_so_far = frontier.pop()
            successors = successor_indices[current]
            if following in successors:
                return chain_so_far
            for nxt in successors:
                if is_internal[nxt] and nxt not in seen:
                    seen.add(nxt)
                    frontier.append((nxt, chain_so_far + [nxt]))
        return None

    @cached_property
    def _lane_id_array(self) -> np.ndarray:
        return np.array(self.lane_ids, dtype=object)

    @cached_property
    def _position_factor(self) -> np.ndarray:
        return np.array([lane.position_factor for lane in self._lanes])

    @cached_property
    def _lane_search(self) -> LaneSearch:
        """The spatial index of the lanes' shapes, built on the first position look-up."""
        return LaneSearch(self.lane_shapes)
