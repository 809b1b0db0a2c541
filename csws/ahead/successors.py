"""Chooses the lane a path ahead goes on to where a lane leads to several: the one that keeps to the road.

At a junction a lane leads on to one lane or to several: a crossing's straight-ahead and turning
connections, and, at a lane split, two lanes of the road's next stretch of which one may lead on
alone onto an exit ramp or a turning lane a hundred metres further (a single lane of a primary
road widening into two before a slip road leaves it). The path ahead takes (:class:`SuccessorChoice`):

* without a route, a successor whose way on keeps to the road over the path's reach
  (:meth:`SuccessorChoice.goes_on`), the road being its own continuation through each junction
  (:func:`keeps_road`, :mod:`csws.road.continuations`): at a lane split the lane that goes on as the
  road, never the one that leads off it a junction or two on, whatever their angles. Among those (or
  among all where none does: the vehicle's own lane leads only off the road, a turn-only lane, and
  its turn is truly ahead), the road's continuation through the junction
  (:attr:`csws.road.network.Lane.continues_road`), then the same street name, then road type, then the
  least turning;
* with a route, among the successors leading to the route's next edge, one whose way on follows the
  route over the reach (a lane that leads only onto a ramp the route does not take would end the path
  there), then as without one.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from csws.geometry import wrap_angle_rad
from csws.road.roadmap import Lane, RoadMap

__all__ = ["SuccessorChoice", "keeps_road"]

#: ``edge -> the route's next edge`` from a vehicle's edge on (None: no route, the path is predicted).
RouteNext = Mapping[str, str] | None


def keeps_road(previous: Lane, following: Lane) -> bool:
    """Whether the step from ``previous`` onto ``following`` keeps to the road: onto a connection that continues it,
    off such a connection, or from a normal lane straight onto the lane its road continues on."""
    if following.is_internal:
        return following.continues_road
    if previous.is_internal:
        return previous.continues_road
    return previous.continues_into == following.lane_id


class SuccessorChoice:
    """The lane a path goes on to after each lane, along a route or predicted (see the module's description).

    Parameters
    ----------
    road_map
        The map.
    reach_m
        How far beyond a successor's start its way on is followed, m: as far as a path ahead is looked along.
    max_lanes
        A way on is followed over at most this many lanes (guards against loops of tiny lanes).
    """

    def __init__(self, road_map: RoadMap, reach_m: float, max_lanes: int) -> None:
        self.road_map = road_map
        self.reach_m = reach_m
        self.max_lanes = max_lanes
        self._predicted: dict[tuple[str, tuple[str, ...]], str] = {}
        self._toward_edge: dict[tuple[str, str], tuple[str, ...]] = {}

    def following(self, lane_id: str, route_next: RouteNext) -> str | None:
        """The lane after ``lane_id``: along the route if there is one (None where it ends or cannot be followed),
        else the most probable; None where nothing follows."""
        successors = self.road_map.successors(lane_id)
        if not successors:
            return None
        if route_next is None:
            return self._predicted_successor(lane_id, successors)
        candidates = self._route_lanes(lane_id, successors, route_next)
        if not candidates:
            return None
        return candidates[0] if len(candidates) == 1 else self._most_probable(lane_id, candidates, route_next)

    def leads_to_edge(self, lane_id: str, edge_id: str) -> bool:
        """Whether ``lane_id`` is on ``edge_id`` or is an internal lane whose chain ends on it."""
        for _ in range(self.max_lanes):
            lane = self.road_map.lane(lane_id)
            if not lane.is_internal:
                return lane.edge_id == edge_id
            successors = self.road_map.successors(lane_id)
            if len(successors) != 1:
                return False
            lane_id = successors[0]
        return False

    def goes_on(self, lane_id: str, candidate: str, route_next: RouteNext) -> bool:
        """Whether a way on from ``lane_id`` through its successor ``candidate`` keeps to the road (without a route)
        or follows the route over the whole reach from the candidate's start, or until the road or the route ends
        (nothing to turn into there); not where the step onto the candidate already leaves it."""
        onward = self._onward(lane_id, route_next)
        if onward is not None and candidate not in onward:
            return False
        return self._goes_on_through(candidate, route_next, self.reach_m, 0)

    def _goes_on_through(self, lane_id: str, route_next: RouteNext, budget_m: float, depth: int) -> bool:
        """Whether a way on through ``lane_id`` keeps to the road or route for ``budget_m`` from the lane's start."""
        length_m = self.road_map.lane(lane_id).length_m
        onward = self._onward(lane_id, route_next)
        if length_m >= budget_m or onward is None or depth >= self.max_lanes:
            return True
        return any(self._goes_on_through(following, route_next, budget_m - length_m, depth + 1) for following in onward)

    def _onward(self, lane_id: str, route_next: RouteNext) -> Sequence[str] | None:
        """The successors of ``lane_id`` that keep to the road (without a route) or lead along the route; None
        where the road or the route ends at the lane's end."""
        successors = self.road_map.successors(lane_id)
        if not successors:
            return None
        if route_next is None:
            lane = self.road_map.lane(lane_id)
            return [s for s in successors if keeps_road(lane, self.road_map.lane(s))]
        return self._route_lanes(lane_id, successors, route_next)

    def _route_lanes(
        self, lane_id: str, successors: Sequence[str], route_next: Mapping[str, str]
    ) -> Sequence[str] | None:
        """The successors of ``lane_id`` that lead along the route (all of an internal lane's); None where the route
        ends at the lane's edge. Which lead to an edge depends on the map alone, so it is remembered."""
        lane = self.road_map.lane(lane_id)
        if lane.is_internal:
            return successors
        next_edge = route_next.get(lane.edge_id)
        if next_edge is None:
            return None
        toward = self._toward_edge.get((lane_id, next_edge))
        if toward is None:
            toward = self._toward_edge[(lane_id, next_edge)] = tuple(
                s for s in successors if self.leads_to_edge(s, next_edge)
            )
        return toward

    def _predicted_successor(self, lane_id: str, successors: Sequence[str]) -> str:
        """The most probable successor without a route (it depends on the map alone, so it is remembered)."""
        if len(successors) == 1:
            return successors[0]
        key = (lane_id, tuple(successors))
        chosen = self._predicted.get(key)
        if chosen is None:
            chosen = self._predicted[key] = self._most_probable(lane_id, successors, None)
        return chosen

    def _most_probable(self, lane_id: str, candidates: Sequence[str], route_next: RouteNext) -> str:
        """The candidate whose way on keeps to the road (or follows the route) over the reach, then the road's
        continuation through the junction, then the same street name, then road type, then the least turning."""
        current = self.road_map.lane(lane_id)
        heading_out = _lane_end_heading(self.road_map.lane_shape(lane_id), -1)

        def preference(candidate: str) -> tuple[bool, bool, bool, bool, float]:
            destination = self.road_map.lane(self._destination(candidate))
            turning = abs(wrap_angle_rad(_lane_end_heading(self.road_map.lane_shape(candidate), 0) - heading_out))
            return (
                not self.goes_on(lane_id, candidate, route_next),
                not self.road_map.lane(candidate).continues_road,
                not (current.street_name and destination.street_name == current.street_name),
                not (current.road_type and destination.road_type == current.road_type),
                turning,
            )

        return min(candidates, key=preference)

    def _destination(self, lane_id: str) -> str:
        """The first normal lane reached from ``lane_id`` (itself when it is normal)."""
        for _ in range(self.max_lanes):
            if not self.road_map.lane(lane_id).is_internal:
                return lane_id
            successors = self.road_map.successors(lane_id)
            if not successors:
                return lane_id
            lane_id = successors[0]
        return lane_id


def _lane_end_heading(shape: np.ndarray, end: int) -> float:
    """Heading of a lane's first (``end=0``) or last (``end=-1``) segment, radians."""
    if len(shape) < 2:
        return 0.0
    dx, dy = shape[1] - shape[0] if end == 0 else shape[-1] - shape[-2]
    return math.atan2(dy, dx)
