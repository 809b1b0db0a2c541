"""One object that turns a vehicle's state into its answer: the system of clauses 5 and 6.

:class:`Engine` ties the parts together for the co-simulation, the HTTP service and
library users alike, so that the same input gives the same answer everywhere:

road map -> look-ahead (path and CPOIs) -> warning (clause 6) -> system state (5.2-5.4).

It keeps each vehicle's :class:`~csws.state.VehicleStatus` between updates. Many
vehicles are evaluated together with :meth:`Engine.evaluate_many`: the path ahead is
found per vehicle, and the warning of all of them is computed in one vectorised step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from .lookahead import LookAhead, LookAheadSettings, PathAhead
from .roadmap import RoadMap
from .standard import Level
from .state import ActivationSettings, Fault, SystemState, VehicleStatus, next_status, switch
from .warning import CurveWarning, WarningSettings, column_index, evaluate_batch, no_warning

__all__ = ["VehicleInput", "Answer", "EngineSettings", "Engine"]


@dataclass(frozen=True)
class VehicleInput:
    """What the system knows of a vehicle at one instant.

    Attributes
    ----------
    vehicle_id
        The vehicle.
    category
        Its category (GB/T 15089): M1, M2, M3, N or O.
    speed_kmh
        Its speed V, km/h.
    lane_id, lane_pos_m
        Where it is on the map (SUMO lane id and lane position, m); ``lane_id`` None
        when the position matched no lane.
    route_edges
        Its route as edge ids, when known.
    timestamp_s
        When the position was taken, s.
    age_s
        How old the position is now, s, where known.
    """

    vehicle_id: str
    category: str
    speed_kmh: float
    lane_id: str | None
    lane_pos_m: float = 0.0
    route_edges: Sequence[str] | None = None
    timestamp_s: float | None = None
    age_s: float | None = None


@dataclass(frozen=True)
class Answer:
    """The system's answer for one vehicle at one instant.

    Attributes
    ----------
    vehicle_id
        The vehicle.
    state
        The system state (5.2-5.4); warnings come only in ``active``.
    fault
        Why the state is ``fault``, else None.
    warning
        The warning (level 0 when there is none; always level 0 unless active).
    path
        The path ahead, when one was found.
    """

    vehicle_id: str
    state: SystemState
    fault: Fault | None
    warning: CurveWarning
    path: PathAhead | None

    @property
    def level(self) -> Level:
        """The warning level, 0 to 2."""
        return self.warning.level


@dataclass(frozen=True)
class EngineSettings:
    """Everything the engine can be tuned with: warning, look-ahead and activation settings."""

    warning: WarningSettings = field(default_factory=WarningSettings)
    lookahead: LookAheadSettings = field(default_factory=LookAheadSettings)
    activation: ActivationSettings = field(default_factory=ActivationSettings)


#: The status of a vehicle not seen before (shared: statuses are immutable).
_NEW_STATUS = VehicleStatus()


class Engine:
    """The curve speed warning system for the vehicles on one road map.

    Parameters
    ----------
    road_map
        The map; None runs the system without one (every vehicle is in fault, 5.4).
    settings
        Warning, look-ahead and activation settings.
    """

    def __init__(self, road_map: RoadMap | None, settings: EngineSettings = EngineSettings()) -> None:
        self.road_map = road_map
        self.settings = settings
        self.lookahead = LookAhead(road_map, settings.lookahead, settings.warning) if road_map is not None else None
        self.statuses: dict[str, VehicleStatus] = {}

    def status(self, vehicle_id: str) -> VehicleStatus:
        """The vehicle's current status (a new vehicle starts switched on, in standby)."""
        return self.statuses.get(vehicle_id, _NEW_STATUS)

    def switch(self, vehicle_id: str, on: bool) -> VehicleStatus:
        """The driver switches CSWS on or off for a vehicle (5.2)."""
        self.statuses[vehicle_id] = switch(self.status(vehicle_id), on)
        return self.statuses[vehicle_id]

    def forget(self, vehicle_id: str) -> None:
        """Drop a vehicle's status (it left the simulation, or its session expired)."""
        self.statuses.pop(vehicle_id, None)

    def evaluate(self, vehicle: VehicleInput) -> Answer:
        """The answer for one vehicle; its status is updated (the same answer :meth:`evaluate_many` gives)."""
        status = self._next_status(vehicle)
        if not status.warns:
            return Answer(vehicle.vehicle_id, status.state, status.fault, no_warning(), None)
        path = self.lookahead(vehicle.lane_id, vehicle.lane_pos_m, vehicle.speed_kmh, vehicle.category,
                              vehicle.route_edges)
        distance_m = path.cpoi_distance_m
        batch = evaluate_batch(np.array([vehicle.speed_kmh], dtype=float), np.array([column_index(vehicle.category)]),
                               np.zeros(distance_m.size, dtype=np.intp), distance_m, path.cpoi_radius_m,
                               self.settings.warning)
        warning = batch.vehicle_warning(0, 0, path.cpoi_curve_id, path.cpoi_part_index, path.kind)
        return Answer(vehicle.vehicle_id, status.state, status.fault, warning, path)

    def _next_status(self, vehicle: VehicleInput) -> VehicleStatus:
        """Update and return the vehicle's status (5.2-5.4).

        Raises
        ------
        ValueError
            For an unknown category, before anything about the vehicle changes.
        """
        column_index(vehicle.category)
        status = next_status(
            self.status(vehicle.vehicle_id),
            vehicle.speed_kmh,
            timestamp_s=vehicle.timestamp_s,
            age_s=vehicle.age_s,
            found_fault=self._found_fault(vehicle),
            settings=self.settings.activation,
        )
        self.statuses[vehicle.vehicle_id] = status
        return status

    def evaluate_many(self, vehicles: Sequence[VehicleInput]) -> list[Answer]:
        """The answers for many vehicles, in order.

        The state machine runs per vehicle; the look-ahead and the warning of every
        active vehicle are computed together, in one vectorised step each.
        """
        statuses: list[VehicleStatus] = []
        active: list[int] = []
        for i, vehicle in enumerate(vehicles):
            status = self._next_status(vehicle)
            statuses.append(status)
            if status.warns:
                active.append(i)
        warnings: list[CurveWarning] = [no_warning()] * len(vehicles)
        paths: list[PathAhead | None] = [None] * len(vehicles)
        if active:
            for i, warning, path in zip(active, *self._warnings([vehicles[i] for i in active])):
                warnings[i], paths[i] = warning, path
        return [
            Answer(vehicle.vehicle_id, status.state, status.fault, warning, path)
            for vehicle, status, warning, path in zip(vehicles, statuses, warnings, paths)
        ]

    def _found_fault(self, vehicle: VehicleInput) -> Fault | None:
        """What prevents a path ahead (5.4): no map, no lane, or a lane position that is not a number."""
        if self.road_map is None:
            return Fault.NO_MAP
        if vehicle.lane_id is None or not self.road_map.has_lane(vehicle.lane_id):
            return Fault.NO_MAP_MATCH
        if not math.isfinite(vehicle.lane_pos_m):
            return Fault.INVALID_INPUT
        return None

    def _warnings(self, vehicles: Sequence[VehicleInput]) -> tuple[list[CurveWarning], list[PathAhead]]:
        """Look-ahead and clause 6 for active vehicles on known lanes, each in one vectorised step."""
        speed_kmh = np.array([v.speed_kmh for v in vehicles], dtype=float)
        columns = np.array([column_index(v.category) for v in vehicles], dtype=np.intp)
        ahead = self.lookahead.many(
            [v.lane_id for v in vehicles], np.array([v.lane_pos_m for v in vehicles], dtype=float), speed_kmh,
            [v.route_edges for v in vehicles],
        )
        batch = evaluate_batch(speed_kmh, columns, ahead.cpoi_vehicle, ahead.cpoi_distance_m, ahead.cpoi_radius_m,
                               self.settings.warning)
        first = np.searchsorted(ahead.cpoi_vehicle, np.arange(len(vehicles) + 1)).tolist()
        warnings = [
            batch.vehicle_warning(i, first[i], ahead.cpoi_curve_id[first[i]:first[i + 1]],
                                  ahead.cpoi_part_index[first[i]:first[i + 1]], horizon.kind)
            if level else no_warning(horizon.kind)  # most vehicles: nothing to look at
            for i, (level, horizon) in enumerate(zip(batch.level.tolist(), ahead.horizons))
        ]
        return warnings, ahead.paths_ahead()
