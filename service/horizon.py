"""The electronic horizon: the road ahead of a position, as ADAS map providers give it.

For units that cache the road ahead: the radius profile (parts of constant curvature,
straights included) and the CPOIs (3.11) along the path a vehicle at a lane position
will drive (its route, or the most probable path), up to a requested distance, with
the warning speeds of every category at each CPOI. Distances are measured from the
position along the path.
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from csws.lookahead import PathAhead
from csws.mapmatch import points_along

from .curves import warning_speeds_kmh
from .networks import MAX_HORIZON_M, ServedNetwork

__all__ = ["DEFAULT_HORIZON_M", "cpoi_points", "position", "horizon"]

#: Horizon length when none is asked for, m.
DEFAULT_HORIZON_M = 1000.0


def position(network: ServedNetwork, point: np.ndarray) -> dict[str, float]:
    """A point as the contract's position: x, y and, on a geo-referenced network, lon and lat."""
    x, y = float(point[0]), float(point[1])
    if not network.road_map.has_projection:
        return {"x": x, "y": y}
    lon, lat = network.road_map.xy_to_lonlat(x, y)
    return {"x": x, "y": y, "lon": float(lon), "lat": float(lat)}


def cpoi_points(
    ahead: PathAhead, distance_m: np.ndarray, part_index: np.ndarray, warning_radius_m: float
) -> np.ndarray:
    """Where CPOIs are: the first point of each constant-radius part, ``(n, 2)``, m.

    A CPOI ahead lies its distance beyond the vehicle along the path; one the vehicle
    is already inside (distance 0) lies where its part starts, behind the vehicle.
    """
    s = ahead.vehicle_s + np.asarray(distance_m, dtype=float)
    inside = np.flatnonzero(s == ahead.vehicle_s)
    if inside.size:
        parts = [(index, part) for curve in ahead.path.curves(warning_radius_m) for index, part in enumerate(curve.parts)]
        for i in inside:
            s[i] = next(
                (part.start_s for index, part in parts
                 if index == part_index[i] and part.start_s <= ahead.vehicle_s < part.end_s),
                ahead.vehicle_s,
            )
    return points_along(ahead.path.xy, s, ahead.path.profile.s)


def horizon(
    network: ServedNetwork,
    lane_id: str,
    lane_pos_m: float,
    route_edges: Sequence[str] | None,
    length_m: float = DEFAULT_HORIZON_M,
) -> dict[str, Any]:
    """The horizon of ``length_m`` (at most :data:`MAX_HORIZON_M`) ahead of a lane position.

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
            "radius_m": None if math.isinf(part.radius_m) else part.radius_m,
            "direction": "straight" if part.curvature == 0 else ("left" if part.curvature > 0 else "right"),
        }
        for part in path.profile.parts
        if part.end_s > start_s and part.start_s < end_s
    ]
    keep = np.flatnonzero(ahead.cpoi_distance_m <= end_s - start_s)
    points = cpoi_points(ahead, ahead.cpoi_distance_m[keep], ahead.cpoi_part_index[keep],
                         network.horizon.settings.warning_radius_m)
    policy = network.engine.settings.warning.policy
    cpois = [
        {
            "curve_id": ahead.cpoi_curve_id[i],
            "part_index": int(ahead.cpoi_part_index[i]),
            "distance_m": float(ahead.cpoi_distance_m[i]),
            "radius_m": float(ahead.cpoi_radius_m[i]),
            "position": position(network, point),
            "warning_speed_kmh": warning_speeds_kmh(float(ahead.cpoi_radius_m[i]), policy),
        }
        for i, point in zip(keep, points)
    ]
    lanes_ahead = path.lane_ids[path.lane_ids.index(lane_id):]
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
