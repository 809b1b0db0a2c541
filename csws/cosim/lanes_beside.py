"""The curves on the lanes beside a path: what a vehicle that changes lanes while asleep may meet.

A sleeping vehicle is not read (:mod:`csws.cosim.schedule`), so nothing sees it change lanes. SUMO keeps
a vehicle on its route's edges, but not on the lanes of the path it fell asleep on: it may change to any
lane of an edge, and so cross a junction by another of the internal lanes that join the same two edges.
Where the lanes of a road share their curves (the road model fits a road once and offsets its lanes from
it), the schedule's lane-change margin covers their small differences in length. Where they do not, a
curve beside the path may start far earlier than any on it: a lane fitted on its own (its shape leaves
its road's), or an internal lane whose turn its neighbours do not make.

So a vehicle sleeps towards the first curve of its path *or of the lanes beside it*
(:meth:`LanesBeside.spans_s`): for each lane of the path, the curves of the other lanes of its edge, at
the same lane positions (SUMO gives every lane of a normal edge the edge's length, and a lane change keeps
the lane position), and for an internal lane the curves of every other internal lane between the same two
edges, taken to cover the whole internal lane (their lengths differ, and a way through a junction may have
one internal lane or two). A lane's position runs faster or slower than its own arc length (its position
factor): a curve beside the path is placed where it starts at the larger of the two lanes' factors and ends
at the smaller, so that it is never farther, nor ends sooner, on the path than on its own lane. Sidewalks
(lanes open to pedestrians alone) are beside no lane. A curve beside the path only keeps a vehicle awake
sooner; it never changes an answer.

Not covered: a vehicle overtaking on the opposite direction's lane (a network with ``<neigh>`` lanes) leaves
its route's edges for a while.
"""

from __future__ import annotations

import numpy as np

from csws.ahead.lookahead import LookAhead
from csws.road.path import PathProfile
from csws.road.roadmap import RoadMap

__all__ = ["LanesBeside"]

#: Vehicle classes that make no lane a vehicle changes onto: a lane open to these alone is a sidewalk.
_NO_VEHICLE = frozenset({"pedestrian"})
#: The most internal lanes on one way through a junction (SUMO makes two at most: a via lane after the first).
_MOST_INTERNAL = 8


class LanesBeside:
    """The curves of the lanes beside each lane of a path, found with a look-ahead's R_c and junction setting.

    Parameters
    ----------
    lookahead
        The look-ahead whose horizons the vehicles sleep along: its road map, R_c and whether it offers the
        curves of junction manoeuvres.
    """

    def __init__(self, lookahead: LookAhead) -> None:
        self.road_map = lookahead.road_map
        self.warning_radius_m = lookahead.settings.warning_radius_m
        self.junctions = lookahead.settings.warn_at_junctions
        self._beside = _lanes_beside(self.road_map)
        self._spans: dict[str, tuple[float, tuple[tuple[float, float], ...]]] = {}

    def beside(self, lane_id: str) -> tuple[str, ...]:
        """The lanes a vehicle on ``lane_id`` may be on instead at that place of its route, unseen: the other lanes
        of its normal edge, or the other internal lanes between the same two edges (a way's via lane among them);
        none for a lane alone on its edge."""
        return self._beside.get(lane_id, ())

    def spans_s(self, path: PathProfile) -> tuple[np.ndarray, np.ndarray]:
        """Where the curves of the lanes beside ``path``'s lanes start and end, in the path's arc length, m
        (two arrays of one length; empty where no lane of the path has a lane beside it with a curve)."""
        starts: list[float] = []
        ends: list[float] = []
        lane_start_s, shape_m = path.lane_start_s.tolist(), path.lane_shape_length_m.tolist()
        factors = path.lane_position_factor.tolist()
        for lane_id, start_s, length_m, factor in zip(path.lane_ids, lane_start_s, shape_m, factors, strict=True):
            others = self._beside.get(lane_id)
            if not others:
                continue
            internal = self.road_map.lane(lane_id).is_internal
            for other in others:
                other_factor, spans = self._factor_and_spans(other)
                larger, smaller = max(factor, other_factor), min(factor, other_factor)
                for begin_m, end_m in spans:
                    if internal:  # another length: the curve covers the whole internal lane
                        starts.append(start_s)
                        ends.append(start_s + length_m)
                    elif smaller > 0.0:
                        starts.append(start_s + min(max(begin_m / larger, 0.0), length_m))
                        ends.append(start_s + min(max(end_m / smaller, 0.0), length_m))
        return np.array(starts, dtype=float), np.array(ends, dtype=float)

    def _factor_and_spans(self, lane_id: str) -> tuple[float, tuple[tuple[float, float], ...]]:
        """A lane's position factor (lane position per metre of its shape), and where the curves on it start and
        end in its lane positions, m (the look-ahead's curves of the lane alone: those that run on from an
        earlier lane start at 0), worked out once per lane."""
        found = self._spans.get(lane_id)
        if found is None:
            path = self.road_map.path_profile((lane_id,))
            factor = float(path.lane_position_factor[0])
            found = self._spans[lane_id] = (
                factor,
                tuple(
                    (curve.start_s * factor, curve.end_s * factor)
                    for curve, _, _ in path.curve_sources(self.warning_radius_m, self.junctions)
                ),
            )
        return found


def _lanes_beside(road_map: RoadMap) -> dict[str, tuple[str, ...]]:
    """Per lane with a lane beside it, those lanes: the other lanes of its normal edge, or the other internal lanes
    between the same two edges, that a vehicle may drive on (not sidewalks)."""
    groups: dict[object, list[str]] = {}
    for lane_id in road_map.lane_ids:
        lane = road_map.lane(lane_id)
        if not lane.is_internal and not lane.allowed_vclasses <= _NO_VEHICLE:
            groups.setdefault(lane.edge_id, []).append(lane_id)
    for edges, lane_id in _internal_ways(road_map):
        if not road_map.lane(lane_id).allowed_vclasses <= _NO_VEHICLE:
            groups.setdefault(edges, []).append(lane_id)
    return {
        lane_id: tuple(other for other in lanes if other != lane_id)
        for lanes in groups.values()
        if len(lanes) > 1
        for lane_id in lanes
    }


def _internal_ways(road_map: RoadMap) -> list[tuple[tuple[str, str], str]]:
    """Each internal lane reached from a normal lane, with the normal edge its way through the junction leaves
    and the one it reaches."""
    found: dict[str, tuple[str, str]] = {}
    for lane_id in road_map.lane_ids:
        lane = road_map.lane(lane_id)
        if lane.is_internal:
            continue
        for first in road_map.successors(lane_id):
            way = [first]
            while road_map.lane(way[-1]).is_internal and len(way) <= _MOST_INTERNAL:
                following = road_map.successors(way[-1])
                if len(following) != 1:
                    break
                way.append(following[0])
            end = road_map.lane(way[-1])
            if end.is_internal:
                continue
            for internal in way[:-1]:
                found.setdefault(internal, (lane.edge_id, end.edge_id))
    return [(edges, lane_id) for lane_id, edges in found.items()]
