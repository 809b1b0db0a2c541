"""The electronic horizon: the road ahead of a position, as ADAS map providers give it.

For units that cache the road ahead: the radius profile (parts of constant curvature,
straights included) and the CPOIs (3.11) along the path a vehicle at a lane position
will drive (its route, or the most probable path), up to a requested distance, with
the warning speeds of every category at each CPOI. Distances are measured from the
position along the path.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import msgspec
import numpy as np

from csws.ahead.horizon import PathAhead
from csws.opendrive.profiles import slopes_by_curve_id
from csws.road.export import warning_speeds_kmh
from csws.road.matching import points_along

from .decoding import DecodedQuery
from .networks import MAX_HORIZON_M, ServedNetwork
from .schemas import Query

if TYPE_CHECKING:
    from .answers import WarningService
    from .vehicles import VehicleRegistry

__all__ = ["DEFAULT_HORIZON_M", "CpoiPositions", "cpoi_points", "positions", "horizon", "road_ahead"]

#: Horizon length when none is asked for, m.
DEFAULT_HORIZON_M = 1000.0


class CpoiPositions:
    """Where the CPOIs of one network are, as the contract gives positions, and their curves' grade and
    superelevation: each worked out once.

    A CPOI is the first point of its constant-radius part (3.11) on the lane a path reaches it
    by; a fleet meets the same CPOIs again and again, and working one out costs an interpolation
    along the path and, on a geo-referenced network, a projection (some 50 µs in all). The
    first path from a lane that reaches a CPOI places it for paths from that lane (the lanes of a
    road share their curves' ids, not their places: each lies on its own lane, and a path that
    starts inside a curve sees its part from the path's start); the place is kept for as long as
    the network is served (a network has as many CPOIs as its lanes' curves have parts). The grade
    and superelevation of the curves (:meth:`slopes`) are read from the curve index at the first call.

    Parameters
    ----------
    network
        The network.
    """

    def __init__(self, network: ServedNetwork) -> None:
        self.network = network
        self._known: dict[tuple[str, str, int], dict[str, float]] = {}
        self._road_parts: dict[tuple[str, int], dict[str, float]] | None = None
        self._slopes: dict[str, dict[str, float]] | None = None

    def slopes(self, curve_id: str) -> tuple[float | None, float | None]:
        """The mean grade and superelevation (toward the inside of the turn) of a curve, per cent
        (:func:`csws.opendrive.profiles.curve_slopes`): information beside V_w and S_w (docs/road-model.md);
        None and None on a network without them (one not imported from OpenDRIVE)."""
        if self._slopes is None:
            self._slopes = slopes_by_curve_id(self.network.road_map)
        found = self._slopes.get(curve_id)
        return (None, None) if found is None else (found["grade_pct"], found["superelevation_pct"])

    def of(
        self, ahead: PathAhead, curve_ids: Sequence[str], part_index: Sequence[int] | np.ndarray
    ) -> list[dict[str, float]]:
        """The positions of CPOIs (curve id, part index) on the path ``ahead``, in order; a CPOI the
        release rule recalls from the vehicle's memory, not on the path (:mod:`csws.warning.release`,
        rule 4), lies where its part starts on the lane its road's curve starts on."""
        lane_id = ahead.path.lane_ids[0]
        keys = [(lane_id, curve_id, int(part)) for curve_id, part in zip(curve_ids, part_index, strict=False)]
        on_path = set(zip(ahead.cpoi_curve_id, ahead.cpoi_part_index.tolist(), strict=True))
        missing = [key for key in dict.fromkeys(keys) if key not in self._known and key[1:] in on_path]
        if missing:
            points = cpoi_points(ahead, [curve_id for _, curve_id, _ in missing], [part for _, _, part in missing])
            self._known.update(zip(missing, positions(self.network, points), strict=False))
        return [self._known[key] if key in self._known else self._road_part(key[1], key[2]) for key in keys]

    def _road_part(self, curve_id: str, part: int) -> dict[str, float]:
        """Where a road's curve's part starts, on the lane the curve starts on (all placed at the first call)."""
        if self._road_parts is None:
            road_map = self.network.road_map
            found, points = [], []
            for lane_curve in road_map.curves(include_junctions=True):
                shape, curve = road_map.curve_shape(lane_curve), lane_curve.curve
                starts_s = [piece.start_s - curve.start_s for piece in curve.parts]
                found += [(lane_curve.curve_id, lane_curve.first_part_index + k) for k in range(len(starts_s))]
                points.append(points_along(shape, np.asarray(starts_s, dtype=float)))
            xy = np.concatenate(points) if points else np.zeros((0, 2))
            self._road_parts = dict(zip(found, positions(self.network, xy), strict=True))
        return self._road_parts[(curve_id, part)]


def positions(network: ServedNetwork, points: np.ndarray) -> list[dict[str, float]]:
    """Points ``(n, 2)`` as the contract's positions: x, y and, on a geo-referenced network, lon and
    lat (all projected in one call)."""
    xy = np.asarray(points, dtype=float).reshape(-1, 2)
    if not network.road_map.has_projection:
        return [{"x": x, "y": y} for x, y in xy.tolist()]
    lonlat = network.road_map.xy_to_lonlat_many(xy)
    return [
        {"x": x, "y": y, "lon": lon, "lat": lat}
        for (x, y), (lon, lat) in zip(xy.tolist(), lonlat.tolist(), strict=False)
    ]


def cpoi_points(ahead: PathAhead, curve_ids: Sequence[str], part_index: Sequence[int]) -> np.ndarray:
    """Where CPOIs are: the first point of each one's constant-radius part, ``(n, 2)``, m.

    A CPOI ahead lies its distance beyond the vehicle; one the vehicle is already inside
    lies where its part starts, behind the vehicle.
    """
    start_of = {
        (curve, int(part)): start_s
        for curve, part, start_s in zip(ahead.cpoi_curve_id, ahead.cpoi_part_index, ahead.cpoi_start_s, strict=False)
    }
    s = np.array(
        [start_of[(curve, int(part))] for curve, part in zip(curve_ids, part_index, strict=False)], dtype=float
    )
    return points_along(ahead.path.xy, s, ahead.path.profile.s)


#: A stretch of the profile gentler than this is shown as straight (radius null), m.
STRAIGHT_RADIUS_M = 10_000.0


def _direction(curvature: float) -> str:
    """``left``, ``right``, or ``straight`` for a stretch gentler than :data:`STRAIGHT_RADIUS_M`."""
    if abs(curvature) < 1.0 / STRAIGHT_RADIUS_M:
        return "straight"
    return "left" if curvature > 0 else "right"


def _slope_fields(slopes: tuple[float | None, float | None]) -> dict[str, float | None]:
    """A curve's grade and superelevation as the contract's fields (:meth:`CpoiPositions.slopes`)."""
    return {"grade_pct": slopes[0], "superelevation_pct": slopes[1]}


def horizon(
    network: ServedNetwork,
    cpoi_positions: CpoiPositions,
    lane_id: str,
    lane_pos_m: float,
    route_edges: Sequence[str] | None,
    length_m: float = DEFAULT_HORIZON_M,
) -> dict[str, Any]:
    """The horizon of ``length_m`` (at most :data:`MAX_HORIZON_M`) ahead of a lane position; its
    CPOIs placed by ``cpoi_positions`` (the network's).

    Raises
    ------
    KeyError
        If the lane is not on the network.
    """
    ahead = network.horizon(lane_id, lane_pos_m, 0.0, "M1", route_edges)
    path, start_s = ahead.path, ahead.vehicle_s
    end_s = min(start_s + min(length_m, MAX_HORIZON_M), path.length_m)
    profile = [
        {
            "start_m": max(part.start_s, start_s) - start_s,
            "end_m": min(part.end_s, end_s) - start_s,
            "radius_m": None if part.radius_m > STRAIGHT_RADIUS_M else part.radius_m,
            "direction": _direction(part.curvature),
        }
        for part in path.profile.parts
        if part.end_s > start_s and part.start_s < end_s
    ]
    keep = np.flatnonzero(ahead.cpoi_distance_m <= end_s - start_s)
    places = cpoi_positions.of(ahead, [ahead.cpoi_curve_id[i] for i in keep], ahead.cpoi_part_index[keep])
    policy = network.engine.settings.warning.policy
    cpois = [
        {
            "curve_id": ahead.cpoi_curve_id[i],
            "part_index": int(ahead.cpoi_part_index[i]),
            "distance_m": float(ahead.cpoi_distance_m[i]),
            "radius_m": float(ahead.cpoi_radius_m[i]),
            "position": place,
            "warning_speed_kmh": warning_speeds_kmh(float(ahead.cpoi_radius_m[i]), policy),
            **_slope_fields(cpoi_positions.slopes(ahead.cpoi_curve_id[i])),
        }
        for i, place in zip(keep, places, strict=False)
    ]
    lanes_ahead = path.lane_ids[path.lane_ids.index(lane_id) :]
    return {
        "network": network.name,
        "lane_id": lane_id,
        "lane_pos_m": float(lane_pos_m),
        "path_kind": ahead.kind.value,
        "length_m": end_s - start_s,
        "lanes": list(lanes_ahead),
        "profile": profile,
        "cpois": cpois,
    }


def road_ahead(
    service: WarningService, registry: VehicleRegistry, query: Query, length_m: float = DEFAULT_HORIZON_M
) -> dict[str, Any]:
    """``GET /v1/horizon``: where a position (``query``, of no vehicle) matches, and the :func:`horizon` ahead
    of it (of a fix: from the lane of its edge that keeps the road, :class:`csws.ahead.roadlane.RoadLanes`);
    ``matched`` None with the reason as ``fault`` when nothing matches.

    Raises
    ------
    service.answers.QueryErrors
        When the networks cannot answer the query (an unknown lane, a lane position beyond its lane, ...).
    """
    decoded = msgspec.convert(query, DecodedQuery, from_attributes=True)
    with registry.read(()) as nobody:  # a position, not a vehicle: no previous lane
        service.check([decoded], nobody, loc=("query",))
        (placement,) = service.place([decoded], nobody)
    if placement.lane_id is None or placement.path_lane_id is None:
        return {"matched": None, "fault": placement.reason, "profile": [], "cpois": []}
    ahead = horizon(
        service.networks[placement.network_index],
        service.cpoi_positions[placement.network_index],
        placement.path_lane_id,
        placement.path_lane_pos_m,
        query.route,
        length_m,
    )
    matched = {"lane_id": placement.lane_id, "lane_pos_m": placement.lane_pos_m, "distance_m": placement.distance_m}
    return {"matched": matched, "fault": None, **ahead}
