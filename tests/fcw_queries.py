"""Queries of the service's FCW tests: a vehicle on the R 120 m track, a stopped car ahead, and the level
formula (4) gives for it, computed by hand."""

from __future__ import annotations

import math

from csws.fcw.settings import FcwSettings
from csws.networks import networks_dir

TRACK_NET = str(networks_dir() / "single_r120_left.net.xml")
#: The library's commercial defaults for category N: T_resp 1.2 s, collision 0.5 g, preliminary 0.3 g, hold 0.4 s.
N_SETTINGS = FcwSettings.for_category("N")


def fcw_query(vehicle_id: str, speed_kmh: float = 72.0, **extra) -> dict:
    """A query of a category N vehicle on the track's approach, 100 m along it, with ``extra`` fields."""
    return {
        "vehicle_id": vehicle_id,
        "category": "N",
        "speed_kmh": speed_kmh,
        "lane_id": "approach_0",
        "lane_pos_m": 100.0,
        "timestamp_s": 1.0,
        **extra,
    }


def stopped_car(x_m: float, speed_mps: float, object_id: int = 7, **extra) -> dict:
    """A stopped car straight ahead: it closes at the subject's speed."""
    return {"id": object_id, "x_m": x_m, "y_m": 0.0, "relative_speed_mps": -speed_mps, "accel_mps2": 0.0, **extra}


def stopped_car_level(x_m: float, speed_mps: float, settings: FcwSettings = N_SETTINGS) -> int:
    """Formula (4) by hand for a car ahead closing at ``speed_mps`` without accelerating (a_TV 0):
    a_req = v^2 / (2 (x_c - v T_resp)); the level of 4.5.3 after 4.5.5 e."""
    left_m = x_m - speed_mps * (settings.reaction_time_s + settings.brake_response_s)
    a_req = math.inf if left_m <= 0.0 else speed_mps**2 / (2.0 * left_m)
    ttc_s = x_m / speed_mps
    if ttc_s > settings.max_ttc_s and a_req < settings.preliminary_a_req_mps2:
        return 0  # 4.5.5 e: no measure shows a threat
    return 2 if a_req >= settings.collision_a_req_mps2 else 1 if a_req >= settings.preliminary_a_req_mps2 else 0
