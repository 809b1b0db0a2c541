"""Chooses the lane a fix-fed vehicle's path ahead starts from: the lane of its edge that keeps the road.

A GNSS fix cannot tell the lanes of one edge apart: they lie some 3.2 m apart and a fleet's fixes
are off by 3 to 8 m. The lane a fix is matched to is then a guess, and so is the path ahead of
that lane: the rightmost lane of a motorway may lead onto an exit ramp alone, a turning lane into
a side street, and a path from it would warn of the ramp's curve a vehicle on the through road
never meets. The path ahead of a fix is therefore the path ahead of its edge (:class:`RoadLanes`):
where the matched lane's path turns off the road at the edge's end, or at a junction within 200 m past it
(a junction connection that is not the road's continuation, :attr:`csws.road.network.Lane.continues_road`,
:mod:`csws.road.continuations`; the right lane of a motorway whose next stretch, metres long, splits onto
an exit ramp) while other lanes of the edge keep the road, it starts from the nearest of those instead, unless more
of the edge's lanes lead into that turn than keep the road (then the turn is where the road's traffic
goes, and the matched lane keeps its path). A ramp or a turn counts once a fix is matched onto it:
the path then starts on the ramp. With a route the path starts from a lane that leads along it. A
vehicle that gives its lane (the co-simulation, a unit that knows its lane) keeps its lane's path.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence

from csws.ahead.lookahead import LookAhead
from csws.ahead.successors import keeps_road
from csws.road.roadmap import Lane, RoadMap

__all__ = ["RoadLanes"]

#: A path is followed this far beyond its first lane to find the edge it leads to across the junction, m.
_ACROSS_M = 200.0
#: Choices remembered before the memory is emptied (a choice depends on the map and route alone).
_MEMORY = 65_536


class RoadLanes:
    """The lane each fix-fed vehicle's path ahead starts from, and its position on it.

    Parameters
    ----------
    lookahead
        The look-ahead whose paths are followed (its most probable successor at each junction).
    """

    def __init__(self, lookahead: LookAhead) -> None:
        self.lookahead = lookahead
        self.road_map: RoadMap = lookahead.road_map
        self._chosen: dict[tuple[str, tuple[str, ...] | None], str] = {}
        self._edge_lanes: dict[str, list[str]] | None = None

    def __call__(self, lane_id: str, lane_pos_m: float, route_edges: Sequence[str] | None = None) -> tuple[str, float]:
        """The lane of ``lane_id``'s edge the path ahead starts from and the position on it, m (the same fraction
        of its length): ``lane_id`` itself unless its path turns off the road, or leaves the route, where a
        lane of the edge beside it would not (see the module's description).

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
        """:meth:`__call__`'s lane worked out from where each lane of the edge leads at the edge's end."""
        matched = self.road_map.lane(lane_id)
        if matched.is_internal:
            return lane_id
        siblings = [
            sibling
            for sibling in self._lanes_of(matched.edge_id)
            if sibling == lane_id or _shares_a_class(matched, self.road_map.lane(sibling))
        ]
        leads = {sibling: self.leads_to(sibling, route_edges) for sibling in siblings}
        next_edge, keeps = leads[lane_id]
        if route_edges:  # the route says where the vehicle goes: a lane that leads there
            along = [sibling for sibling in siblings if leads[sibling][0] is not None]
            return lane_id if next_edge is not None or not along else _nearest(self.road_map, matched, along)
        on_road = [sibling for sibling in siblings if leads[sibling][1]]
        taking_the_turn = sum(next_edge is not None and leads[sibling][0] == next_edge for sibling in siblings)
        if keeps or not on_road or taking_the_turn > len(on_road):
            return lane_id
        return _nearest(self.road_map, matched, on_road)

    def leads_to(self, lane_id: str, route_edges: Sequence[str] | None = None) -> tuple[str | None, bool]:
        """Where the path ahead of ``lane_id`` (along the route, else predicted) goes within :data:`_ACROSS_M` of the
        lane's end: the edge it turns into where it leaves the road (a junction connection that is a turn), else
        the edge it reaches at the lane's end (None where it ends there); and whether it keeps the road.

        A lane that keeps the road across the first junction but is the one lane of the next edge that turns off
        it (the right lane of a motorway whose next stretch, a few metres long, splits onto an exit ramp) leads
        into that turn: a fix cannot tell that lane from its neighbour any better than the next one's."""
        lane = self.road_map.lane(lane_id)
        lanes, _ = self.lookahead.lanes_ahead(lane_id, lane.length_m, lane.length_m + _ACROSS_M, route_edges)
        previous, next_edge = lane, None
        for following_id in lanes[1:]:
            following = self.road_map.lane(following_id)
            if not keeps_road(previous, following):
                return self._edge_after(lanes, following_id), False
            if next_edge is None and not following.is_internal:
                next_edge = following.edge_id
            previous = following
        return next_edge, next_edge is not None

    def _edge_after(self, lanes: Sequence[str], lane_id: str) -> str | None:
        """The first normal lane's edge in ``lanes`` from ``lane_id`` on (None if there is none)."""
        for following_id in lanes[lanes.index(lane_id) :]:
            following = self.road_map.lane(following_id)
            if not following.is_internal:
                return following.edge_id
        return None

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


def _nearest(road_map: RoadMap, matched: Lane, lanes: Sequence[str]) -> str:
    """The lane of ``lanes`` nearest ``matched`` by lane index (the rightmost of two as near)."""
    return min(lanes, key=lambda lane_id: abs(road_map.lane(lane_id).index - matched.index))


def _shares_a_class(lane: Lane, other: Lane) -> bool:
    """Whether two lanes allow a vehicle class in common (a sidewalk or a bus lane is no lane of a lorry)."""
    return bool(lane.allowed_vclasses & other.allowed_vclasses)
