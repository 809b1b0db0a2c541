"""Chooses the lane a fix-fed vehicle's path ahead starts from: the lane of its edge that keeps the road.

A GNSS fix cannot tell the lanes of one edge apart: they lie some 3.2 m apart and a fleet's fixes
are off by 3 to 8 m. The lane a fix is matched to is then a guess, and so is the path ahead of
that lane: the rightmost lane of a motorway may lead onto an exit ramp alone, a turning lane into
a side street, and a path from it would warn of the ramp's curve a vehicle on the through road
never meets. The path ahead of a fix is therefore the path ahead of its edge (:class:`RoadLanes`):
it starts from the lane of the edge whose path goes farthest along the road's own continuation
(:attr:`csws.road.network.Lane.continues_road`, :mod:`csws.road.continuations`) before it turns
off it, the matched lane where none goes farther. A ramp or a turn counts once a fix is matched
onto it: the path then starts on the ramp. A vehicle that gives its lane (the co-simulation, a
unit that knows its lane) keeps the path of its lane.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence

from csws.ahead.lookahead import LookAhead
from csws.road.roadmap import Lane, RoadMap
from csws.warning.rules import PathKind

__all__ = ["ROAD_LANE_REACH_M", "RoadLanes"]

#: How far ahead the lanes of an edge are compared, m: beyond the longest look-ahead distance S_LAD (3.9) a
#: vehicle needs at motorway speed (formula (1) at 130 km/h with V_w = 0 and a second of latency: some 200 m).
ROAD_LANE_REACH_M = 500.0
#: Two lanes whose paths keep the road for lengths this close keep it equally far, m.
_TIE_M = 1.0
#: Choices remembered before the memory is emptied (a choice depends on the map and route alone).
_MEMORY = 65_536


class RoadLanes:
    """The lane each fix-fed vehicle's path ahead starts from, and its position on it.

    Parameters
    ----------
    lookahead
        The look-ahead whose paths are compared (its most probable successor at each junction).
    reach_m
        How far ahead the lanes of an edge are compared, m.
    """

    def __init__(self, lookahead: LookAhead, reach_m: float = ROAD_LANE_REACH_M) -> None:
        self.lookahead = lookahead
        self.road_map: RoadMap = lookahead.road_map
        self.reach_m = reach_m
        self._chosen: dict[tuple[str, tuple[str, ...] | None], str] = {}
        self._edge_lanes: dict[str, list[str]] | None = None

    def __call__(
        self, lane_id: str, lane_pos_m: float, route_edges: Sequence[str] | None = None
    ) -> tuple[str, float]:
        """The lane of ``lane_id``'s edge the path ahead starts from and the position on it, m (the same fraction
        of its length): the lane whose path keeps the road farthest, ``lane_id`` itself where none goes farther.

        Raises
        ------
        KeyError
            If ``lane_id`` is not a lane of the map.
        """
        key = (lane_id, tuple(route_edges) if route_edges else None)
        chosen = self._chosen.get(key)
        if chosen is None:
            if len(self._chosen) >= _MEMORY:
                self._chosen.clear()
            chosen = self._chosen[key] = self._road_lane(lane_id, key[1])
        if chosen == lane_id:
            return lane_id, lane_pos_m
        matched, road = self.road_map.lane(lane_id), self.road_map.lane(chosen)
        fraction = lane_pos_m / matched.length_m if matched.length_m > 0 else 0.0
        return chosen, min(max(fraction, 0.0), 1.0) * road.length_m

    def _road_lane(self, lane_id: str, route_edges: tuple[str, ...] | None) -> str:
        """:meth:`__call__`'s lane worked out: the sibling lanes ranked by how far their paths keep the road."""
        matched = self.road_map.lane(lane_id)
        if matched.is_internal:
            return lane_id
        siblings = [
            sibling
            for sibling in self._lanes_of(matched.edge_id)
            if sibling == lane_id or _shares_a_class(matched, self.road_map.lane(sibling))
        ]
        if len(siblings) < 2:
            return lane_id
        kept_m = {sibling: self.road_kept_m(sibling, route_edges) for sibling in siblings}
        farthest_m = max(kept_m.values())
        if kept_m[lane_id] >= farthest_m - _TIE_M:
            return lane_id
        best = [sibling for sibling in siblings if kept_m[sibling] >= farthest_m - _TIE_M]
        return min(best, key=lambda sibling: abs(self.road_map.lane(sibling).index - matched.index))

    def road_kept_m(self, lane_id: str, route_edges: Sequence[str] | None = None) -> float:
        """How far the path ahead of the start of ``lane_id`` keeps to the road, up to the reach, m: along a route,
        as far as it goes; predicted, as far as its first turn off the road (a junction connection that is not
        the road's continuation), since the predicted path is to follow the road, never a guessed turn."""
        lane = self.road_map.lane(lane_id)
        lanes, kind = self.lookahead.lanes_ahead(lane_id, lane.length_m, lane.length_m + self.reach_m, route_edges)
        kept_m, previous = lane.length_m, lane
        for following_id in lanes[1:]:
            following = self.road_map.lane(following_id)
            if kind is PathKind.PREDICTED and not _keeps_road(previous, following):
                break
            kept_m += following.length_m
            previous = following
        return min(kept_m, lane.length_m + self.reach_m)

    def _lanes_of(self, edge_id: str) -> list[str]:
        """The lanes of a normal edge, rightmost first (all edges indexed at the first call)."""
        if self._edge_lanes is None:
            by_edge: dict[str, list[Lane]] = defaultdict(list)
            for lane_id in self.road_map.lane_ids:
                lane = self.road_map.lane(lane_id)
                if not lane.is_internal:
                    by_edge[lane.edge_id].append(lane)
            self._edge_lanes = {
                edge: [lane.lane_id for lane in sorted(lanes, key=lambda lane: lane.index)]
                for edge, lanes in by_edge.items()
            }
        return self._edge_lanes[edge_id]


def _keeps_road(previous: Lane, following: Lane) -> bool:
    """Whether the step from ``previous`` onto ``following`` keeps to the road: onto a connection that continues it,
    off such a connection, or from a normal lane straight onto the lane its road continues on."""
    if following.is_internal:
        return following.continues_road
    if previous.is_internal:
        return previous.continues_road
    return previous.continues_into == following.lane_id


def _shares_a_class(lane: Lane, other: Lane) -> bool:
    """Whether two lanes allow a vehicle class in common (a sidewalk or a bus lane is no lane of a lorry)."""
    return bool(lane.allowed_vclasses & other.allowed_vclasses)
