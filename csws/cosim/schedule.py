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

A vehicle may change lanes while asleep, unseen: the curves of the lanes beside its path count as the
path's (:mod:`csws.cosim.lanes_beside`), and since lanes of one road differ a little in length along a
bend, :data:`LANE_CHANGE_MARGIN_M` and :data:`LANE_CHANGE_MARGIN_SHARE` of ``d`` are taken off. A route
SUMO changes while the vehicle sleeps (a rerouter, its rerouting device) can leave the path found at any
junction ahead, before the curve it slept towards: such a vehicle is woken at the step its route id changes
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
from collections.abc import Callable, Sequence
from dataclasses import replace
from itertools import repeat

import numpy as np

from csws.ahead.horizon import END_MARGIN_M, Horizon
from csws.ahead.lookahead import lookahead_distances_m
from csws.engine import VehicleMemory
from csws.standard import mps_to_kmh
from csws.warning.latency import KEPT_INTERVALS, next_intervals
from csws.warning.settings import WarningSettings

from .lanes_beside import LanesBeside

__all__ = [
    "LANE_CHANGE_MARGIN_M",
    "LANE_CHANGE_MARGIN_SHARE",
    "WakeSchedule",
    "PartsAhead",
    "caught_up",
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


class PartsAhead:
    """The curve parts of many horizons in flat arrays, ordered by where they end within each horizon, with the
    nearest start among each part and those ending after it: the first part not passed by each of many vehicles is
    then one vectorised bisection away (each horizon is laid out once, at its first use).

    The pool keeps every horizon it holds alive (so that a horizon's ``id`` names its slot) and is emptied when it
    would hold more than ``capacity`` of them. With ``beside``, the curves of the lanes beside each horizon's
    lanes count as its parts too (a vehicle may change onto them while asleep: :mod:`csws.cosim.lanes_beside`).
    """

    def __init__(self, capacity: int = 20_000, beside: LanesBeside | None = None) -> None:
        self.capacity = capacity
        self.beside = beside
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

    def distances_m(self, horizons: Sequence[Horizon], vehicle_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per vehicle, the path distance from ``vehicle_s`` to the start of the first curve part of its horizon not
        yet passed (0 inside one; a part counts until :data:`~csws.ahead.horizon.END_MARGIN_M` after its end), or
        to the end of the path when no part is ahead, m; and the smallest lane-length per path-length factor of the
        path's lanes (a lane position advances ``factor`` times the path's arc length)."""
        slots = self._slots(horizons)
        low, high = self._first[slots], self._first[slots] + self._count[slots]
        found = _bisect_right(self._ends_s, vehicle_s, low, high)
        ahead = found < high
        nearest_s = self._nearest_start_s[np.where(ahead, found, 0)] if ahead.any() else vehicle_s
        end_s = np.where(ahead, nearest_s, self._length_m[slots])
        return np.maximum(end_s - vehicle_s, 0.0), self._factor[slots]

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
        spans = [self._spans_s(horizon) for horizon in horizons]
        orders = [np.argsort(span_end_s, kind="stable") for _, span_end_s in spans]
        counts = np.array([order.size for order in orders], dtype=np.intp)
        ends_s = [end_s[order] + END_MARGIN_M for (_, end_s), order in zip(spans, orders, strict=True)]
        starts_s = [start_s[order][::-1] for (start_s, _), order in zip(spans, orders, strict=True)]
        nearest_s = [np.minimum.accumulate(reversed_s)[::-1] for reversed_s in starts_s]
        first = self._ends_s.size + np.cumsum(counts) - counts
        self._first, self._count = np.concatenate([self._first, first]), np.concatenate([self._count, counts])
        lengths_m = np.array([horizon.path.length_m for horizon in horizons], dtype=float)
        factors = np.array([np.min(horizon.path.lane_position_factor) for horizon in horizons], dtype=float)
        self._length_m = np.concatenate([self._length_m, lengths_m])
        self._factor = np.concatenate([self._factor, factors])
        self._ends_s = np.concatenate([self._ends_s, *ends_s])
        self._nearest_start_s = np.concatenate([self._nearest_start_s, *nearest_s])
        for horizon in horizons:
            self._slot_of[id(horizon)] = len(self._horizons)
            self._horizons.append(horizon)

    def _spans_s(self, horizon: Horizon) -> tuple[np.ndarray, np.ndarray]:
        """Where a horizon's curve parts start and end, with the curves of the lanes beside it, m."""
        if self.beside is None:
            return horizon.part_start_s, horizon.part_end_s
        beside_start_s, beside_end_s = self.beside.spans_s(horizon.path)
        if not beside_start_s.size:
            return horizon.part_start_s, horizon.part_end_s
        return (
            np.concatenate([horizon.part_start_s, beside_start_s]),
            np.concatenate([horizon.part_end_s, beside_end_s]),
        )


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
        The engine's warning settings: formula (1)'s g and the latency allowance of 6.1.
    beside
        The curves of the lanes beside the paths, which a vehicle may change onto while asleep
        (:mod:`csws.cosim.lanes_beside`); None where every lane keeps to the path it slept on.
    """

    def __init__(self, step_s: float, warning: WarningSettings, beside: LanesBeside | None = None) -> None:
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
        #: The curve parts of the horizons of the vehicles evaluated (and of the lanes beside them), for their
        #: distances to the first part ahead.
        self.parts = PartsAhead(beside=beside)

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
        vehicle_ids: Sequence[str],
        speed_mps: np.ndarray,
        distance_m: np.ndarray,
        position_factor: np.ndarray,
        update_period_s: np.ndarray | None = None,
    ) -> None:
        """Put vehicles without a warning to sleep after their evaluation at ``step``, each until the first step at
        which a CPOI ``distance_m`` ahead on its path (or the end of that path) could come within S_w + the allowance
        of it at the fastest speed it can reach by then; the allowance for the longer of its update period as the
        engine takes it (``update_period_s``, the configured one where None) and a step. A vehicle that could be
        that near within two steps, or has no finite positive speed bound or position factor, stays awake."""
        count = len(vehicle_ids)
        bounds_mps = np.fromiter(map(self.speed_bound_mps.get, vehicle_ids, repeat(math.inf)), float, count)
        bound_mps = np.maximum(bounds_mps, speed_mps)
        accel_mps2 = np.fromiter(map(self.accel_mps2.get, vehicle_ids, repeat(math.inf)), float, count)
        if update_period_s is None:
            update_period_s = np.full(count, self.warning.update_period_s)
        rows = np.flatnonzero(np.isfinite(bound_mps) & (bound_mps > 0.0) & (position_factor > 0.0))
        drive = _Drive(speed_mps[rows], bound_mps[rows], accel_mps2[rows], self.step_s)
        clear_m = distance_m[rows] * (1.0 - LANE_CHANGE_MARGIN_SHARE) - LANE_CHANGE_MARGIN_M
        period_s = np.maximum(update_period_s[rows], self.step_s)
        factor = position_factor[rows]

        def can_warn(which: np.ndarray, steps: np.ndarray) -> np.ndarray:
            """Whether a CPOI could be within S_w + allowance ``steps`` steps on, for the vehicles ``which``."""
            speed_kmh = mps_to_kmh(drive.speed_mps(which, steps))
            reach_m = lookahead_distances_m(speed_kmh, self.warning, 0.0, period_s[which])
            return clear_m[which] - drive.lane_m(which, steps) / factor[which] <= reach_m

        def reach_m(speed_mps: np.ndarray) -> np.ndarray:
            """S_w + allowance at ``speed_mps`` of every vehicle scheduled, m."""
            return lookahead_distances_m(mps_to_kmh(speed_mps), self.warning, 0.0, period_s)

        wake = step + _first(can_warn, drive.first_step_guess(clear_m * factor, factor, reach_m))
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


class _Drive:
    """The farthest vehicles can go: from ``speed_mps`` each one's speed rises by at most ``accel_mps2`` per second
    (SUMO's car-following models never accelerate faster) up to ``bound_mps``, and each step it advances that step's
    speed times the step (SUMO's default Euler update; the ballistic one advances less). Arrays, one per vehicle."""

    def __init__(self, speed_mps: np.ndarray, bound_mps: np.ndarray, accel_mps2: np.ndarray, step_s: float) -> None:
        self.speed0_mps, self.bound_mps, self.step_s = speed_mps, bound_mps, step_s
        gain_mps = accel_mps2 * step_s
        rises = (0.0 < gain_mps) & (gain_mps < math.inf)
        #: The speed gained per step where it rises (0 where the gain is 0 or infinite: at its bound at once).
        self.gain_mps = np.where(rises, gain_mps, 0.0)
        #: Steps at which the speed still rises below the bound.
        self.rising = np.where(rises, np.floor((bound_mps - speed_mps) / np.where(rises, gain_mps, 1.0)), 0.0)

    def speed_mps(self, which: np.ndarray, steps: np.ndarray) -> np.ndarray:
        """The highest speed of the vehicles ``which`` after ``steps`` steps, m/s."""
        rising_mps = self.speed0_mps[which] + self.gain_mps[which] * steps
        return np.where(steps > self.rising[which], self.bound_mps[which], rising_mps)

    def lane_m(self, which: np.ndarray, steps: np.ndarray) -> np.ndarray:
        """The longest lane distance the vehicles ``which`` drive in ``steps`` steps, m."""
        rising = np.minimum(steps, self.rising[which])
        rising_m = np.where(rising > 0, self._rising_m(which, rising), 0.0)
        return self.step_s * (rising_m + (steps - rising) * self.bound_mps[which])

    def _rising_m(self, which: np.ndarray, rising: np.ndarray) -> np.ndarray:
        """The lane distance over the first ``rising`` steps while the speed rises, in steps (m over the step)."""
        return rising * self.speed0_mps[which] + self.gain_mps[which] * rising * (rising + 1) / 2

    def first_step_guess(
        self, target_m: np.ndarray, factor: np.ndarray, reach_m: Callable[[np.ndarray], np.ndarray]
    ) -> np.ndarray:
        """Per vehicle, the first step at which the lane distance driven plus ``factor`` times the reach at the speed
        then, ``reach_m(speed_mps)``, could be ``target_m``, as the closed form gives it: a quadratic in the steps
        while the speed still rises (the reach, formula (1) plus the allowance, is a quadratic in the speed: its
        coefficients are read from it at 1 and 2 m/s), linear once at the bound. A first guess: rounding may put it
        a step off."""
        every = np.arange(self.rising.size)
        rising_m = np.where(self.rising > 0, self._rising_m(every, self.rising), 0.0)
        reach_at_bound_m = reach_m(self.bound_mps)
        at_bound = self.rising + np.ceil(
            ((target_m - factor * reach_at_bound_m) / self.step_s - rising_m) / self.bound_mps
        )
        at_one_m, at_two_m = reach_m(np.ones(every.size)), reach_m(np.full(every.size, 2.0))
        square, linear = (at_two_m - 2.0 * at_one_m) / 2.0, at_one_m - (at_two_m - 2.0 * at_one_m) / 2.0
        speed_mps, gain_mps = self.speed0_mps, self.gain_mps
        a = self.step_s * gain_mps / 2.0 + factor * square * gain_mps**2
        b = self.step_s * (speed_mps + gain_mps / 2.0) + factor * gain_mps * (linear + 2.0 * square * speed_mps)
        c = factor * (linear * speed_mps + square * speed_mps**2) - target_m
        root = np.sqrt(np.maximum(b * b - 4.0 * a * c, 0.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            while_rising = np.ceil(np.where(a > 0.0, (root - b) / (2.0 * a), np.inf))
        guess = np.where(while_rising <= self.rising, while_rising, np.maximum(at_bound, self.rising + 1.0))
        return np.nan_to_num(guess, nan=1.0, posinf=float(_MOST), neginf=1.0)


#: The most steps a vehicle sleeps.
_MOST = 1 << 24


def _first(holds: Callable[[np.ndarray, np.ndarray], np.ndarray], guess: np.ndarray, most: int = _MOST) -> np.ndarray:
    """Per vehicle, the first step from 1 on at which ``holds(vehicles, steps)`` (false until then, true from then
    on), ``most`` where it holds at none up to it: ``guess`` where it holds there and not the step before, else
    found by doubling then halving."""
    count = guess.size
    guess = np.clip(guess, 1, most).astype(np.int64)
    which = np.arange(count)
    right = (holds(which, guess) | (guess == most)) & ((guess == 1) | ~holds(which, guess - 1))
    first = np.where(right, guess, most)
    which = which[~right]
    ones = np.ones(which.size, dtype=np.int64)
    at_once = holds(which, ones)
    first[which[at_once]] = 1
    which, low, high = which[~at_once], ones[~at_once], 2 * ones[~at_once]
    found, found_low, found_high = [], [], []
    while which.size:  # doubling: [low, high) brackets the first step where it holds at high
        held = holds(which, high)
        found.append(which[held])
        found_low.append(low[held])
        found_high.append(high[held])
        going = ~held & (high < most)
        which, low, high = which[going], high[going], 2 * high[going]
    which, low, high = (np.concatenate([np.zeros(0, dtype=np.int64), *part]) for part in (found, found_low, found_high))
    while which.size:  # halving
        wide = high - low > 1
        first[which[~wide]] = high[~wide]
        which, low, high = which[wide], low[wide], high[wide]
        if not which.size:
            break
        middle = (low + high) // 2
        held = holds(which, middle)
        low, high = np.where(held, low, middle), np.where(held, middle, high)
    return first
