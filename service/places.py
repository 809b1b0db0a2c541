"""Where the live map shows each vehicle: the point of its last matched lane position, in the coordinates of
its network's curves (lon/lat on geo-referenced networks, else network metres).

The place is computed when a vehicle's session is written (:meth:`service.vehicles.LoadedVehicles.writes`),
for all the vehicles of a request at once, and stored with the session (:class:`service.store.Place`), so
that ``GET /v1/fleet`` finds the vehicles of a box in the store's index instead of placing every vehicle of
the fleet on every request.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Mapping, Sequence
from functools import cache

import numpy as np

from csws.road.roadmap import RoadMap

from .store import Place

__all__ = ["lane_points_many", "shown_places"]


@cache
def _along_all_lanes(road_map: RoadMap) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The arc length of every vertex counted along all lanes back to back, m, where each lane starts on
    it, m, and each lane's shape length, m (computed once per map)."""
    shapes = road_map.lane_shapes
    first, last = shapes.vertex_start[:-1], shapes.vertex_start[1:] - 1
    length_m = shapes.vertex_s[last]
    lane_start_m = np.concatenate(([0.0], np.cumsum(length_m)[:-1]))
    lane_of_vertex = np.repeat(np.arange(len(first)), np.diff(shapes.vertex_start))
    return shapes.vertex_s + lane_start_m[lane_of_vertex], lane_start_m, length_m


def lane_points_many(road_map: RoadMap, lane_ids: Sequence[str], lane_pos_m: Sequence[float]) -> np.ndarray:
    """The points at SUMO lane positions of any lanes, ``(k, 2)``, m, in one vectorised pass (a lane
    position runs along the shape scaled by :attr:`csws.road.network.Lane.position_factor`; clamped
    to the lane's ends), as :func:`csws.road.matching.lane_points` gives them lane by lane."""
    if not lane_ids:
        return np.empty((0, 2))
    shapes = road_map.lane_shapes
    vertex_m, lane_start_m, length_m = _along_all_lanes(road_map)
    lane = np.array([road_map.lane_index(lane_id) for lane_id in lane_ids], dtype=np.intp)
    shape_s = np.clip(np.asarray(lane_pos_m, dtype=float) / shapes.position_factor[lane], 0.0, length_m[lane])
    along_m = lane_start_m[lane] + shape_s
    # The segment holding each point, within its own lane (a point at a lane's end is on its last segment).
    segment = np.searchsorted(vertex_m, along_m, side="right") - 1
    segment = np.clip(segment, shapes.vertex_start[lane], shapes.vertex_start[lane + 1] - 2)
    segment_m = vertex_m[segment + 1] - vertex_m[segment]
    fraction = np.divide(along_m - vertex_m[segment], segment_m, out=np.zeros_like(along_m), where=segment_m > 0)
    xy = shapes.xy
    return xy[segment] + fraction[:, None] * (xy[segment + 1] - xy[segment])


def shown_places(
    road_maps: Sequence[RoadMap | None], network_names: Sequence[str], lanes: Mapping[str, tuple[int, str, float]]
) -> dict[str, Place]:
    """The place of each vehicle of ``lanes`` (network index, lane id and lane position, m, by vehicle), in
    the coordinates of its network's curves: one vectorised pass (and one projection) per network."""
    by_network: dict[int, list[str]] = defaultdict(list)
    for vehicle_id, (network_index, _lane_id, _lane_pos_m) in lanes.items():
        by_network[network_index].append(vehicle_id)
    places = {}
    for network_index, vehicle_ids in by_network.items():
        road_map, name = road_maps[network_index], network_names[network_index]
        assert road_map is not None  # only vehicles on a map's lanes are placed
        xy = lane_points_many(road_map, [lanes[v][1] for v in vehicle_ids], [lanes[v][2] for v in vehicle_ids])
        if road_map.has_projection:
            xy = road_map.xy_to_lonlat_many(xy)
        for vehicle_id, (x, y) in zip(vehicle_ids, xy.tolist(), strict=True):
            places[vehicle_id] = Place(name, x, y)
    return places
