"""When each vehicle must be evaluated again: only where a curve warning can arise (``--evaluate scheduled``).

A vehicle without a warning can be warned (6.1) only once a CPOI is within S_w + the latency
allowance of it, and that distance is at most formula (1) with V_w = 0 plus the allowance at
the fastest speed it can reach (:func:`csws.ahead.lookahead.lookahead_distances_m`: the same
bound sizes the look-ahead distance S_LAD). SUMO caps a vehicle's speed at the lane's speed
limit times its speed factor, and at its type's maximum speed, so its fastest speed is known
when it departs (:func:`speed_bound_mps`). From the path ahead the engine found at its last
evaluation, the distance ``d`` to the start of the first curve part still ahead (or to the end
of that path when none is on it), the vehicle cannot come within that bound ``D`` before it has
driven ``d - D``: it is not read or evaluated before then (:meth:`WakeSchedule.sleep`).

Lanes of one road differ a little in length along a bend, so a vehicle that changes lanes may find
the curve slightly nearer than on its old lane: :data:`LANE_CHANGE_MARGIN_M` and
:data:`LANE_CHANGE_MARGIN_SHARE` of ``d`` are taken off. A route changed while asleep changes the
path only beyond the vehicle's current edge, which lies on the path found; the path is followed to
its end, so the vehicle wakes before it can come near anything the new route puts after it.

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
from bisect import bisect_right
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import ClassVar

import numpy as np

from csws.ahead.horizon import END_MARGIN_M, Horizon
from csws.ahead.lookahead import lookahead_distances_m
from csws.engine import VehicleMemory
from csws.standard import mps_to_kmh
from csws.warning.latency import KEPT_INTERVALS, next_intervals
from csws.warning.settings import WarningSettings

__all__ = [
    "LANE_CHANGE_MARGIN_M",
    "LANE_CHANGE_MARGIN_SHARE",
    "WakeSchedule",
    "caught_up",
    "distance_to_first_part_m",
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


def caught_up(memory: VehicleMemory, skipped_times_s: Sequence[float]) -> VehicleMemory:
    """A vehicle's engine memory after fixes at ``skipped_times_s`` (in order, each later than its last
    accepted one) that carried no warning: each is accepted, and adds its interval (:mod:`csws.warning.latency`)."""
    last_s, intervals_s = memory.status.last_timestamp_s, memory.intervals_s
    for time_s in skipped_times_s:
        intervals_s = next_intervals(intervals_s, last_s, time_s)
        last_s = time_s
    return VehicleMemory(replace(memory.status, last_timestamp_s=last_s), memory.held, intervals_s)


def distance_to_first_part_m(horizon: Horizon, vehicle_s: float) -> tuple[float, float]:
    """The path distance from ``vehicle_s`` to the start of the first curve part not yet passed (0 inside one),
    or to the end of the path when no part is ahead, m; and the smallest lane-length per path-length
    factor of the path's lanes (a lane position advances ``factor`` times the path's arc length)."""
    return _PartsAhead.of(horizon).distance_m(vehicle_s)


class _PartsAhead:
    """A horizon's parts ordered by where they end, with the nearest start among each one and those ending
    after it: the first part not passed is then one bisection away (built once per horizon)."""

    #: The horizons seen, by identity (each kept alive with its parts); emptied when it holds this many.
    _CAPACITY: ClassVar[int] = 20_000
    _cache: ClassVar[dict[int, tuple[Horizon, _PartsAhead]]] = {}

    def __init__(self, horizon: Horizon) -> None:
        order = np.argsort(horizon.part_end_s, kind="stable")
        self.ends_s = (horizon.part_end_s[order] + END_MARGIN_M).tolist()
        starts_s = horizon.part_start_s[order]
        self.nearest_start_s = np.minimum.accumulate(starts_s[::-1])[::-1].tolist()
        self.length_m = horizon.path.length_m
        self.factor = float(np.min(horizon.path.lane_position_factor))

    @classmethod
    def of(cls, horizon: Horizon) -> _PartsAhead:
        """The parts of ``horizon`` (built at its first use)."""
        found = cls._cache.get(id(horizon))
        if found is not None and found[0] is horizon:
            return found[1]
        if len(cls._cache) >= cls._CAPACITY:
            cls._cache.clear()
        parts = cls(horizon)
        cls._cache[id(horizon)] = (horizon, parts)
        return parts

    def distance_m(self, vehicle_s: float) -> tuple[float, float]:
        """:func:`distance_to_first_part_m` of a vehicle at ``vehicle_s``."""
        first = bisect_right(self.ends_s, vehicle_s)
        end_s = self.nearest_start_s[first] if first < len(self.ends_s) else self.length_m
        return max(end_s - vehicle_s, 0.0), self.factor


class WakeSchedule:
    """Per vehicle, the step from which it is evaluated again; the vehicles kept awake are evaluated every step.

    Parameters
    ----------
    step_s
        SUMO's step length, s.
    warning
        The engine's warning settings: formula (1)'s g and the latency allowance of 6.1.
    """

    def __init__(self, step_s: float, warning: WarningSettings) -> None:
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

    def awake_next_step(self, speeds_mps: np.ndarray, distances_m: np.ndarray, factors: np.ndarray) -> np.ndarray:
        """Whether :meth:`sleep` would keep each vehicle awake whatever its speed bound, acceleration and update
        period, by its speed (m/s), its distance to the first curve part (m) and its lane position factor: a CPOI
        could come within reach at the next step even at its present speed and the step as update period (the
        reach and the distance driven only grow with the bound, the acceleration and the period), or its factor
        is not positive. One array test for the many vehicles near a curve instead of one schedule each.
        """
        clear_m = distances_m * (1.0 - LANE_CHANGE_MARGIN_SHARE) - LANE_CHANGE_MARGIN_M
        with np.errstate(divide="ignore", invalid="ignore"):
            nearest_m = clear_m - self.step_s * speeds_mps / factors
        reach_m = lookahead_distances_m(mps_to_kmh(speeds_mps), self.warning, 0.0, self.step_s)
        return (factors <= 0.0) | (nearest_m <= reach_m)

    def sleep(
        self,
        step: int,
        vehicle_id: str,
        speed_mps: float,
        distance_m: float,
        position_factor: float,
        update_period_s: float | None = None,
    ) -> None:
        """Put a vehicle without a warning to sleep after its evaluation at ``step``, until the first step
        at which a CPOI ``distance_m`` ahead on its path (or the end of that path) could come within
        S_w + the allowance of it at the fastest speed it can reach by then; the allowance for the longer of
        its update period as the engine takes it (``update_period_s``, the configured one where None) and a step."""
        bound_mps = max(self.speed_bound_mps.get(vehicle_id, math.inf), speed_mps)
        if not (math.isfinite(bound_mps) and bound_mps > 0.0 and position_factor > 0.0):
            return
        period_s = max(self.warning.update_period_s if update_period_s is None else update_period_s, self.step_s)
        drive = _Drive(speed_mps, bound_mps, self.accel_mps2.get(vehicle_id, math.inf), self.step_s)
        clear_m = distance_m * (1.0 - LANE_CHANGE_MARGIN_SHARE) - LANE_CHANGE_MARGIN_M

        def can_warn(steps: int) -> bool:
            """Whether a CPOI could be within S_w + allowance ``steps`` steps on."""
            reach_m = lookahead_distances_m(float(mps_to_kmh(drive.speed_mps(steps))), self.warning, 0.0, period_s)
            return clear_m - drive.lane_m(steps) / position_factor <= reach_m

        steps = _first(can_warn)
        if steps < 2:
            return
        wake = step + steps
        self.wake_step[vehicle_id] = wake
        self.slept_at[vehicle_id] = step
        self._waking.setdefault(wake, []).append(vehicle_id)

    def forget(self, vehicle_ids: Sequence[str]) -> None:
        """Drop vehicles that left."""
        for vehicle_id in vehicle_ids:
            self.speed_bound_mps.pop(vehicle_id, None)
            self.accel_mps2.pop(vehicle_id, None)
            self.wake_step.pop(vehicle_id, None)
            self.slept_at.pop(vehicle_id, None)


class _Drive:
    """The farthest a vehicle can go: from ``speed_mps`` its speed rises by at most ``accel_mps2`` per second
    (SUMO's car-following models never accelerate faster) up to ``bound_mps``, and each step it advances
    that step's speed times the step (SUMO's default Euler update; the ballistic one advances less)."""

    def __init__(self, speed_mps: float, bound_mps: float, accel_mps2: float, step_s: float) -> None:
        self.speed0_mps, self.bound_mps, self.step_s = speed_mps, bound_mps, step_s
        self.gain_mps = accel_mps2 * step_s
        #: Steps at which the speed still rises below the bound.
        rises = 0.0 < self.gain_mps < math.inf
        self.rising = math.floor((bound_mps - speed_mps) / self.gain_mps) if rises else 0

    def speed_mps(self, steps: int) -> float:
        """The highest speed after ``steps`` steps, m/s."""
        return self.bound_mps if steps > self.rising else self.speed0_mps + self.gain_mps * steps

    def lane_m(self, steps: int) -> float:
        """The longest lane distance driven in ``steps`` steps, m."""
        rising = min(steps, self.rising)  # 0 where the gain is infinite: the speed is at its bound at once
        rising_m = rising * self.speed0_mps + self.gain_mps * rising * (rising + 1) / 2 if rising else 0.0
        return self.step_s * (rising_m + (steps - rising) * self.bound_mps)


def _first(holds: Callable[[int], bool], most: int = 1 << 24) -> int:
    """The first step from 1 on at which ``holds`` (false until then, true from then on), found by doubling
    then halving; ``most`` when it holds at none up to it."""
    if holds(1):
        return 1
    low, high = 1, 2
    while not holds(high):
        if high >= most:
            return most
        low, high = high, 2 * high
    while high - low > 1:
        middle = (low + high) // 2
        if holds(middle):
            high = middle
        else:
            low = middle
    return high
