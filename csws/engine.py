"""Turns each vehicle's state into its answer (the system of clauses 5 and 6), for one vehicle or a fleet.

:class:`Engine` ties the parts together for the co-simulation, the HTTP service and
library users alike, so that the same input gives the same answer everywhere:

road map -> look-ahead (path and CPOIs) -> warning (clause 6) -> system state (5.2-5.4).

It keeps each vehicle's :class:`~csws.state.VehicleStatus` between updates, and what
its warning needs for the release rule (:mod:`csws.warning.release`): a level that is on goes
off 1 km/h below V_w, not before 1 s has passed, and at once behind the curve. Many
vehicles are evaluated together with :meth:`Engine.evaluate_many`: the path ahead is
found per vehicle, and the warning of all of them is computed in one vectorised step.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, fields
from operator import attrgetter
from typing import cast

import numpy as np

from csws.ahead.horizon import BatchAhead, PathAhead
from csws.ahead.lookahead import LookAhead, LookAheadSettings
from csws.answers import Answer, FleetAnswers, TargetColumns
from csws.road.roadmap import RoadMap
from csws.state import ActivationSettings, Fault, SystemState, VehicleStatus, next_status, next_statuses, switch
from csws.warning import latency
from csws.warning.fleet import judged, keep_memories, keep_memory, with_recalled
from csws.warning.release import NOT_HELD, HeldWarning
from csws.warning.rules import BatchWarnings, WarningSettings, column_index, column_indices, no_warning
from csws.warning.single import judge_one

__all__ = ["VehicleInput", "Answer", "FleetAnswers", "TargetColumns", "EngineSettings", "VehicleMemory", "Engine"]


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
class EngineSettings:
    """Everything the engine can be tuned with: warning, look-ahead and activation settings."""

    warning: WarningSettings = field(default_factory=WarningSettings)
    lookahead: LookAheadSettings = field(default_factory=LookAheadSettings)
    activation: ActivationSettings = field(default_factory=ActivationSettings)


#: The fields of a :class:`VehicleInput`, in the order :meth:`Engine.evaluate_fleet` takes them as columns.
_INPUT_FIELD_NAMES = tuple(input_field.name for input_field in fields(VehicleInput))
_INPUT_FIELDS = attrgetter(*_INPUT_FIELD_NAMES)

#: The status of a vehicle not seen before (shared: statuses are immutable).
_NEW_STATUS = VehicleStatus()


@dataclass(frozen=True)
class VehicleMemory:
    """What the engine keeps of one vehicle from one update to the next.

    A service that answers a vehicle's updates in several processes keeps this between
    them (:meth:`Engine.memory`, :meth:`Engine.restore`), so that each update is answered
    as if one engine had seen them all.

    Attributes
    ----------
    status
        The system state (5.2-5.4): switch, activation latch, last accepted timestamp, fault.
    held
        What the release rule keeps of the warning (:mod:`csws.warning.release`).
    intervals_s
        The last intervals between its accepted fixes, s, oldest first: its update period is
        learnt from them (:mod:`csws.warning.latency`).
    """

    status: VehicleStatus = _NEW_STATUS
    held: HeldWarning = NOT_HELD
    intervals_s: tuple[float, ...] = ()


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
        self.held: dict[str, HeldWarning] = {}
        self.intervals: dict[str, tuple[float, ...]] = {}

    def status(self, vehicle_id: str) -> VehicleStatus:
        """The vehicle's current status (a new vehicle starts switched on, in standby)."""
        return self.statuses.get(vehicle_id, _NEW_STATUS)

    def switch(self, vehicle_id: str, on: bool) -> VehicleStatus:
        """The driver switches CSWS on or off for a vehicle (5.2)."""
        self.statuses[vehicle_id] = switch(self.status(vehicle_id), on)
        return self.statuses[vehicle_id]

    def memory(self, vehicle_id: str) -> VehicleMemory:
        """What the engine keeps of the vehicle (that of a new vehicle when it has none)."""
        return VehicleMemory(
            self.status(vehicle_id), self.held.get(vehicle_id, NOT_HELD), self.intervals.get(vehicle_id, ())
        )

    def restore(self, vehicle_id: str, memory: VehicleMemory) -> None:
        """Take up a vehicle where :meth:`memory` (of this engine or another one) left it."""
        self.statuses[vehicle_id] = memory.status
        if memory.intervals_s:
            self.intervals[vehicle_id] = memory.intervals_s
        else:
            self.intervals.pop(vehicle_id, None)
        if memory.held.is_on:
            self.held[vehicle_id] = memory.held
        else:
            self.held.pop(vehicle_id, None)

    def forget(self, vehicle_id: str) -> None:
        """Drop a vehicle's status and warning memory (it left the simulation, or its session expired)."""
        self.statuses.pop(vehicle_id, None)
        self.held.pop(vehicle_id, None)
        self.intervals.pop(vehicle_id, None)

    def update_period_s(self, vehicle_id: str, warning: WarningSettings | None = None) -> float:
        """The vehicle's update period as the warning takes it now: learnt from its timestamps, or the
        configured one (:mod:`csws.warning.latency`; of ``warning`` where given, else the engine's), s."""
        return latency.update_period_s(self.intervals.get(vehicle_id, ()), warning or self.settings.warning)

    def _update_periods_s(self, vehicle_ids: Sequence[str], warning: WarningSettings) -> np.ndarray:
        """:meth:`update_period_s` of many vehicles (:func:`csws.warning.latency.update_periods_s`), s."""
        return np.array(latency.update_periods_s(self.intervals, vehicle_ids, warning), dtype=float)

    def _learn_interval(self, vehicle_id: str, last_timestamp_s: float | None, status: VehicleStatus) -> None:
        """Add the interval between the vehicle's last accepted fix and this one, if it was accepted."""
        before = self.intervals.get(vehicle_id, ())
        after = latency.next_intervals(before, last_timestamp_s, status.last_timestamp_s)
        if after is not before:
            self.intervals[vehicle_id] = after

    def evaluate(self, vehicle: VehicleInput, warning: WarningSettings | None = None) -> Answer:
        """The answer for one vehicle; its status is updated (the same answer :meth:`evaluate_many` gives).
        ``warning``: the warning settings of this vehicle's fleet, where they are not the engine's
        (:meth:`evaluate_fleet`)."""
        settings = warning or self.settings.warning
        vehicle_id = vehicle.vehicle_id
        last_timestamp_s = self.status(vehicle_id).last_timestamp_s
        status = self._next_status(vehicle)
        self._learn_interval(vehicle_id, last_timestamp_s, status)
        if not status.warns:
            self.held.pop(vehicle_id, None)
            return Answer(vehicle_id, status.state, status.fault, no_warning(), None)
        period_s = self.update_period_s(vehicle_id, settings)
        age_s = latency.fix_age_s(vehicle.age_s)
        path = self._lookahead_on_map()(
            _lanes_of_active((vehicle.lane_id,))[0],
            vehicle.lane_pos_m,
            vehicle.speed_kmh,
            vehicle.category,
            vehicle.route_edges,
            period_s,
            age_s,
        )
        judged_warning, memory = judge_one(
            float(vehicle.speed_kmh),
            column_index(vehicle.category),
            path.cpoi_points(),
            path.kind,
            self.held.get(vehicle_id, NOT_HELD),
            vehicle.timestamp_s,
            settings,
            period_s,
            age_s,
        )
        keep_memory(self.held, vehicle_id, memory)
        return Answer(vehicle_id, status.state, status.fault, judged_warning, path)

    def _lookahead_on_map(self) -> LookAhead:
        """The look-ahead of the map; a vehicle is active (5.2) only where there is one."""
        if self.lookahead is None:
            raise RuntimeError("no path ahead without a road map: no vehicle is active then (5.4)")
        return self.lookahead

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
            found_fault=self._found_fault(vehicle.lane_id, vehicle.lane_pos_m),
            settings=self.settings.activation,
        )
        self.statuses[vehicle.vehicle_id] = status
        return status

    def evaluate_many(self, vehicles: Sequence[VehicleInput]) -> list[Answer]:
        """The answers for many vehicles, in order (:meth:`evaluate_fleet` of their columns, with paths)."""
        ids, categories, speeds, lanes, positions, routes, times, ages = _input_columns(vehicles)
        fleet = self.evaluate_fleet(ids, categories, speeds, lanes, positions, routes, timestamp_s=times, age_s=ages)
        paths: list[PathAhead | None] = [None] * len(vehicles)
        if fleet.ahead is not None:
            for i, path in zip(fleet.active, fleet.ahead.paths_ahead(), strict=False):
                paths[i] = path
        return list(map(Answer, fleet.vehicle_id, fleet.state, fleet.fault, fleet.warning, paths))

    def evaluate_fleet(
        self,
        vehicle_ids: Sequence[str],
        categories: Sequence[str],
        speed_kmh: Sequence[float],
        lane_ids: Sequence[str | None],
        lane_pos_m: Sequence[float],
        route_edges: Sequence[Sequence[str] | None],
        *,
        timestamp_s: Sequence[float | None] | None = None,
        age_s: Sequence[float | None] | None = None,
        warning: WarningSettings | None = None,
    ) -> FleetAnswers:
        """The answers for many vehicles given as columns (the fields of :class:`VehicleInput`), in order.

        The system state of every vehicle (5.2-5.4) is updated in one vectorised step; the
        look-ahead and the warning of every active vehicle are computed together, in one
        vectorised step each. A fleet whose vehicles keep their route objects from step to
        step (the co-simulation's) shares the look-up of their horizons.

        ``warning`` are the warning settings of these vehicles' fleet where they are not the engine's:
        its update period, whether it is learnt and up to what, and the release rule (a service's fleets
        share one engine per network). The look-ahead's latency is the engine's; only those fields may
        differ.

        Raises
        ------
        ValueError
            For an unknown category, before any vehicle's status changes.
        """
        columns = column_indices(categories)
        speeds_kmh = np.asarray(speed_kmh, dtype=float)
        positions_m = np.asarray(lane_pos_m, dtype=float)
        before = [self.statuses.get(vehicle_id, _NEW_STATUS) for vehicle_id in vehicle_ids]
        statuses = next_statuses(
            before,
            speeds_kmh,
            timestamp_s=timestamp_s,
            age_s=age_s,
            found_fault=self._found_faults(lane_ids, positions_m),
            settings=self.settings.activation,
        )
        self.statuses.update(zip(vehicle_ids, statuses, strict=False))
        latency.learn_intervals(
            self.intervals,
            vehicle_ids,
            [status.last_timestamp_s for status in before],
            [status.last_timestamp_s for status in statuses],
        )
        states = [status.state for status in statuses]
        active = [i for i, state in enumerate(states) if state is SystemState.ACTIVE]
        everyone = len(active) == len(states)
        if not everyone:
            self._forget_warnings_of_inactive(vehicle_ids, states)
        ahead = judgement = None
        if active:
            rows = np.array(active, dtype=np.intp)
            ahead, judgement = self._warnings(
                warning or self.settings.warning,
                _of_active(vehicle_ids, active, everyone),
                [None] * len(active) if timestamp_s is None else _of_active(timestamp_s, active, everyone),
                [0.0] * len(active) if age_s is None else [latency.fix_age_s(age_s[i]) for i in active],
                speeds_kmh[rows],
                columns[rows],
                _lanes_of_active(_of_active(lane_ids, active, everyone)),
                positions_m[rows],
                _of_active(route_edges, active, everyone),
            )
        return FleetAnswers(vehicle_ids, states, [status.fault for status in statuses], active, ahead, judgement)

    def _forget_warnings_of_inactive(self, vehicle_ids: Sequence[str], states: Sequence[SystemState]) -> None:
        """Drop the warning memory of every vehicle that is not active: its warning is off (5.2-5.4)."""
        if self.held:
            for vehicle_id, state in zip(vehicle_ids, states, strict=False):
                if state is not SystemState.ACTIVE:
                    self.held.pop(vehicle_id, None)

    def _found_faults(self, lane_ids: Sequence[str | None], lane_pos_m: np.ndarray) -> list[Fault | None]:
        """:meth:`_found_fault` of many vehicles: one look at the positions, one look-up per lane."""
        if self.road_map is None:
            return [Fault.NO_MAP] * len(lane_ids)
        has_lane = self.road_map.has_lane
        finite = np.isfinite(lane_pos_m).tolist()
        return [
            None if lane_id is not None and has_lane(lane_id) and ok else self._found_fault(lane_id, float(position))
            for lane_id, ok, position in zip(lane_ids, finite, lane_pos_m.tolist(), strict=False)
        ]

    def _found_fault(self, lane_id: str | None, lane_pos_m: float) -> Fault | None:
        """What prevents a path ahead (5.4): no map, no lane, or a lane position that is not a number."""
        if self.road_map is None:
            return Fault.NO_MAP
        if lane_id is None or not self.road_map.has_lane(lane_id):
            return Fault.NO_MAP_MATCH
        if not math.isfinite(lane_pos_m):
            return Fault.INVALID_INPUT
        return None

    def _warnings(
        self,
        warning: WarningSettings,
        vehicle_ids: Sequence[str],
        now_s: Sequence[float | None],
        age_s: Sequence[float],
        speed_kmh: np.ndarray,
        columns: np.ndarray,
        lane_ids: Sequence[str],
        lane_pos_m: np.ndarray,
        route_edges: Sequence[Sequence[str] | None],
    ) -> tuple[BatchAhead, BatchWarnings]:
        """Look-ahead and clause 6 for active vehicles on known lanes, each in one vectorised step."""
        periods_s = self._update_periods_s(vehicle_ids, warning)
        ages_s = np.array(age_s, dtype=float)
        ahead = self._lookahead_on_map().many(lane_ids, lane_pos_m, speed_kmh, route_edges, periods_s, ages_s)
        kept = self.held
        held = [kept.get(vehicle_id, NOT_HELD) for vehicle_id in vehicle_ids] if kept else [NOT_HELD] * len(lane_ids)
        ahead, recalled = with_recalled(held, now_s, speed_kmh, warning.hold_s(periods_s), ahead)
        first = np.searchsorted(ahead.cpoi_vehicle, np.arange(len(lane_ids) + 1)).tolist()
        batch, memories = judged(ahead, first, held, now_s, periods_s, ages_s, speed_kmh, columns, recalled, warning)
        keep_memories(kept, vehicle_ids, memories, held)
        return ahead, batch


def _input_columns(vehicles: Sequence[VehicleInput]) -> list[Sequence]:
    """The fields of the vehicles as columns, in :data:`_INPUT_FIELD_NAMES`' order, read in one pass."""
    columns: list[Sequence] = list(zip(*map(_INPUT_FIELDS, vehicles), strict=True))
    return columns if columns else [()] * len(_INPUT_FIELD_NAMES)


def _of_active(column: Sequence, active: Sequence[int], everyone: bool) -> list:
    """The entries of a fleet's column at the rows of its active vehicles (``everyone`` when all are)."""
    return list(column) if everyone else [column[i] for i in active]


def _lanes_of_active(lane_ids: Sequence[str | None]) -> list[str]:
    """The lanes of active vehicles: each is on one, or it would be in fault (5.4: no map match)."""
    if None in lane_ids:
        raise RuntimeError("an active vehicle has no lane: it should be in fault (5.4)")
    return cast("list[str]", list(lane_ids))
