"""The forward collision warning in SUMO: each vehicle's target from SUMO's own leaders, and the warning.

A vehicle's candidates are what a forward sensor sees (GB/T 33577-2017 4.7.3), read from
SUMO in the vehicle's path coordinates:

* the vehicles ahead in its own lanes, from ``vehicle.getLeader(id, range)`` and the leader's
  leader (4.7.3.1: the nearer one does not hide the farther). ``getLeader`` reports the gap
  from the front *plus minGap* to the leader's rear, and by default searches only as far as
  the vehicle could brake: the look-ahead is passed, and the vehicle's ``minGap`` added back
  to make the clearance x_c. It follows the lanes the vehicle will take, so on a curve the
  gap is measured along the curve;
* the nearest leader in each adjacent lane (``getLeftLeaders``, ``getRightLeaders``), with its
  lateral offset from the path's centre line: half of each lane's width plus the two
  vehicles' lateral offsets in their lanes.

:func:`csws.fcw_target.select_targets` keeps the in-path one reached first; the radius of the
path up to a candidate is its length over the change of heading between the two vehicles
(SUMO's angle of a vehicle is its body's, rear to front: the road's heading at its middle).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from csws.fcw_target import TargetSettings, select_targets

__all__ = ["ForwardTargets", "forward_targets"]

#: SUMO's brake-light bit of ``vehicle.getSignals`` (the driver brakes, 4.5.4).
BRAKE_LIGHT = 8
#: Leaders followed down each subject's own lanes (the leader and the leader's leader).
CHAIN = 2


@dataclass(frozen=True)
class ForwardTargets:
    """Each subject's target, as arrays ``(n,)`` in the subjects' order.

    Attributes
    ----------
    target_id
        The target vehicle, or None.
    clearance_m
        x_c along the path, m (``nan`` without a target).
    relative_velocity_mps
        v_r = v_TV - v_SV, m/s (``nan`` without a target).
    target_accel_mps2
        a_TV, m/s^2 (``nan`` without a target).
    """

    target_id: list[str | None]
    clearance_m: np.ndarray
    relative_velocity_mps: np.ndarray
    target_accel_mps2: np.ndarray


def _heading_radius_m(distance_m: float, subject_deg: float, candidate_deg: float) -> float:
    """The mean radius of a path of ``distance_m`` along which the heading turns between the two angles."""
    turn_rad = abs(math.radians((candidate_deg - subject_deg + 180.0) % 360.0 - 180.0))
    return distance_m / turn_rad if turn_rad > 1e-9 else math.inf


def _candidates(sumo: Any, subject: str, range_m: float) -> list[tuple[str, float, float]]:
    """(id, clearance along the path m, lateral offset m) of what the subject's sensor sees ahead."""
    vehicle = sumo.vehicle
    seen = []
    follower, ahead_m = subject, 0.0
    for _ in range(CHAIN):
        if ahead_m >= range_m:
            break
        leader = vehicle.getLeader(follower, range_m - ahead_m)
        if not leader or not leader[0]:
            break
        leader_id, gap_m = leader
        ahead_m += gap_m + vehicle.getMinGap(follower) + (vehicle.getLength(follower) if follower != subject else 0.0)
        seen.append((leader_id, ahead_m, vehicle.getLateralLanePosition(leader_id) - vehicle.getLateralLanePosition(subject)))
        follower = leader_id
    own_half_m = sumo.lane.getWidth(vehicle.getLaneID(subject)) / 2.0
    for side, neighbours in ((1.0, vehicle.getLeftLeaders(subject)), (-1.0, vehicle.getRightLeaders(subject))):
        for neighbour_id, gap_m in neighbours[:1]:
            beside_m = own_half_m + sumo.lane.getWidth(vehicle.getLaneID(neighbour_id)) / 2.0
            offset_m = side * beside_m + vehicle.getLateralLanePosition(neighbour_id) - vehicle.getLateralLanePosition(subject)
            seen.append((neighbour_id, gap_m + vehicle.getMinGap(subject), offset_m))
    return seen


def forward_targets(sumo: Any, subjects: Sequence[str], settings: TargetSettings = TargetSettings(),
                    noise: Any = None) -> ForwardTargets:  # fmt: skip
    """The target of each of ``subjects`` (libsumo or traci as ``sumo``), its clearance, relative
    velocity and acceleration.

    ``noise``, if given, is called as ``noise(clearance_m, lateral_offset_m)`` on the candidates'
    arrays and returns them as the sensor measures them (the conformance suite's test equipment).
    """
    vehicle = sumo.vehicle
    owner, ids, distance, offset, radius = [], [], [], [], []
    for index, subject in enumerate(subjects):
        angle, half_m = vehicle.getAngle(subject), vehicle.getLength(subject) / 2.0
        for candidate, clearance_m, offset_m in _candidates(sumo, subject, settings.range_m):
            owner.append(index)
            ids.append(candidate)
            distance.append(clearance_m)
            offset.append(offset_m)
            middles_m = half_m + clearance_m + vehicle.getLength(candidate) / 2.0
            radius.append(_heading_radius_m(middles_m, angle, vehicle.getAngle(candidate)))
    distance_m, offset_m = np.array(distance, dtype=float), np.array(offset, dtype=float)
    if noise is not None and ids:
        distance_m, offset_m = noise(distance_m, offset_m)
    chosen = select_targets(np.array(owner, dtype=np.intp), distance_m, offset_m, np.array(radius, dtype=float),
                            len(subjects), settings)  # fmt: skip
    count = len(subjects)
    target_id: list[str | None] = [None] * count
    clearance, relative, accel = (np.full(count, np.nan) for _ in range(3))
    for index in np.flatnonzero(chosen >= 0):
        candidate = ids[chosen[index]]
        target_id[index] = candidate
        clearance[index] = distance_m[chosen[index]]
        relative[index] = vehicle.getSpeed(candidate) - vehicle.getSpeed(subjects[index])
        accel[index] = vehicle.getAcceleration(candidate)
    return ForwardTargets(target_id, clearance, relative, accel)
