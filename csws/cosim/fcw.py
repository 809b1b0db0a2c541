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

:func:`csws.fcw.target.select_targets` keeps the in-path one reached first; the radius of the
path up to a candidate is its length over the change of heading between the two vehicles
(SUMO's angle of a vehicle is its body's, rear to front: the road's heading at its middle).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from csws.fcw.physics import ACTIVE, FCW_STATES, STANDBY, FcwSettings, evaluate_fcw, next_fcw_states
from csws.fcw.target import TargetSettings, select_targets

from .driver import DriverResponse
from .records import StepValues, Summary
from .sumo import FleetState

__all__ = [
    "ForwardTargets",
    "VehicleSizes",
    "forward_targets",
    "FcwColumns",
    "FleetFcw",
    "FCW_TIMESERIES_FIELDS",
    "FCW_EVENT_COLUMNS",
    "fcw_events",
]

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


class VehicleSizes(dict[str, tuple[float, float]]):
    """Each vehicle's length and ``minGap`` (m), read from SUMO once per vehicle: they do not
    change while it drives (a fleet's evaluation keeps one across steps and forgets arrived vehicles)."""

    def __init__(self, vehicle: Any) -> None:
        super().__init__()
        self.vehicle = vehicle

    def __missing__(self, vehicle_id: str) -> tuple[float, float]:
        sizes = self[vehicle_id] = (self.vehicle.getLength(vehicle_id), self.vehicle.getMinGap(vehicle_id))
        return sizes


def _heading_radius_m(distance_m: np.ndarray, subject_deg: np.ndarray, candidate_deg: np.ndarray) -> np.ndarray:
    """The mean radius of paths of ``distance_m`` along which the heading turns between the two angles."""
    turn_rad = np.abs(np.radians((candidate_deg - subject_deg + 180.0) % 360.0 - 180.0))
    with np.errstate(divide="ignore"):
        return np.where(turn_rad > 1e-9, distance_m / turn_rad, np.inf)


def _candidates(
    sumo: Any, subject: str, range_m: float, sizes: VehicleSizes, sublanes: bool = True
) -> list[tuple[str, float, float]]:
    """(id, clearance along the path m, lateral offset m) of what the subject's sensor sees ahead.

    Without SUMO's sublane model (``sublanes`` False) every vehicle drives on its lane's centre
    line: a leader in the subject's lanes is 0 m off its path, and the nearest vehicle in an
    adjacent lane is half of each lane's width off it, beyond half a lane width (the path,
    :func:`csws.fcw.target.select_targets`) wherever the two lanes are 3.5 m wide together:
    neither offset is read from SUMO, and the adjacent lanes are not searched.
    """
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
        length_m, min_gap_m = sizes[follower]
        ahead_m += gap_m + min_gap_m + (length_m if follower != subject else 0.0)
        offset_m = (
            vehicle.getLateralLanePosition(leader_id) - vehicle.getLateralLanePosition(subject) if sublanes else 0.0
        )
        seen.append((leader_id, ahead_m, offset_m))
        follower = leader_id
    if not sublanes:
        return seen
    own_half_m = sumo.lane.getWidth(vehicle.getLaneID(subject)) / 2.0
    for side, neighbours in ((1.0, vehicle.getLeftLeaders(subject)), (-1.0, vehicle.getRightLeaders(subject))):
        for neighbour_id, gap_m in neighbours[:1]:
            beside_m = own_half_m + sumo.lane.getWidth(vehicle.getLaneID(neighbour_id)) / 2.0
            offset_m = (
                side * beside_m + vehicle.getLateralLanePosition(neighbour_id) - vehicle.getLateralLanePosition(subject)
            )
            seen.append((neighbour_id, gap_m + sizes[subject][1], offset_m))
    return seen


def forward_targets(
    sumo: Any,
    subjects: Sequence[str],
    settings: TargetSettings = TargetSettings(),
    noise: Any = None,
    sublanes: bool = True,
    sizes: VehicleSizes | None = None,
) -> ForwardTargets:
    """The target of each of ``subjects`` (libsumo or traci as ``sumo``), its clearance, relative
    velocity and acceleration.

    ``noise``, if given, is called as ``noise(clearance_m, lateral_offset_m)`` on the candidates'
    arrays and returns them as the sensor measures them (the conformance suite's test equipment).
    ``sublanes`` False reads fewer values for a simulation without SUMO's sublane model
    (:func:`_candidates`); ``sizes`` keeps the vehicles' lengths between calls.
    """
    vehicle = sumo.vehicle
    sizes = VehicleSizes(vehicle) if sizes is None else sizes
    owner, seen = [], []
    for index, subject in enumerate(subjects):
        found = _candidates(sumo, subject, settings.range_m, sizes, sublanes)
        owner += [index] * len(found)
        seen += found
    ids, distance, offset = zip(*seen, strict=False) if seen else ((), (), ())
    owners = np.array(owner, dtype=np.intp)
    distance_m, offset_m = np.array(distance, dtype=float), np.array(offset, dtype=float)
    radius_m = np.empty(0)
    if ids:
        subject_deg = np.array([vehicle.getAngle(subject) for subject in subjects])[owners]
        half_lengths_m = (
            np.array(
                [sizes[subjects[index]][0] + sizes[candidate][0] for index, candidate in zip(owner, ids, strict=False)]
            )
            / 2.0
        )
        candidate_deg = np.array([vehicle.getAngle(candidate) for candidate in ids])
        radius_m = _heading_radius_m(half_lengths_m + distance_m, subject_deg, candidate_deg)
    if noise is not None and ids:
        distance_m, offset_m = noise(distance_m, offset_m)
    chosen = select_targets(owners, distance_m, offset_m, radius_m, len(subjects), settings)
    count = len(subjects)
    target_id: list[str | None] = [ids[pick] if pick >= 0 else None for pick in chosen.tolist()]
    clearance, relative, accel = (np.full(count, np.nan) for _ in range(3))
    rows = np.flatnonzero(chosen >= 0)
    targets = [target_id[row] for row in rows.tolist()]
    clearance[rows] = distance_m[chosen[rows]]
    relative[rows] = np.array([vehicle.getSpeed(target) for target in targets], dtype=float) - np.array(
        [vehicle.getSpeed(subjects[row]) for row in rows.tolist()], dtype=float
    )
    accel[rows] = np.array([vehicle.getAcceleration(target) for target in targets], dtype=float)
    return ForwardTargets(target_id, clearance, relative, accel)


#: The time series' FCW columns (``csws cosim --systems ...,fcw``), beside the curve warning's, with their Arrow types.
FCW_TIMESERIES_FIELDS = (
    ("fcw_state", "string"),
    ("fcw_level", "int8"),
    ("fcw_target_id", "string"),
    ("fcw_range_m", "float64"),
    ("fcw_range_rate_mps", "float64"),
    ("fcw_ttc_s", "float64"),
)
#: Columns ``warnings.csv`` gains with FCW: the FCW events' target (empty in the curve warning's events).
FCW_EVENT_COLUMNS = ("fcw_target_id", "fcw_range_m", "fcw_range_rate_mps", "fcw_ttc_s")
#: The curve's columns of an event (curve id, part index, radius, distance, warning speed), empty in FCW events.
_CURVE_EVENT_COLUMNS = 5


@dataclass(frozen=True)
class FcwColumns:
    """The forward collision warning of every vehicle of a step, as columns in the fleet's order.

    Attributes
    ----------
    state
        ``off``, ``standby``, ``active`` or ``fault`` (4.3).
    level
        0, 1 preliminary or 2 collision warning.
    target_id
        The target vehicle of an active system, or None.
    range_m
        x_c, the clearance to the target, m (None without one).
    range_rate_mps
        v_r = v_TV - v_SV, m/s (None without a target; negative while closing).
    ttc_s
        TTC, s (None without a target or while not closing).
    """

    state: list[str]
    level: list[int]
    target_id: list[str | None]
    range_m: list[float | None]
    range_rate_mps: list[float | None]
    ttc_s: list[float | None]

    @classmethod
    def quiet(cls, state: list[str]) -> FcwColumns:
        """The columns of vehicles in ``state`` without a warning or a target (filled in by the evaluation)."""
        count = len(state)
        return cls(state, [0] * count, [None] * count, [None] * count, [None] * count, [None] * count)

    def columns(self) -> tuple[list[Any], ...]:
        """The time-series columns, in :data:`FCW_TIMESERIES_FIELDS` order."""
        return self.state, self.level, self.target_id, self.range_m, self.range_rate_mps, self.ttc_s


class FleetFcw:
    """The forward collision warning of a fleet in SUMO, one vectorised evaluation per step.

    Each step, the state of every vehicle follows its speed (:func:`csws.fcw.physics.next_fcw_states`,
    with the hysteresis of Figure 2 kept per vehicle; fault while it is on no lane); only the
    active ones are looked at further: their targets from SUMO's leaders (:func:`forward_targets`),
    and only those with a target have their own acceleration and brake light read, for one
    :func:`csws.fcw.physics.evaluate_fcw` call.

    Parameters
    ----------
    sumo
        libsumo or traci, with a simulation running.
    settings, targets
        The warning's thresholds and the target selection.
    """

    def __init__(
        self, sumo: Any, settings: FcwSettings = FcwSettings(), targets: TargetSettings = TargetSettings()
    ) -> None:
        self.sumo = sumo
        self.settings = settings
        self.targets = targets
        self.sublanes = float(sumo.simulation.getOption("lateral-resolution")) > 0.0
        self.states: dict[str, int] = {}
        self.sizes = VehicleSizes(sumo.vehicle)

    def __call__(self, vehicle_ids: Sequence[str], lane_ids: Sequence[str], speed_mps: np.ndarray) -> FcwColumns:
        """The warning of every vehicle, in order."""
        count = len(vehicle_ids)
        previous = np.array([self.states.get(vehicle_id, STANDBY) for vehicle_id in vehicle_ids], dtype=np.int8)
        on_lane = np.array([bool(lane_id) for lane_id in lane_ids], dtype=bool)
        states = next_fcw_states(previous, speed_mps, np.ones(count, dtype=bool), on_lane, self.settings)
        self.states.update(zip(vehicle_ids, states.tolist(), strict=False))
        columns = FcwColumns.quiet([FCW_STATES[code].value for code in states.tolist()])
        active = np.flatnonzero(states == ACTIVE)
        if active.size:
            subjects = [vehicle_ids[i] for i in active.tolist()]
            found = forward_targets(self.sumo, subjects, self.targets, sublanes=self.sublanes, sizes=self.sizes)
            seen = np.flatnonzero(np.isfinite(found.clearance_m))
            if seen.size:
                self._evaluate(subjects, found, seen, active, columns)
        return columns

    def _evaluate(
        self, subjects: list[str], found: ForwardTargets, seen: np.ndarray, active: np.ndarray, columns: FcwColumns
    ) -> None:
        """Evaluate the subjects with a target and write their level, target, range, range rate and
        TTC into ``columns`` at their rows of the fleet."""
        vehicle = self.sumo.vehicle
        with_target = [subjects[k] for k in seen.tolist()]
        accel_mps2 = np.array([vehicle.getAcceleration(subject) for subject in with_target])
        braking = np.array([bool(vehicle.getSignals(subject) & BRAKE_LIGHT) for subject in with_target])
        x_c, v_r = found.clearance_m[seen], found.relative_velocity_mps[seen]
        batch = evaluate_fcw(accel_mps2, x_c, v_r, found.target_accel_mps2[seen], braking, self.settings)
        for j, (k, row) in enumerate(zip(seen.tolist(), active[seen].tolist(), strict=False)):
            ttc = float(batch.ttc_s[j])
            columns.level[row], columns.target_id[row] = int(batch.level[j]), found.target_id[k]
            columns.range_m[row], columns.range_rate_mps[row] = float(x_c[j]), float(v_r[j])
            columns.ttc_s[row] = ttc if math.isfinite(ttc) else None

    def forget(self, vehicle_ids: Sequence[str]) -> None:
        """Drop vehicles that left."""
        for vehicle_id in vehicle_ids:
            self.states.pop(vehicle_id, None)
            self.sizes.pop(vehicle_id, None)


def fcw_events(fcw: FcwColumns, levels: dict[str, int], summary: Summary, step: StepValues) -> list[tuple[Any, ...]]:
    """The ``warnings.csv`` rows of the step's FCW level changes (``fcw_onset``, ``fcw_change``,
    ``fcw_end``), counted in ``summary``; ``levels`` holds each vehicle's last FCW level.

    The curve's columns stay empty; the target's are :data:`FCW_EVENT_COLUMNS`.
    """
    rows = []
    for i, (vehicle_id, level) in enumerate(zip(step.fleet.vehicle_id, fcw.level, strict=False)):
        previous = levels.get(vehicle_id, 0)
        if level == previous:
            continue
        levels[vehicle_id] = level
        if level > previous:
            summary.add_fcw_onset(vehicle_id, level)
        event = "fcw_onset" if previous == 0 else "fcw_end" if level == 0 else "fcw_change"
        target = (fcw.target_id[i], fcw.range_m[i], fcw.range_rate_mps[i], fcw.ttc_s[i])
        rows.append(step.event_row(i, event, level, previous, (None,) * _CURVE_EVENT_COLUMNS, target))
    return rows


def respond_to_fcw(
    driver: DriverResponse, fleet: FleetState, fcw: FcwColumns, step_s: float, commands: dict[str, float]
) -> None:
    """Add the driver-response model's answers to the FCW warnings to the step's ``commands`` (m/s,
    -1 hands back): where both warnings ask for a speed, the lower one."""
    responding = driver.fcw_drivers
    for i, (vehicle_id, level) in enumerate(zip(fleet.vehicle_id, fcw.level, strict=False)):
        if level == 0 and vehicle_id not in responding:
            continue
        command = driver.fcw_command(
            fleet.time_s, step_s, vehicle_id, level, fcw.range_rate_mps[i], float(fleet.speed_mps[i])
        )
        if command is None:
            continue
        curve_command = commands.get(vehicle_id, -1.0)
        commands[vehicle_id] = (
            command if curve_command < 0 else curve_command if command < 0 else min(command, curve_command)
        )
