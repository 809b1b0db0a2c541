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
the same lane positions (SUMO gives every lane of a normal edge the edge's length, so a lane change keeps
the lane position), and for an internal lane the curves of the other internal lanes between the same two
edges at the same place in the junction, taken to cover the whole internal lane (their lengths differ).
A curve beside the path only keeps a vehicle awake sooner; it never changes an answer.
"""

from __future__ import annotations

import numpy as np

from csws.ahead.lookahead import LookAhead
from csws.road.path import PathProfile
from csws.road.roadmap import RoadMap

__all__ = ["LanesBeside"]

#: An internal lane's place: the normal edge its connection leaves, the one it reaches, and its rank on the way.
InternalPlace = tuple[str, str, int]
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
        self._spans: dict[str, tuple[tuple[float, float], ...]] = {}

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
            for begin_m, end_m in (span for other in others for span in self._lane_spans(other)):
                if internal:  # another length: the curve covers the whole internal lane
                    starts.append(start_s)
                    ends.append(start_s + length_m)
                elif factor > 0.0:
                    starts.append(start_s + min(max(begin_m / factor, 0.0), length_m))
                    ends.append(start_s + min(max(end_m / factor, 0.0), length_m))
        return np.array(starts, dtype=float), np.array(ends, dtype=float)

    def _lane_spans(self, lane_id: str) -> tuple[tuple[float, float], ...]:
        """Where the curves on ``lane_id`` start and end, in its lane positions, m (the look-ahead's curves of
        the lane alone: those that run on from an earlier lane start at 0), worked out once per lane."""
        spans = self._spans.get(lane_id)
        if spans is None:
            path = self.road_map.path_profile((lane_id,))
            factor = float(path.lane_position_factor[0])
            spans = self._spans[lane_id] = tuple(
                (curve.start_s * factor, curve.end_s * factor)
                for curve, _, _ in path.curve_sources(self.warning_radius_m, self.junctions)
            )
        return spans


def _lanes_beside(road_map: RoadMap) -> dict[str, tuple[str, ...]]:
    """Per lane with a lane beside it, those lanes: the other lanes of its normal edge, or the other internal lanes
    at its place in a junction (:data:`InternalPlace`), that allow a vehicle class it allows (a vehicle changes
    only onto a lane open to it: a sidewalk is beside no carriageway)."""
    groups: dict[object, list[str]] = {}
    for lane_id in road_map.lane_ids:
        lane = road_map.lane(lane_id)
        if not lane.is_internal:
            groups.setdefault(lane.edge_id, []).append(lane_id)
    for place, lane_id in _internal_places(road_map):
        groups.setdefault(place, []).append(lane_id)
    classes = {lane_id: road_map.lane(lane_id).allowed_vclasses for lanes in groups.values() for lane_id in lanes}
    beside = {
        lane_id: tuple(other for other in lanes if other != lane_id and classes[lane_id] & classes[other])
        for lanes in groups.values()
        if len(lanes) > 1
        for lane_id in lanes
    }
    return {lane_id: others for lane_id, others in beside.items() if others}


def _internal_places(road_map: RoadMap) -> list[tuple[InternalPlace, str]]:
    """Each internal lane reached from a normal lane with its place: the edge it leaves, the normal edge its way
    through the junction reaches, and its rank on that way (0 first)."""
    found: dict[str, InternalPlace] = {}
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
            for rank, internal in enumerate(way[:-1]):
                found.setdefault(internal, (lane.edge_id, end.edge_id, rank))
    return [(place, lane_id) for lane_id, place in found.items()]
