"""When each vehicle must be evaluated again: only where a curve warning can arise (``--evaluate scheduled``).

A vehicle without a warning can be warned (6.1) at a CPOI only once its speed V reaches the CPOI's V_w
and the CPOI is within S_w + the latency allowance: ``0.8 v + (v^2 - v_w^2) / g`` (formula (1)) plus
``v`` times the latency. SUMO caps a vehicle's speed at the lane's limit times its speed factor, and at
its type's maximum speed, so its fastest speed is known when it departs (:func:`speed_bound_mps`). From
the path ahead the engine found at its last evaluation: the distance ``d`` to the nearest start of a
curve part still ahead, and a V_w below that of every such part (:func:`lowest_warning_speeds_mps`, at
the part's tightest radius less the widest road's width: a road's lanes hold its curve at R - d on the
inside, so a lane change may tighten it that much). The vehicle cannot be warned there before it has
driven ``d - S_w`` at a speed of at least that V_w. Beyond the end of that path lies road the engine has
not looked at, where any V_w may come: it must also be evaluated again before it could come within
S_w + allowance with V_w = 0 (the look-ahead's own bound, :func:`csws.ahead.lookahead.lookahead_distances_m`)
of that end. It is not read or evaluated before the earlier of the two (:meth:`WakeSchedule.sleep`).

Lanes of one road differ a little in length along a bend, so a vehicle that changes lanes may find
the curve slightly nearer than on its old lane: :data:`LANE_CHANGE_MARGIN_M` and
:data:`LANE_CHANGE_MARGIN_SHARE` of ``d`` are taken off. A route SUMO changes while the vehicle
sleeps (a rerouter, its rerouting device) can leave the path found at any junction ahead, before the
curve it slept towards: such a vehicle is woken at the step its route id changes
(:class:`csws.cosim.sumo.Simulation` reads the route id of the sleeping vehicles SUMO may reroute, and of
no others).

Vehicles inside a warning, held by the release rule, answered by the driver-response model or just
departed are evaluated every step (the run keeps them awake). A vehicle SUMO starts to teleport
(out of a jam, to somewhere ahead) is woken at that step.

A woken vehicle is answered as if it had been evaluated at every step: the engine's memory of it
(its last accepted timestamp and the intervals its update period is learnt from) is brought up to the
steps it slept through (:func:`caught_up`), as the engine would have kept it had it seen each of them.
A vehicle is in fault (5.4) only off every lane, while SUMO teleports it, and it is awake then.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import replace
from itertools import repeat
from typing import NamedTuple

import numpy as np

from csws.ahead.horizon import END_MARGIN_M, Horizon
from csws.ahead.lookahead import lookahead_distances_m
from csws.engine import VehicleMemory
from csws.standard import Column, Level, WarningSpeedPolicy, kmh_to_mps, mps_to_kmh
from csws.warning.latency import KEPT_INTERVALS, next_intervals
from csws.warning.settings import WarningSettings

from .fastest import FastestDrive, first_step

__all__ = [
    "LANE_CHANGE_MARGIN_M",
    "LANE_CHANGE_MARGIN_SHARE",
    "WakeSchedule",
    "PartsAhead",
    "RoadAhead",
    "caught_up",
    "lowest_accelerations_mps2",
    "lowest_warning_speeds_mps",
    "speed_bound_mps",
]

#: Taken off the distance to the first curve part for a lane change while asleep, m.
LANE_CHANGE_MARGIN_M = 10.0
#: And this share of that distance (lanes of a bend differ in length by their offset over the radius).
LANE_CHANGE_MARGIN_SHARE = 0.05


def speed_bound_mps(max_speed_mps: float, speed_factor: float, fastest_lane_mps: float) -> float:
    """The fastest a vehicle can drive in SUMO, m/s: its type's maximum speed, and the fastest lane's
    speed limit times its speed factor (SUMO's own cap on the speed its driver chooses)."""
    return min(max_speed_mps, speed_factor * fastest_lane_mps)


#: Taken off each V_w bound, km/h: V_w is rounded to 1e-9 km/h (:mod:`csws.standard`).
_ROUNDING_KMH = 1e-6


def lowest_accelerations_mps2(policy: WarningSpeedPolicy) -> np.ndarray:
    """Per column of Tables 1-2 (in ``Column``'s order), the least lateral acceleration of the policy at its radii,
    of either level, m/s^2: V_w = sqrt(a R) with ``a`` interpolated between the policy's radii and held beyond them
    (:meth:`csws.standard.WarningSpeedPolicy.warning_speeds_kmh`), so V_w is never below sqrt(a_min R)."""
    levels = (Level.LEVEL_1, Level.LEVEL_2)
    return np.array(
        [min(float(policy.lateral_acceleration_mps2(column, level).min()) for level in levels) for column in Column]
    )


def lowest_warning_speeds_mps(radius_m: np.ndarray, lowest_mps2: np.ndarray) -> np.ndarray:
    """Per column (rows) and radius, a speed below V_w of both levels at that radius and at every larger one, m/s:
    sqrt(a_min R) (``lowest_mps2``: :func:`lowest_accelerations_mps2`) less V_w's rounding; 0 at a radius of 0 or
    less."""
    speeds_mps = np.sqrt(lowest_mps2[:, None] * np.maximum(np.asarray(radius_m, dtype=float), 0.0)[None, :])
    return np.maximum(speeds_mps - kmh_to_mps(_ROUNDING_KMH), 0.0)


class RoadAhead(NamedTuple):
    """What a sleeping vehicle's schedule reads of its path ahead, one entry per vehicle.

    Attributes
    ----------
    curve_m
        Path distance to the nearest start of a curve part not yet passed, m: 0 inside one, inf where none is ahead.
    end_m
        Path distance to the end of the path, m.
    warning_speed_mps
        A speed below the V_w of every such part for the vehicle's column (:func:`lowest_warning_speeds_mps`),
        m/s; inf where none is ahead.
    factor
        The smallest lane-length per path-length factor of the path's lanes (a lane position advances
        ``factor`` times the path's arc length).
    """

    curve_m: np.ndarray
    end_m: np.ndarray
    warning_speed_mps: np.ndarray
    factor: np.ndarray

    def of(self, rows: np.ndarray) -> RoadAhead:
        """The entries of the vehicles at ``rows``."""
        return RoadAhead(*(column[rows] for column in self))


def caught_up(memory: VehicleMemory, skipped_times_s: Sequence[float]) -> VehicleMemory:
    """A vehicle's engine memory after fixes at ``skipped_times_s`` (in order, each later than its last
    accepted one) that carried no warning: each is accepted, and adds its interval (:mod:`csws.warning.latency`)."""
    last_s, intervals_s = memory.status.last_timestamp_s, memory.intervals_s
    for time_s in skipped_times_s:
        intervals_s = next_intervals(intervals_s, last_s, time_s)
        last_s = time_s
    return VehicleMemory(replace(memory.status, last_timestamp_s=last_s), memory.held, intervals_s)


class PartsAhead:
    """The curve parts of many horizons in flat arrays, ordered by where they end within each horizon, with the
    nearest start and the lowest V_w bound among each part and those ending after it: the first part not passed by
    each of many vehicles is then one vectorised bisection away (each horizon is laid out once, at its first use).

    The pool keeps every horizon it holds alive (so that a horizon's ``id`` names its slot) and is emptied when it
    would hold more than ``capacity`` of them.

    Parameters
    ----------
    capacity
        The most horizons held.
    policy
        The warning speeds (Tables 1-2 by default).
    radius_margin_m
        Taken off each part's radius before its V_w bound: the most a lane change can tighten a bend (the widest
        road's width: its lanes hold its curve at R - d on the inside, :mod:`csws.road.sharing`), m.
    """

    def __init__(
        self, capacity: int = 20_000, policy: WarningSpeedPolicy | None = None, radius_margin_m: float = 0.0
    ) -> None:
        self.capacity = capacity
        self.lowest_mps2 = lowest_accelerations_mps2(WarningSpeedPolicy() if policy is None else policy)
        self.radius_margin_m = radius_margin_m
        self.clear()

    def clear(self) -> None:
        """Forget every horizon."""
        self._horizons: list[Horizon] = []
        self._slot_of: dict[int, int] = {}
        #: Per slot: its first part in the part arrays, its number of parts, its path's length (m) and factor.
        self._first, self._count = np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.intp)
        self._length_m, self._factor = np.zeros(0), np.zeros(0)
        #: Per part: its end with the end margin, and the nearest start among it and the parts after it, s (m).
        self._ends_s, self._nearest_start_s = np.zeros(0), np.zeros(0)
        #: Per column and part: the lowest V_w bound among it and the parts after it, m/s.
        self._slowest_mps = np.zeros((len(Column), 0))

    def ahead(self, horizons: Sequence[Horizon], vehicle_s: np.ndarray, columns: np.ndarray) -> RoadAhead:
        """Per vehicle at ``vehicle_s`` on its horizon, of column ``columns`` (indices into ``Column``), the road
        ahead as its schedule reads it (:class:`RoadAhead`). A part counts until
        :data:`~csws.ahead.horizon.END_MARGIN_M` after its end."""
        slots = self._slots(horizons)
        low, high = self._first[slots], self._first[slots] + self._count[slots]
        found = _bisect_right(self._ends_s, vehicle_s, low, high)
        ahead = found < high
        if ahead.any():
            first = np.where(ahead, found, 0)
            curve_s = np.where(ahead, self._nearest_start_s[first], math.inf)
            slowest_mps = np.where(ahead, self._slowest_mps[columns, first], math.inf)
        else:
            curve_s = slowest_mps = np.full(slots.size, math.inf)
        end_m = np.maximum(self._length_m[slots] - vehicle_s, 0.0)
        return RoadAhead(np.maximum(curve_s - vehicle_s, 0.0), end_m, slowest_mps, self._factor[slots])

    def _slots(self, horizons: Sequence[Horizon]) -> np.ndarray:
        """The slot of each horizon, laying out those not yet in the pool (emptied first when it would overflow)."""
        ids = list(map(id, horizons))
        found = list(map(self._slot_of.get, ids))
        if None in found:
            new = {ids[k]: horizons[k] for k, slot in enumerate(found) if slot is None}
            if len(self._horizons) + len(new) > self.capacity:
                self.clear()
                new = dict(zip(ids, horizons, strict=True))
            self._extend(list(new.values()))
            found = list(map(self._slot_of.get, ids))
        return np.array(found, dtype=np.intp)

    def _extend(self, horizons: list[Horizon]) -> None:
        """Lay out horizons' parts in new slots."""
        orders = [np.argsort(horizon.part_end_s, kind="stable") for horizon in horizons]
        counts = np.array([order.size for order in orders], dtype=np.intp)
        ends_s = [h.part_end_s[order] + END_MARGIN_M for h, order in zip(horizons, orders, strict=True)]
        starts_s = [h.part_start_s[order][::-1] for h, order in zip(horizons, orders, strict=True)]
        nearest_s = [np.minimum.accumulate(reversed_s)[::-1] for reversed_s in starts_s]
        slowest = self._suffix_slowest_mps(horizons, orders, counts)
        first = self._ends_s.size + np.cumsum(counts) - counts
        self._first, self._count = np.concatenate([self._first, first]), np.concatenate([self._count, counts])
        lengths_m = np.array([horizon.path.length_m for horizon in horizons], dtype=float)
        factors = np.array([np.min(horizon.path.lane_position_factor) for horizon in horizons], dtype=float)
        self._length_m = np.concatenate([self._length_m, lengths_m])
        self._factor = np.concatenate([self._factor, factors])
        self._ends_s = np.concatenate([self._ends_s, *ends_s])
        self._nearest_start_s = np.concatenate([self._nearest_start_s, *nearest_s])
        self._slowest_mps = np.concatenate([self._slowest_mps, slowest], axis=1)
        for horizon in horizons:
            self._slot_of[id(horizon)] = len(self._horizons)
            self._horizons.append(horizon)

    def _suffix_slowest_mps(self, horizons: list[Horizon], orders: list[np.ndarray], counts: np.ndarray) -> np.ndarray:
        """Per column and part of ``horizons`` (each in its ``order``), the lowest V_w bound among the part and those
        after it on its horizon, m/s: at the part's tightest radius (its ends'; a spiral piece's curvature runs
        linearly between them) less the margin."""
        tightest_m = np.concatenate(
            [
                np.minimum(h.part_radius_m[order], h.part_end_radius_m[order])
                for h, order in zip(horizons, orders, strict=True)
            ]
            + [np.zeros(0)]
        )
        speeds_mps = lowest_warning_speeds_mps(tightest_m - self.radius_margin_m, self.lowest_mps2)
        ends = np.cumsum(counts).tolist()
        for start, end in zip([0, *ends], ends, strict=False):
            if end > start:
                speeds_mps[:, start:end] = np.minimum.accumulate(speeds_mps[:, start:end][:, ::-1], axis=1)[:, ::-1]
        return speeds_mps


def _bisect_right(values: np.ndarray, x: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """Per element, :func:`bisect.bisect_right` of ``x`` in the sorted run ``values[low:high]`` (a position
    within ``[low, high]``), for many runs of one flat array at once."""
    while True:
        open_ = low < high
        if not open_.any():
            return low
        middle = np.where(open_, (low + high) // 2, 0)
        right = values[middle] <= x
        low = np.where(open_ & right, middle + 1, low)
        high = np.where(open_ & ~right, middle, high)


class WakeSchedule:
    """Per vehicle, the step from which it is evaluated again; the vehicles kept awake are evaluated every step.

    Parameters
    ----------
    step_s
        SUMO's step length, s.
    warning
        The engine's warning settings: formula (1)'s g, the warning speeds and the latency allowance of 6.1.
    road_width_m
        The widest road's width, m: the most a lane change can tighten a bend (:class:`PartsAhead`).
    """

    def __init__(self, step_s: float, warning: WarningSettings, road_width_m: float = 0.0) -> None:
        self.step_s = step_s
        self.warning = warning
        self.speed_bound_mps: dict[str, float] = {}
        self.accel_mps2: dict[str, float] = {}
        #: The wake-up step of each sleeping vehicle (those not read or evaluated this step).
        self.wake_step: dict[str, int] = {}
        #: The step each sleeping vehicle was last evaluated at.
        self.slept_at: dict[str, int] = {}
        self._waking: dict[int, list[str]] = {}
        #: The times of the last steps, s, by step: enough to catch a memory up (:func:`caught_up`).
        self._times_s: deque[tuple[int, float]] = deque(maxlen=KEPT_INTERVALS + 2)
        #: The curve parts of the horizons of the vehicles evaluated, for their distances to the first part ahead.
        self.parts = PartsAhead(policy=warning.policy, radius_margin_m=road_width_m)

    def add(self, vehicle_id: str, speed_bound_mps: float, accel_mps2: float = math.inf) -> None:
        """A vehicle departed, with its speed bound (m/s) and maximum acceleration (m/s^2): awake until its
        first evaluation puts it to sleep."""
        self.speed_bound_mps[vehicle_id] = speed_bound_mps
        self.accel_mps2[vehicle_id] = accel_mps2

    def wake_due(self, step: int, everyone: bool = False) -> dict[str, int]:
        """Wake the sleeping vehicles whose wake-up step is ``step`` (every one with ``everyone``): the step
        each was last evaluated at, by vehicle. They are awake from now on."""
        waking = self._waking.pop(step, [])
        if everyone:
            waking = list(self.wake_step)
            self._waking.clear()
        # A vehicle woken early and put to sleep again until the same step is listed twice.
        woken = {v: self.slept_at[v] for v in dict.fromkeys(waking) if self.wake_step.get(v) == step or everyone}
        for vehicle_id in woken:
            del self.wake_step[vehicle_id], self.slept_at[vehicle_id]
        return woken

    def wake(self, vehicle_ids: Sequence[str]) -> dict[str, int]:
        """Wake vehicles at once (SUMO teleports them: they may reappear anywhere ahead): the step each
        sleeping one of them was last evaluated at, by vehicle."""
        woken = {v: self.slept_at.pop(v) for v in vehicle_ids if v in self.wake_step}
        for vehicle_id in woken:
            del self.wake_step[vehicle_id]
        return woken

    def stepped(self, step: int, time_s: float) -> None:
        """Note the time of a step, s (after waking its vehicles, before putting any to sleep)."""
        self._times_s.append((step, time_s))

    def skipped_times_s(self, slept_at: int) -> list[float]:
        """The times of the steps since ``slept_at`` before the current one that a catch-up needs, s: the
        last :data:`~csws.warning.latency.KEPT_INTERVALS` + 1 of them at most."""
        times = [time_s for step, time_s in self._times_s if step > slept_at]
        return times[:-1][-(KEPT_INTERVALS + 1) :]

    def awake_next_step(self, speeds_mps: np.ndarray, road: RoadAhead) -> np.ndarray:
        """Whether :meth:`sleep` would keep each vehicle awake whatever its speed bound, acceleration and update
        period, by its speed (m/s) and its road ahead: it could be warned at the next step even at its present
        speed and the step as update period (the reach and the distance driven only grow with the bound, the
        acceleration and the period), or its factor is not positive. One array test for the many vehicles near a
        curve instead of one schedule each.
        """
        reach_m = lookahead_distances_m(mps_to_kmh(speeds_mps), self.warning, 0.0, self.step_s)
        with np.errstate(divide="ignore", invalid="ignore"):
            driven_m = self.step_s * speeds_mps / road.factor
            curve = (self._curve_clear_m(road) - driven_m <= reach_m) & (speeds_mps >= road.warning_speed_mps)
            end = _clear_m(road.end_m) - driven_m <= reach_m
        return (road.factor <= 0.0) | curve | end

    def _curve_clear_m(self, road: RoadAhead) -> np.ndarray:
        """The margined distance to the nearest curve part ahead with formula (1)'s ``v_w^2 / g`` added: the
        vehicle can be warned there once that less the distance driven is within the reach with V_w = 0, m."""
        with np.errstate(invalid="ignore"):
            return _clear_m(road.curve_m) + road.warning_speed_mps**2 / self.warning.g_mps2

    def sleep(
        self,
        step: int,
        vehicle_ids: Sequence[str],
        speed_mps: np.ndarray,
        road: RoadAhead,
        update_period_s: np.ndarray | None = None,
    ) -> None:
        """Put vehicles without a warning to sleep after their evaluation at ``step``, each until the first step at
        which, at the fastest speed it can reach by then, it could be warned at a curve part of its road ahead (its
        speed at that part's V_w bound, the part within S_w + the allowance) or come within S_w + allowance with
        V_w = 0 of the end of that road; the allowance for the longer of its update period as the engine takes it
        (``update_period_s``, the configured one where None) and a step. A vehicle that could be warned within two
        steps, or has no finite positive speed bound or position factor, stays awake."""
        count = len(vehicle_ids)
        bounds_mps = np.fromiter(map(self.speed_bound_mps.get, vehicle_ids, repeat(math.inf)), float, count)
        bound_mps = np.maximum(bounds_mps, speed_mps)
        accel_mps2 = np.fromiter(map(self.accel_mps2.get, vehicle_ids, repeat(math.inf)), float, count)
        if update_period_s is None:
            update_period_s = np.full(count, self.warning.update_period_s)
        rows = np.flatnonzero(np.isfinite(bound_mps) & (bound_mps > 0.0) & (road.factor > 0.0))
        drive = FastestDrive(speed_mps[rows], bound_mps[rows], accel_mps2[rows], self.step_s)
        road = road.of(rows)
        period_s = np.maximum(update_period_s[rows], self.step_s)
        factor = road.factor

        def reach_m(speed_mps: np.ndarray, which: np.ndarray | slice = slice(None)) -> np.ndarray:
            """S_w with V_w = 0 + allowance at ``speed_mps`` of the vehicles ``which``, m."""
            return lookahead_distances_m(mps_to_kmh(speed_mps), self.warning, 0.0, period_s[which])

        def wake_steps(clear_m: np.ndarray, least_speed_mps: np.ndarray) -> np.ndarray:
            """The first step from 1 on at which a vehicle could be ``clear_m`` less its drive within the reach,
            at a speed of at least ``least_speed_mps``."""

            def can_warn(which: np.ndarray, steps: np.ndarray) -> np.ndarray:
                speed_mps = drive.speed_mps(which, steps)
                near = clear_m[which] - drive.lane_m(which, steps) / factor[which] <= reach_m(speed_mps, which)
                return near & (speed_mps >= least_speed_mps[which])

            guess = drive.first_step_guess(clear_m * factor, factor, reach_m)
            return first_step(can_warn, np.maximum(guess, drive.first_step_at(least_speed_mps)))

        curve_steps = wake_steps(self._curve_clear_m(road), road.warning_speed_mps)
        end_steps = wake_steps(_clear_m(road.end_m), np.zeros(rows.size))
        wake = step + np.minimum(curve_steps, end_steps)
        for k in np.flatnonzero(wake >= step + 2).tolist():
            vehicle_id, at = vehicle_ids[int(rows[k])], int(wake[k])
            self.wake_step[vehicle_id] = at
            self.slept_at[vehicle_id] = step
            self._waking.setdefault(at, []).append(vehicle_id)

    def forget(self, vehicle_ids: Sequence[str]) -> None:
        """Drop vehicles that left."""
        for vehicle_id in vehicle_ids:
            self.speed_bound_mps.pop(vehicle_id, None)
            self.accel_mps2.pop(vehicle_id, None)
            self.wake_step.pop(vehicle_id, None)
            self.slept_at.pop(vehicle_id, None)


def _clear_m(distance_m: np.ndarray) -> np.ndarray:
    """A distance ahead less the lane-change margins, m (:data:`LANE_CHANGE_MARGIN_M`, and
    :data:`LANE_CHANGE_MARGIN_SHARE` of it)."""
    return distance_m * (1.0 - LANE_CHANGE_MARGIN_SHARE) - LANE_CHANGE_MARGIN_M
