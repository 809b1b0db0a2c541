"""The lanes of the matched road maps as a graph: the route distances map matching weighs.

A hidden-Markov map matcher (:mod:`csws.road.hmm`) compares the distance driven along
the road between two candidate positions with the straight distance between the fixes.
Distances are measured on the graph of edges (a lane change within an edge costs no
distance), from the start of one edge to the start of another, and found once for every
edge and every edge reached from it within a reach (:attr:`LaneGraph.reach_m` beyond its
end), so a transition costs a look-up in a sorted array.

Each lane also knows what the matcher needs at a junction: for an internal lane, the
normal edge its connection comes from and the one it leads to, the normal lane it starts
from, and whether it turns off the road (:attr:`csws.road.network.Lane.continues_road`);
for every lane, the lane its road continues on (:attr:`csws.road.network.Lane.continues_into`).
Lanes and edges of several maps are numbered back to back, the lanes in the order of the
maps' :attr:`csws.road.roadmap.RoadMap.lane_ids` (as :class:`csws.road.matching.MapMatcher`
numbers them).
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from csws.road.roadmap import RoadMap

__all__ = ["LaneGraph"]


@dataclass(frozen=True)
class _Lanes:
    """Per lane of all maps: the columns a :class:`LaneGraph` is made of (built by :func:`_lanes_of`)."""

    edge: np.ndarray
    length_m: np.ndarray
    continuation: np.ndarray
    internal: np.ndarray
    turns: np.ndarray
    successors: list[list[int]]
    edge_count: int


def _lanes_of(road_maps: Sequence[RoadMap]) -> _Lanes:
    """The lanes of all maps numbered back to back, with their edges numbered back to back too."""
    edge, length_m, continuation, internal, turns, successors = [], [], [], [], [], []
    first_lane, first_edge = 0, 0
    for road_map in road_maps:
        index = {lane_id: number for number, lane_id in enumerate(road_map.lane_ids, start=first_lane)}
        edge_numbers: dict[str, int] = {}
        for lane_id in road_map.lane_ids:
            lane = road_map.lane(lane_id)
            edge.append(edge_numbers.setdefault(lane.edge_id, first_edge + len(edge_numbers)))
            length_m.append(lane.length_m)
            continuation.append(index.get(lane.continues_into, -1))
            internal.append(lane.is_internal)
            turns.append(lane.is_internal and not lane.continues_road)
            successors.append([index[following] for following in road_map.successors(lane_id)])
        first_lane += len(road_map.lane_ids)
        first_edge += len(edge_numbers)
    return _Lanes(
        np.array(edge, dtype=np.int64),
        np.array(length_m, dtype=float),
        np.array(continuation, dtype=np.intp),
        np.array(internal, dtype=bool),
        np.array(turns, dtype=bool),
        successors,
        first_edge,
    )


def _edge_reach(
    edge_successors: list[set[int]], edge_length_m: np.ndarray, reach_m: float
) -> tuple[np.ndarray, np.ndarray]:
    """Every pair (edge, edge reached from it within its length plus ``reach_m``) with the route
    distance from the first's start to the second's start, m: as sorted keys ``from * count + to``
    and their distances (an edge reaches itself at 0). One bounded Dijkstra search per edge."""
    count = len(edge_successors)
    lengths_m = edge_length_m.tolist()
    keys: list[int] = []
    offsets: list[float] = []
    for start in range(count):
        limit_m = lengths_m[start] + reach_m
        best = {start: 0.0}
        heap = [(0.0, start)]
        while heap:
            offset_m, edge = heapq.heappop(heap)
            beyond_m = offset_m + lengths_m[edge]
            if offset_m > best[edge] or beyond_m > limit_m:
                continue
            for following in edge_successors[edge]:
                if beyond_m < best.get(following, math.inf):
                    best[following] = beyond_m
                    heapq.heappush(heap, (beyond_m, following))
        keys += [start * count + edge for edge in best]
        offsets += best.values()
    key_array = np.array(keys, dtype=np.int64)
    order = np.argsort(key_array)
    return key_array[order], np.array(offsets, dtype=float)[order]


@dataclass(frozen=True)
class _JunctionEnds:
    """Where the connections through the junctions start and end (built by :func:`_junction_ends`).

    Attributes
    ----------
    entry, exit_lane
        Per internal lane: the normal lane its connection starts from and the one it leads to (-1 for normal
        lanes, and where none is found).
    first
        Per lane: whether it is the first internal lane of a connection (where the connection starts, at the end
        of the normal lane it comes from).
    links
        Sorted keys ``from * count + to`` of every pair of normal lanes joined by a connection.
    """

    entry: np.ndarray
    exit_lane: np.ndarray
    first: np.ndarray
    links: np.ndarray


def _junction_ends(lanes: _Lanes) -> _JunctionEnds:
    """Each connection's first and last normal lane, and the pairs of normal lanes the connections join."""
    count = len(lanes.edge)
    entry = np.full(count, -1, dtype=np.intp)
    exit_lane = np.full(count, -1, dtype=np.intp)
    first_lane = np.zeros(count, dtype=bool)
    links: list[int] = []
    for lane, following in enumerate(lanes.successors):
        if lanes.internal[lane]:
            continue
        for first in following:
            chain, current = [], first
            while lanes.internal[current] and current not in chain:
                chain.append(current)
                nexts = lanes.successors[current]
                if not nexts:
                    break
                current = nexts[0]
            reached = -1 if lanes.internal[current] else current
            entry[chain] = lane
            exit_lane[chain] = reached
            first_lane[chain[:1]] = True
            if reached >= 0:
                links.append(lane * count + reached)
    return _JunctionEnds(entry, exit_lane, first_lane, np.unique(np.array(links, dtype=np.int64)))


def _crossing_changes(lanes: _Lanes, ends: _JunctionEnds, entry_edge: np.ndarray, exit_edge: np.ndarray) -> np.ndarray:
    """Sorted keys ``from * count + to`` of every move between lanes of different edges that changes lanes
    (:meth:`LaneGraph.changes_lane`), found once so that a move costs one look-up: onto a connection from
    another lane of its incoming edge, off a connection onto a lane beside the one it leads to, or across a
    junction between normal lanes no connection joins although their edges are joined."""
    count = len(lanes.edge)
    edge_lanes: list[list[int]] = [[] for _ in range(lanes.edge_count)]
    for lane, edge in enumerate(lanes.edge.tolist()):
        edge_lanes[edge].append(lane)
    keys: list[int] = []
    for lane, (entry, incoming, exit_lane, outgoing) in enumerate(
        zip(ends.entry.tolist(), entry_edge.tolist(), ends.exit_lane.tolist(), exit_edge.tolist(), strict=True)
    ):
        if incoming >= 0:
            keys += [beside * count + lane for beside in edge_lanes[incoming] if beside != entry]
        if outgoing >= 0:
            keys += [lane * count + beside for beside in edge_lanes[outgoing] if beside != exit_lane]
    linked = set(ends.links.tolist())
    internal = lanes.internal.tolist()
    for edge_key in np.unique(lanes.edge[ends.links // count] * lanes.edge_count + lanes.edge[ends.links % count]):
        from_edge, to_edge = divmod(int(edge_key), lanes.edge_count)
        if from_edge == to_edge:
            continue
        keys += [
            a * count + b
            for a in edge_lanes[from_edge]
            for b in edge_lanes[to_edge]
            if not internal[a] and not internal[b] and a * count + b not in linked
        ]
    return np.unique(np.array(keys, dtype=np.int64))


#: The key after every sorted array of keys here, so that a search never runs past the end.
_BEYOND_KEYS = np.iinfo(np.int64).max


def _within(keys: np.ndarray, sorted_keys: np.ndarray) -> np.ndarray:
    """Whether each of ``keys`` is one of ``sorted_keys`` (ending in :data:`_BEYOND_KEYS`)."""
    return sorted_keys[sorted_keys.searchsorted(keys)] == keys


class LaneGraph:
    """The lanes of one or more road maps as a graph of edges with route distances within a reach.

    Parameters
    ----------
    road_maps
        The maps, numbered as :class:`csws.road.matching.MapMatcher` numbers them.
    reach_m
        Route distances are known from an edge to every edge reached within this distance
        beyond its end, m: at least what a vehicle drives between two fixes.
    """

    def __init__(self, road_maps: Sequence[RoadMap], reach_m: float) -> None:
        lanes = _lanes_of(road_maps)
        self.reach_m = reach_m
        #: Per lane: its edge, SUMO length (m), the lane its road continues on (-1: none), whether it
        #: lies in a junction, whether it turns off the road there.
        self.lane_edge, self.lane_length_m, self.continuation = lanes.edge, lanes.length_m, lanes.continuation
        self.internal, self.turns = lanes.internal, lanes.turns
        #: Per edge: how many lanes it has.
        self.edge_lane_count = np.bincount(lanes.edge, minlength=lanes.edge_count)
        #: Per internal lane: the normal lane it starts from and the normal lane and edge it leads to (-1 otherwise).
        ends = _junction_ends(lanes)
        self.entry_lane, self.exit_lane = ends.entry, ends.exit_lane
        #: Per lane: whether it is the first internal lane of a connection.
        self.connection_start = ends.first
        self.entry_edge = np.where(self.entry_lane >= 0, lanes.edge[np.maximum(self.entry_lane, 0)], -1)
        self.exit_edge = np.where(self.exit_lane >= 0, lanes.edge[np.maximum(self.exit_lane, 0)], -1)
        self._crossing_changes = np.append(
            _crossing_changes(lanes, ends, self.entry_edge, self.exit_edge), _BEYOND_KEYS
        )
        self._successors = lanes.successors
        self._edge_count = lanes.edge_count
        edge_length_m = np.zeros(lanes.edge_count)
        np.maximum.at(edge_length_m, lanes.edge, lanes.length_m)
        edge_successors: list[set[int]] = [set() for _ in range(lanes.edge_count)]
        lane_edge = lanes.edge.tolist()
        for lane, following in enumerate(lanes.successors):
            edge_successors[lane_edge[lane]].update(lane_edge[f] for f in following)
        reach_key, reach_offset_m = _edge_reach(edge_successors, edge_length_m, reach_m)
        self._reach_key = np.append(reach_key, _BEYOND_KEYS)
        self._reach_offset_m = np.append(reach_offset_m, np.nan)

    def _offsets_m(self, from_edge: np.ndarray, to_edge: np.ndarray) -> np.ndarray:
        """Route distance from the start of each ``from_edge`` to the start of its ``to_edge``, m; NaN
        beyond the reach."""
        key = from_edge * self._edge_count + to_edge
        at = self._reach_key.searchsorted(key)
        return np.where(self._reach_key[at] == key, self._reach_offset_m[at], np.nan)

    def route_m(
        self, from_lane: np.ndarray, from_pos_m: np.ndarray, to_lane: np.ndarray, to_pos_m: np.ndarray
    ) -> np.ndarray:
        """The distance driven along the road from each lane position to its counterpart, m: negative
        for a position behind (GNSS noise moving a stopped vehicle back), NaN where neither is
        reached from the other within the reach (or they lie on different maps)."""
        from_edge, to_edge = self.lane_edge[from_lane], self.lane_edge[to_lane]
        offsets_m = self._offsets_m(np.concatenate((from_edge, to_edge)), np.concatenate((to_edge, from_edge)))
        ahead_m = offsets_m[: len(from_edge)] - from_pos_m + to_pos_m
        behind_m = -(offsets_m[len(from_edge) :] - to_pos_m + from_pos_m)
        return np.where(np.isnan(ahead_m), behind_m, ahead_m)

    def changes_lane(self, from_lane: np.ndarray, to_lane: np.ndarray) -> np.ndarray:
        """Whether moving from each lane to its counterpart changes lanes: to another lane of the same edge, or
        across a junction onto a connection (or the lane beyond it) that another lane of the edge leads to,
        not this one (a vehicle keeps its lane through a junction unless it changes it)."""
        within_edge = (self.lane_edge[from_lane] == self.lane_edge[to_lane]) & (from_lane != to_lane)
        return within_edge | _within(from_lane * len(self.lane_edge) + to_lane, self._crossing_changes)

    def advance(self, lane: int, lane_pos_m: float, distance_m: float) -> tuple[int, float]:
        """The lane position ``distance_m`` further along the road from ``lane_pos_m`` on ``lane``: on
        through the lanes the road continues on (or a lane's only successor); at the end of the last
        lane where the road ends or splits without a continuation (never a guessed turn)."""
        position_m = lane_pos_m + max(distance_m, 0.0)
        seen = {lane}
        while position_m > self.lane_length_m[lane]:
            following = int(self.continuation[lane])
            if following < 0 and len(self._successors[lane]) == 1:
                following = self._successors[lane][0]
            if following < 0 or following in seen:
                return lane, float(self.lane_length_m[lane])
            position_m -= float(self.lane_length_m[lane])
            lane = following
            seen.add(lane)
        return lane, position_m
