"""The live fleet: where every vehicle with a live session is and what its latest answer said.

``GET /v1/fleet`` reads every live session of the asking fleet from the state store (one
round trip, :meth:`service.store.StateStore.sessions`), so it shows the vehicles that any
worker or replica answered. A vehicle is placed on the road: at the lane position of its
last match (the lane point, not the raw fix), in the coordinates of its network's curves
(lon/lat on geo-referenced networks, else network metres). A vehicle that never matched has
no place and is left out; one whose latest fix matched nothing stays where it last matched,
with state ``fault``.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence
from typing import Any

import numpy as np

from csws.road.matching import lane_points

from .curves import feature_collection, in_bbox
from .keys import shown_id
from .networks import ServedNetwork
from .vehicles import SessionRecord, VehicleRegistry

__all__ = ["fleet_features"]


def _placed(records: dict[str, SessionRecord], network: ServedNetwork) -> dict[str, list[float]]:
    """The position of each vehicle of ``records`` (all on ``network``) at its lane position, in the
    network's GeoJSON coordinates; the vehicles of one lane in one interpolation."""
    by_lane: dict[str, list[str]] = defaultdict(list)
    for key, record in records.items():
        if record.lane_id is not None:  # always: only placed vehicles are shown (fleet_features)
            by_lane[record.lane_id].append(key)
    keys, points = [], []
    for lane_id, on_lane in by_lane.items():
        keys += on_lane
        points.append(lane_points(network.road_map, lane_id, np.array([records[k].lane_pos_m for k in on_lane])))
    xy = np.concatenate(points) if points else np.empty((0, 2))
    if network.road_map.has_projection:
        xy = network.road_map.xy_to_lonlat_many(xy)
    return dict(zip(keys, xy.tolist(), strict=False))


def fleet_features(
    sessions: dict[str, bytes],
    registry: VehicleRegistry,
    networks: Sequence[ServedNetwork],
    fleet: str,
    bbox: tuple[float, float, float, float] | None,
    chosen: Sequence[int],
) -> dict[str, Any]:
    """The vehicles of ``fleet`` (its live ``sessions`` by key) on the networks at ``chosen`` within
    ``bbox`` as a GeoJSON FeatureCollection of points: id, network, system state and fault, the
    level, category, speed, timestamp, heading, target curve with its V_w and the service's time of its
    latest answer, its lane with the lane's street name and road type.

    Parameters
    ----------
    sessions
        The fleet's live sessions, by vehicle key (:func:`service.keys.vehicle_key`).
    registry
        Decodes the sessions.
    networks
        The served networks.
    fleet
        The fleet that asks (``""`` on a service without keys).
    bbox
        min x, min y, max x, max y in each network's coordinates; None for everywhere.
    chosen
        The indices of the networks to show.
    """
    by_network: dict[int, dict[str, SessionRecord]] = defaultdict(dict)
    for key, session in sessions.items():
        record = registry.decode(session)
        if record is not None and record.lane_id is not None and record.latest is not None:
            network_index = registry.network_index[record.network]
            if network_index in chosen and networks[network_index].road_map.has_lane(record.lane_id):
                by_network[network_index][key] = record
    features = []
    for network_index, records in sorted(by_network.items()):
        network = networks[network_index]
        for key, position in _placed(records, network).items():
            record, latest = records[key], records[key].latest
            assert latest is not None and record.lane_id is not None  # only placed vehicles with an answer (above)
            lane = network.road_map.lane(record.lane_id)
            feature = {
                "type": "Feature",
                "id": shown_id(fleet, key),
                "bbox": [*position, *position],
                "geometry": {"type": "Point", "coordinates": position},
                "properties": {
                    "vehicle_id": shown_id(fleet, key),
                    "network": network.name,
                    "state": record.state.value,
                    "fault": record.fault.value if record.fault is not None else None,
                    "level": latest.level,
                    "category": latest.category.value if latest.category is not None else None,
                    "speed_kmh": latest.speed_kmh,
                    "timestamp_s": latest.timestamp_s,
                    "lane_id": record.lane_id,
                    "street_name": lane.street_name,
                    "road_type": lane.road_type,
                    "heading_deg": latest.heading_deg,
                    "curve_id": latest.curve_id,
                    "warning_speed_kmh": latest.warning_speed_kmh,
                    "answered_at_s": latest.answered_at_s,
                },
            }
            if in_bbox(feature, bbox):
                features.append(feature)
    return feature_collection(features, [networks[i] for i in chosen])
