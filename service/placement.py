"""Where each query is on the served networks: its given lane, or the map match of its fix.

Every fix without a lane id is matched by one :class:`csws.road.hmm.SequenceMatcher` over all
served networks (a query naming its network on that network alone), continuing the sequence of
the vehicle's fixes that its session keeps (:attr:`service.sessions.Session.matching`): the fixes
of a batch's vehicles are one step of the hidden-Markov matcher, in numpy. A fix inside a
junction whose turn the fixes do not show yet is placed on the road's continuation; a fix that
matches no lane is dead-reckoned along the road for a while after the last match (see
docs/service.md, "Map matching"). A fix is taken at its ``timestamp_s``, else at the time it is
answered less its ``age_s``. The path ahead of a matched fix starts from the lane of its edge that keeps the
road (:class:`csws.ahead.roadlane.RoadLanes`): a fix cannot tell the lanes of an edge apart, unless the
sequence of fixes shows its lane (:attr:`csws.road.fixes.MatchState.lane_shown`).
"""

from __future__ import annotations

import bisect
import math
import time
from collections import defaultdict
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from csws.ahead.roadlane import RoadLanes
from csws.road.hmm import Confirmed, Fixes, Placed, SequenceMatcher, Track
from csws.road.match_settings import MatchSettings
from csws.road.matching import Probes, lane_points
from csws.road.roadmap import RoadMap
from csws.standard import kmh_to_mps

from .checks import QueryCheck
from .decoding import DecodedPosition, DecodedQuery
from .vehicles import LoadedVehicles

__all__ = ["ConfirmedPlace", "Placement", "Placer", "LanePoints"]


class ConfirmedPlace(NamedTuple):
    """A vehicle's last matched fix as its new fix confirms it, named as the contract's ConfirmedFix."""

    timestamp_s: float
    network: str
    lane_id: str
    lane_pos_m: float
    revised: bool


class Placement(NamedTuple):
    """Where one query was placed on the served networks.

    Attributes
    ----------
    network_index
        The network whose engine answers it.
    lane_id, lane_pos_m, distance_m
        The lane (None when nothing matched), the lane position and the distance of the fix from it, m.
    reason
        Why nothing matched, else None.
    path_lane_id, path_lane_pos_m
        The lane and lane position the path ahead starts from: the given lane, or for a matched fix the lane of
        its edge that keeps the road (:class:`csws.ahead.roadlane.RoadLanes`); None where nothing matched.
    confirmed
        For a matched fix that continues its vehicle's sequence, the vehicle's last matched fix as this one
        confirms it (the matcher's :class:`csws.road.fixes.Confirmed` with its network named); else None.
    """

    network_index: int
    lane_id: str | None
    lane_pos_m: float
    distance_m: float
    reason: str | None
    path_lane_id: str | None
    path_lane_pos_m: float
    confirmed: ConfirmedPlace | None = None


class LanePoints:
    """The points of one network's lanes at lane positions, many in one interpolation: where answers were snapped.

    The lanes' vertices are laid end to end on one arc-length axis (each lane after the one before it,
    a metre apart), so that a lane position anywhere on the network is one ``searchsorted`` away from
    its segment, whatever the number of lanes asked about.

    Parameters
    ----------
    road_map
        The network's map.
    """

    def __init__(self, road_map: RoadMap) -> None:
        shapes = road_map.lane_shapes
        self.road_map = road_map
        self.xy = shapes.xy
        self.vertex_start = shapes.vertex_start
        self.position_factor = shapes.position_factor
        lane_length_m = shapes.vertex_s[shapes.vertex_start[1:] - 1]
        self.lane_start_m = np.concatenate(([0.0], np.cumsum(lane_length_m + 1.0)[:-1]))
        self.lane_length_m = lane_length_m
        lane_of_vertex = np.repeat(np.arange(shapes.lane_count), np.diff(shapes.vertex_start))
        self.vertex_m = shapes.vertex_s + self.lane_start_m[lane_of_vertex]

    def point(self, lane_id: str, lane_pos_m: float) -> tuple[float, float]:
        """The point of a lane at a SUMO lane position (clamped to the lane), m: :meth:`points` for one, in
        plain floats (a one-vehicle answer takes it in a few microseconds, where arrays take tens)."""
        lane = self.road_map.lane_index(lane_id)
        first, last = int(self.vertex_start[lane]), int(self.vertex_start[lane + 1]) - 1
        shape_s = min(max(lane_pos_m / float(self.position_factor[lane]), 0.0), float(self.lane_length_m[lane]))
        along_m = float(self.lane_start_m[lane]) + shape_s
        start = min(max(bisect.bisect_right(self.vertex_m, along_m, first, last + 1) - 1, first), max(first, last - 1))
        end = min(start + 1, last)
        (x0, y0), (x1, y1) = self.xy[start].tolist(), self.xy[end].tolist()
        span_m = float(self.vertex_m[end] - self.vertex_m[start])
        fraction = (along_m - float(self.vertex_m[start])) / span_m if span_m > 0 else 0.0
        return x0 + fraction * (x1 - x0), y0 + fraction * (y1 - y0)

    def points(self, lane_ids: Sequence[str], lane_pos_m: Sequence[float]) -> np.ndarray:
        """The points ``(k, 2)`` of lanes at SUMO lane positions (clamped to each lane), m."""
        lane = np.fromiter((self.road_map.lane_index(lane_id) for lane_id in lane_ids), dtype=np.intp)
        shape_s = np.clip(
            np.asarray(lane_pos_m, dtype=float) / self.position_factor[lane], 0.0, self.lane_length_m[lane]
        )
        along_m = self.lane_start_m[lane] + shape_s
        first, last = self.vertex_start[lane], self.vertex_start[lane + 1] - 1
        start = np.clip(np.searchsorted(self.vertex_m, along_m, side="right") - 1, first, np.maximum(first, last - 1))
        end = np.minimum(start + 1, last)
        span_m = self.vertex_m[end] - self.vertex_m[start]
        fraction = np.divide(along_m - self.vertex_m[start], span_m, out=np.zeros_like(span_m), where=span_m > 0)
        return self.xy[start] + fraction[:, None] * (self.xy[end] - self.xy[start])


class Placer:
    """Places queries on the served networks.

    Parameters
    ----------
    lanes
        The networks' check of the queries, which knows on which network a lane id is taken.
    match_settings
        Map matching tolerances.
    """

    def __init__(self, lanes: QueryCheck, match_settings: MatchSettings) -> None:
        self.lanes = lanes
        self.networks = lanes.networks
        self.matcher = SequenceMatcher([n.road_map for n in self.networks], match_settings)
        self.road_lanes = [RoadLanes(network.horizon) for network in self.networks]

    def place(self, queries: Sequence[DecodedQuery], vehicles: LoadedVehicles) -> list[Placement]:
        """Where each query is: its given lane, or the map match of its fix (queries of distinct
        vehicles, preferring each one's previous lane)."""
        placements: dict[int, Placement] = {}
        on_lanes = [i for i, query in enumerate(queries) if query.lane_id is not None]
        to_match = [i for i, query in enumerate(queries) if query.lane_id is None]
        if on_lanes:
            placements.update(zip(on_lanes, self._on_lanes([queries[i] for i in on_lanes], vehicles), strict=True))
        if to_match:
            placements.update(zip(to_match, self._matched([queries[i] for i in to_match], vehicles), strict=True))
        return [placements[i] for i in range(len(queries))]

    def _on_lanes(self, queries: Sequence[DecodedQuery], vehicles: LoadedVehicles) -> list[Placement]:
        """The placements of queries that give their lane (which the checks found on a network)."""
        lanes = []
        for query in queries:
            lane_id, lane_pos_m = query.lane_id, query.lane_pos_m
            assert lane_id is not None and lane_pos_m is not None  # given together (check_located)
            network_index = self.lanes.lane_network(query, lane_id, vehicles)
            assert network_index is not None  # the checks refused a lane no network has
            lanes.append((network_index, lane_id, lane_pos_m))
        distances_m = self._fix_distances_m(queries, lanes)
        return [
            Placement(network_index, lane_id, lane_pos_m, distance_m, None, lane_id, lane_pos_m)
            for (network_index, lane_id, lane_pos_m), distance_m in zip(lanes, distances_m, strict=True)
        ]

    def _matched(self, fixes: Sequence[DecodedQuery], vehicles: LoadedVehicles) -> list[Placement]:
        """The placements of queries by the map match of their fixes (of distinct vehicles), each continuing its
        vehicle's sequence; what the matcher keeps of each is handed to the vehicle's session."""
        matched = self.matcher.match(self.fixes(fixes), [vehicles.track(query.vehicle_id) for query in fixes])
        placements = []
        for query, network_index, lane_id, lane_pos_m, distance_m, reason, track, confirmed, placed in zip(
            fixes,
            matched.map_index.tolist(),
            matched.lane_id,
            matched.lane_pos_m.tolist(),
            matched.distance_m.tolist(),
            matched.reason,
            matched.tracks,
            matched.confirmed,
            matched.placed,
            strict=True,
        ):
            if network_index < 0:
                network_index = vehicles.network_of(query.vehicle_id)
            path_lane_id, path_lane_pos_m = lane_id, lane_pos_m
            shown = placed is Placed.MATCHED and query.route is None and self._shows_lane(track, lane_id)
            if lane_id is not None and not shown:
                path_lane_id, path_lane_pos_m = self.road_lanes[network_index](lane_id, lane_pos_m, query.route)
            placements.append(
                Placement(
                    network_index,
                    lane_id,
                    lane_pos_m,
                    distance_m,
                    reason,
                    path_lane_id,
                    path_lane_pos_m,
                    None if confirmed is None else self._confirmed_place(confirmed),
                )
            )
            vehicles.keep_track(query.vehicle_id, track)
        return placements

    @staticmethod
    def _shows_lane(track: Track | None, lane_id: str | None) -> bool:
        """Whether the fixes show ``lane_id``, where the vehicle's newest fix was matched, among its edge's lanes:
        its path ahead then starts from that lane (a query with a route has its path start from a lane that
        leads along it instead, :class:`csws.ahead.roadlane.RoadLanes`)."""
        return track is not None and track.state.lane_id == lane_id and track.state.lane_shown

    def _confirmed_place(self, confirmed: Confirmed) -> ConfirmedPlace:
        """A confirmed fix with its network named."""
        network = self.networks[confirmed.map_index].name
        return ConfirmedPlace(confirmed.time_s, network, confirmed.lane_id, confirmed.lane_pos_m, confirmed.revised)

    def fixes(self, queries: Sequence[DecodedQuery], now_s: float | None = None) -> Fixes:
        """The fixes of queries as the sequence matcher takes them: each taken at its ``timestamp_s``, else at
        ``now_s`` (the time now by default) less its ``age_s``."""
        now_s = time.time() if now_s is None else now_s
        columns = [
            (
                now_s - (query.age_s or 0.0) if query.timestamp_s is None else query.timestamp_s,
                math.nan if query.heading_deg is None else query.heading_deg,
                kmh_to_mps(query.speed_kmh),
                math.nan if query.accuracy_m is None else query.accuracy_m,
            )
            for query in queries
        ]
        time_s, heading_deg, speed_mps, accuracy_m = (
            np.array(column, dtype=float) for column in zip(*columns, strict=True)
        )
        probes = self.probes([query.position for query in queries], [query.network for query in queries])
        return Fixes(probes, time_s, heading_deg, speed_mps, accuracy_m)

    def probes(self, positions: Sequence[DecodedPosition | None], networks: Sequence[str | None]) -> Probes:
        """Where to look for each fix (of a known network, if named): x, y on the network it names, else on
        every one; lon, lat in the projection of the network it names, else of each geo-referenced one."""
        rows: list[int] = []
        xy: list[tuple[float | None, float | None]] = []
        map_index: list[int] = []
        geographic: dict[int, list[tuple[int, DecodedPosition]]] = defaultdict(list)
        for row, (position, network) in enumerate(zip(positions, networks, strict=True)):
            named = -1 if network is None else self.lanes.network_index[network]
            assert position is not None  # a query without a lane has a fix (check_located)
            if position.lon is None:
                rows.append(row)
                xy.append((position.x, position.y))
                map_index.append(named)
            else:
                for network_index in self.lanes.geo_networks if named < 0 else (named,):
                    geographic[network_index].append((row, position))
        for network_index, placed in geographic.items():
            lonlat = np.array([(position.lon, position.lat) for _row, position in placed])
            rows += [row for row, _position in placed]
            xy += self.networks[network_index].road_map.lonlat_to_xy_many(lonlat).tolist()
            map_index += [network_index] * len(placed)
        return Probes(
            len(positions),
            np.array(rows, dtype=np.intp),
            np.array(xy, dtype=float).reshape(-1, 2),
            np.array(map_index, dtype=np.intp),
        )

    def _fix_distances_m(self, queries: Sequence[DecodedQuery], lanes: Sequence[tuple[int, str, float]]) -> list[float]:
        """Distance from each query's fix to its given lane position (network index, lane id, lane position), m;
        0 without a fix, or with lon/lat on a network without a projection. The queries on one lane are
        placed on it in one interpolation."""
        distances_m = [0.0] * len(queries)
        on_lane: dict[tuple[int, str], list[int]] = defaultdict(list)
        fixes: dict[int, DecodedPosition] = {}
        for row, (query, (network_index, lane_id, _lane_pos_m)) in enumerate(zip(queries, lanes, strict=True)):
            position = query.position
            if position is not None and (position.lon is None or self.networks[network_index].road_map.has_projection):
                on_lane[(network_index, lane_id)].append(row)
                fixes[row] = position
        for (network_index, lane_id), rows in on_lane.items():
            road_map = self.networks[network_index].road_map
            given = [fixes[row] for row in rows]
            geographic = [k for k, fix in enumerate(given) if fix.lon is not None]
            xy = np.array([(fix.x, fix.y) if fix.lon is None else (0.0, 0.0) for fix in given])
            if geographic:
                lonlat = np.array([(given[k].lon, given[k].lat) for k in geographic])
                xy[geographic] = road_map.lonlat_to_xy_many(lonlat)
            lane_xy = lane_points(road_map, lane_id, np.array([lanes[row][2] for row in rows]))
            for row, (x, y), (lane_x, lane_y) in zip(rows, xy.tolist(), lane_xy.tolist(), strict=True):
                distances_m[row] = math.hypot(x - lane_x, y - lane_y)
        return distances_m
