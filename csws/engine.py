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
from .warning import CurveWarning, HmiHint, PathKind, WarningSettings, column_index, evaluate_batch

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


def _no_warning(path_kind: PathKind) -> CurveWarning:
    """A warning of level 0."""
    return CurveWarning(Level.NONE, None, (), path_kind, HmiHint.for_level(Level.NONE))


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
        return self.statuses.get(vehicle_id, VehicleStatus())

    def switch(self, vehicle_id: str, on: bool) -> VehicleStatus:
        """The driver switches CSWS on or off for a vehicle (5.2)."""
        self.statuses[vehicle_id] = switch(self.status(vehicle_id), on)
        return self.statuses[vehicle_id]

    def forget(self, vehicle_id: str) -> None:
        """Drop a vehicle's status (it left the simulation, or its session expired)."""
        self.statuses.pop(vehicle_id, None)

    def evaluate(self, vehicle: VehicleInput) -> Answer:
        """The answer for one vehicle; its status is updated."""
        return self.evaluate_many([vehicle])[0]

    def evaluate_many(self, vehicles: Sequence[VehicleInput]) -> list[Answer]:
        """The answers for many vehicles, in order; the warnings are computed in one vectorised step."""
        paths: list[PathAhead | None] = []
        statuses: list[VehicleStatus] = []
        for vehicle in vehicles:
            path, map_fault = self._path_ahead(vehicle)
            status = next_status(
                self.status(vehicle.vehicle_id),
                vehicle.speed_kmh,
                timestamp_s=vehicle.timestamp_s,
                age_s=vehicle.age_s,
                map_fault=map_fault,
                settings=self.settings.activation,
            )
            self.statuses[vehicle.vehicle_id] = status
            paths.append(path if status.warns else None)
            statuses.append(status)
        warnings = self._warnings(vehicles, paths)
        return [
            Answer(vehicle.vehicle_id, status.state, status.fault, warning, path)
            for vehicle, status, warning, path in zip(vehicles, statuses, warnings, paths)
        ]

    def _path_ahead(self, vehicle: VehicleInput) -> tuple[PathAhead | None, Fault | None]:
        """The path ahead, or the map fault that prevents it (5.4)."""
        if self.lookahead is None:
            return None, Fault.NO_MAP
        if vehicle.lane_id is None:
            return None, Fault.NO_MAP_MATCH
        if not (math.isfinite(vehicle.speed_kmh) and vehicle.speed_kmh >= 0):
            return None, None  # the state machine reports the invalid input
        try:
            return (
                self.lookahead(
                    vehicle.lane_id, vehicle.lane_pos_m, vehicle.speed_kmh, vehicle.category, vehicle.route_edges
                ),
                None,
            )
        except KeyError:
            return None, Fault.NO_MAP_MATCH

    def _warnings(self, vehicles: Sequence[VehicleInput], paths: Sequence[PathAhead | None]) -> list[CurveWarning]:
        """Clause 6 for every vehicle with a path, in one batch."""
        counts = np.array([0 if p is None else p.cpoi_distance_m.size for p in paths], dtype=np.intp)
        if counts.sum() == 0:
            return [_no_warning(p.kind if p is not None else PathKind.PREDICTED) for p in paths]
        with_cpois = [p for p in paths if p is not None and p.cpoi_distance_m.size]
        batch = evaluate_batch(
            np.array([v.speed_kmh for v in vehicles], dtype=float),
            np.array([column_index(v.category) for v in vehicles], dtype=np.intp),
            np.repeat(np.arange(len(vehicles)), counts),
            np.concatenate([p.cpoi_distance_m for p in with_cpois]),
            np.concatenate([p.cpoi_radius_m for p in with_cpois]),
            self.settings.warning,
        )
        offsets = (np.cumsum(counts) - counts).tolist()
        return [
            _no_warning(PathKind.PREDICTED)
            if path is None
            else batch.vehicle_warning(i, offsets[i], path.cpoi_curve_id, path.cpoi_part_index, path.kind)
            for i, path in enumerate(paths)
        ]
