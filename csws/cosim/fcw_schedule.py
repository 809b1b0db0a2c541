"""When each vehicle's forward collision warning must be evaluated again (``--evaluate scheduled`` with FCW).

A vehicle's FCW can warn (4.5) only of an object its sensor sees, one within the range of concern
(:attr:`csws.fcw.settings.FcwSettings.range_m`, the detection range of 4.3.2 a; the sensor view of
:mod:`csws.cosim.sensor` measures it from the subject's front to the object's rear, straight or
along the map path). Two vehicles' fronts are then at most :attr:`FcwSchedule.reach_m` apart: that
range, the longest vehicle, the widest road twice (a lane change moves a vehicle across its road at
once) and :data:`PAIR_MARGIN_M`. From where each vehicle was last read, each drives at most its
speed bound (SUMO's cap: the type's maximum speed, the fastest lane times its speed factor) per
second, a lane distance that is at most that over the smallest lane-length per shape-length factor of
the network in a straight line. So a vehicle's FCW cannot see anything before the first step at
which any other vehicle could be within ``reach_m`` of it (:func:`first_meeting_steps`): it is not
read or evaluated before that step. Its heading alone is read at every step while it sleeps
(:meth:`csws.cosim.fcw.FleetFcw.keep_headings`), so that its yaw rate, the turn of its heading over the
last step, is known whenever an object can first appear. The rule is symmetric, so every
vehicle an awake one could see is awake too and read as an object. A vehicle sleeps
:data:`SLEEP_CAP_S` at most, which bounds the grid search for the vehicles it could meet.

While asleep its state (4.3: standby or active, with a hysteresis on the speed) may still change: it
changes only when the speed crosses a threshold, and from the speed last read the speed rises by at
most the type's acceleration and falls by at most its emergency deceleration per second (SUMO's
car-following models never exceed either), so the speed alone is read at the first step it could
cross one (:func:`steps_state_kept`) and the state is brought up to date there.

Vehicles warned, held (4.5.5), answered by the driver-response model, in fault or switched off are
evaluated every step. A vehicle that appears (departs, or ends a teleport) is read at once and wakes
each sleeping vehicle it could come within ``reach_m`` of (at once if it is that near already, with the
yaw rate its heading read at the step before gives).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from csws.fcw.settings import FcwSettings
from csws.fcw.state import ACTIVE, STANDBY

from .sensor import LONGEST_VEHICLE_M, nearby_pairs

__all__ = [
    "PAIR_MARGIN_M",
    "SLEEP_CAP_S",
    "FcwSchedule",
    "first_meeting_steps",
    "network_spread",
    "steps_state_kept",
]

#: Added to the distance at which two vehicles' fronts may be when one sees the other, m.
PAIR_MARGIN_M = 20.0
#: The longest a vehicle's FCW sleeps, s.
SLEEP_CAP_S = 5.0
#: A vehicle sleeps only if no other can meet it within this many steps (:meth:`FcwSchedule.sleep`: it sleeps
#: at least one step, and wakes at the first step another could meet it).
FEW_STEPS = 2
#: At most this many steps between two searches for vehicles to put to sleep.
SEARCH_GAP_MOST_STEPS = 8
#: A step index beyond any run.
NEVER = 1 << 62


def first_meeting_steps(
    distance_m: np.ndarray,
    reach_m: float,
    now_step: int,
    bound_mps: np.ndarray,
    other_bound_mps: np.ndarray,
    other_read_step: np.ndarray,
    step_s: float,
    position_factor: float,
) -> np.ndarray:
    """The first step at which two vehicles ``distance_m`` apart could be within ``reach_m`` of each other.

    One is read at ``now_step``, the other at ``other_read_step`` (at or before it); each drives at most
    its bound (m/s) per second from then, as lane distance, at most that over ``position_factor`` in a
    straight line. ``now_step`` where they could be that near already.
    """
    per_step = step_s / position_factor
    closing_m = (bound_mps + other_bound_mps) * per_step
    head_start_m = other_bound_mps * (now_step - other_read_step) * per_step
    gap_m = distance_m - reach_m - head_start_m
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        steps = np.where(closing_m > 0.0, np.ceil(gap_m / closing_m), math.inf)
    return np.where(gap_m <= 0.0, float(now_step), now_step + np.maximum(steps, 0.0))


def steps_state_kept(
    state: int, speed_mps: float, settings: FcwSettings, accel_mps2: float, decel_mps2: float, step_s: float
) -> int:
    """How many steps on from a step at ``speed_mps`` in ``state`` the FCW state can first change (4.3, Figure 2).

    An active system leaves the band [V_min - δ, V_max + δ], a standby one (driving slower or faster)
    enters [V_min, V_max]; the speed changes by at most ``accel_mps2`` up and ``decel_mps2`` down per
    second. 0 for other states (kept awake), :data:`NEVER` where no threshold can be reached.
    """
    rise_mps, fall_mps = accel_mps2 * step_s, decel_mps2 * step_s
    low, high = settings.min_speed_mps, settings.max_speed_mps
    gaps: tuple[tuple[float, float], ...]
    if state == ACTIVE:
        gaps = (
            (speed_mps - (low - settings.hysteresis_mps), fall_mps),
            (high + settings.hysteresis_mps - speed_mps, rise_mps),
        )
    elif state == STANDBY and speed_mps < low:
        gaps = ((low - speed_mps, rise_mps),)
    elif state == STANDBY and speed_mps > high:
        gaps = ((speed_mps - high, fall_mps),)
    else:
        return 0
    steps = [math.floor(gap / change) if change > 0.0 else NEVER for gap, change in gaps]
    return max(1, min(steps))


def network_spread(lane: Any) -> tuple[float, float]:
    """The widest road's width (the sum of its lanes' widths), m, and the smallest lane-length per
    shape-length factor of the network's lanes (at most 1), read once through SUMO's ``lane`` domain."""
    widths: dict[str, float] = {}
    factor = 1.0
    for lane_id in lane.getIDList():
        edge = lane.getEdgeID(lane_id)
        widths[edge] = widths.get(edge, 0.0) + float(lane.getWidth(lane_id))
        shape = np.asarray(lane.getShape(lane_id), dtype=float)
        shape_m = float(np.hypot(*np.diff(shape, axis=0).T).sum()) if len(shape) > 1 else 0.0
        if shape_m > 0.0:
            factor = min(factor, float(lane.getLength(lane_id)) / shape_m)
    return max(widths.values(), default=0.0), factor


class FcwSchedule:
    """Per vehicle, the step from which its FCW is read and evaluated again, and the steps its speed is read.

    Parameters
    ----------
    step_s
        SUMO's step length, s.
    range_m
        The largest range of concern of the categories, m.
    road_width_m, position_factor
        :func:`network_spread` of the network.
    """

    def __init__(self, step_s: float, range_m: float, road_width_m: float, position_factor: float) -> None:
        self.step_s = step_s
        self.reach_m = range_m + LONGEST_VEHICLE_M + 2.0 * road_width_m + PAIR_MARGIN_M
        self.position_factor = min(position_factor, 1.0)
        self.cap_steps = max(2, round(SLEEP_CAP_S / step_s))
        self.slot: dict[str, int] = {}
        self.x_m, self.y_m = np.zeros(0), np.zeros(0)
        self.bound_mps, self.read_step = np.zeros(0), np.zeros(0, dtype=np.int64)
        self.alive = np.zeros(0, dtype=bool)
        #: Each vehicle's type's acceleration and emergency deceleration, m/s^2.
        self.limits_mps2: dict[str, tuple[float, float]] = {}
        self.speed_bound_mps: dict[str, float] = {}
        #: The wake-up step of each sleeping vehicle.
        self.wake_step: dict[str, int] = {}
        self._waking: dict[int, list[str]] = {}
        #: The step each sleeping vehicle's speed is read next (to bring its state up to date).
        self._checking: dict[int, list[str]] = {}
        self.check_step: dict[str, int] = {}
        #: The steps between searches for vehicles to put to sleep (doubled while none is found), and the next one.
        self._search_gap, self._next_search = 1, 0

    def add(
        self, vehicle_id: str, x_m: float, y_m: float, step: int, bound_mps: float, limits: tuple[float, float]
    ) -> None:
        """A vehicle appeared (departed or ended a teleport) at ``x_m``, ``y_m`` this ``step``: awake."""
        slot = self.slot.get(vehicle_id)
        if slot is None:
            slot = self.slot[vehicle_id] = len(self.slot)
            if slot >= self.x_m.size:
                self._grow(max(64, 2 * self.x_m.size))
        self.speed_bound_mps[vehicle_id], self.limits_mps2[vehicle_id] = bound_mps, limits
        self._note(np.array([slot]), np.array([x_m]), np.array([y_m]), np.array([bound_mps]), step)
        self.wake([vehicle_id])

    def _grow(self, size: int) -> None:
        """Room for ``size`` vehicles."""
        more = size - self.x_m.size
        self.x_m, self.y_m = np.append(self.x_m, np.zeros(more)), np.append(self.y_m, np.zeros(more))
        self.bound_mps = np.append(self.bound_mps, np.zeros(more))
        self.read_step = np.append(self.read_step, np.zeros(more, dtype=np.int64))
        self.alive = np.append(self.alive, np.zeros(more, dtype=bool))

    def _note(self, slots: np.ndarray, x_m: np.ndarray, y_m: np.ndarray, bound_mps: np.ndarray, step: int) -> None:
        """Where vehicles were read at ``step`` and how fast they can drive from there."""
        self.x_m[slots], self.y_m[slots], self.bound_mps[slots] = x_m, y_m, bound_mps
        self.read_step[slots], self.alive[slots] = step, True

    def appeared(self, step: int, vehicle_ids: Sequence[str]) -> list[str]:
        """Wake, from ``step`` on, the sleeping vehicles the vehicles just added could come near: those that could
        meet them at once are returned (awake now), the others' wake-up is brought forward where it is later."""
        if not vehicle_ids or not self.wake_step:
            return []
        sleeping = list(self.wake_step)
        slots = np.array([self.slot[v] for v in sleeping])
        meets = np.full(slots.size, math.inf)
        for vehicle_id in vehicle_ids:
            new = self.slot[vehicle_id]
            distance_m = np.hypot(self.x_m[slots] - self.x_m[new], self.y_m[slots] - self.y_m[new])
            meet = first_meeting_steps(
                distance_m,
                self.reach_m,
                step,
                np.full(slots.size, self.bound_mps[new]),
                self.bound_mps[slots],
                self.read_step[slots],
                self.step_s,
                self.position_factor,
            )
            meets = np.minimum(meets, meet)
        now = []
        for vehicle_id, meet in zip(sleeping, meets.tolist(), strict=True):
            wake = int(meet) if math.isfinite(meet) else NEVER
            if wake <= step:
                now.append(vehicle_id)
            elif wake < self.wake_step[vehicle_id]:
                self._sleep_until(vehicle_id, wake)
        self.wake(now)
        return now

    def wake_due(self, step: int, everyone: bool = False) -> list[str]:
        """Wake the vehicles due at ``step`` (every sleeping one with ``everyone``)."""
        listed = self._waking.pop(step, [])  # a vehicle woken early and put to sleep until ``step`` again is twice
        due = list(self.wake_step) if everyone else [v for v in dict.fromkeys(listed) if self.wake_step.get(v) == step]
        self.wake(due)
        return due

    def wake(self, vehicle_ids: Iterable[str]) -> None:
        """Wake vehicles at once."""
        for vehicle_id in vehicle_ids:
            self.wake_step.pop(vehicle_id, None)
            self.check_step.pop(vehicle_id, None)

    def checks_due(self, step: int) -> list[str]:
        """The sleeping vehicles whose speed is read at ``step`` (:meth:`checked` reschedules them)."""
        due = [v for v in dict.fromkeys(self._checking.pop(step, [])) if self.check_step.get(v) == step]
        for vehicle_id in due:
            del self.check_step[vehicle_id]
        return due

    def check_after(self, step: int, vehicle_id: str, steps: int) -> None:
        """Read a sleeping vehicle's speed ``steps`` steps after ``step`` (not if it wakes by then)."""
        check = step + steps
        if vehicle_id in self.wake_step and check < self.wake_step[vehicle_id]:
            self.check_step[vehicle_id] = check
            self._checking.setdefault(check, []).append(vehicle_id)

    def sleep(
        self,
        step: int,
        vehicle_ids: Sequence[str],
        x_m: np.ndarray,
        y_m: np.ndarray,
        speed_mps: np.ndarray,
        quiet: np.ndarray,
    ) -> list[str]:
        """Note where the vehicles read at ``step`` are, and put the ``quiet`` ones (no warning or hold) to sleep
        until the first step at which any vehicle could be within :attr:`reach_m` of them; those put to sleep."""
        slots = np.array([self.slot[v] for v in vehicle_ids], dtype=np.int64)
        bounds = np.array([self.speed_bound_mps[v] for v in vehicle_ids])
        self._note(slots, x_m, y_m, np.maximum(bounds, speed_mps), step)
        subjects = slots[quiet]
        if not subjects.size or step < self._next_search:
            return []
        wake = np.minimum(self._first_meetings(step, subjects), float(step + self.cap_steps))
        rows = np.flatnonzero(quiet)
        asleep = []
        for k in np.flatnonzero(wake >= step + 2).tolist():
            vehicle_id = vehicle_ids[int(rows[k])]
            self._sleep_until(vehicle_id, int(wake[k]))
            asleep.append(vehicle_id)
        # Searching costs a step's time; in dense traffic it finds nobody: search less often then (a vehicle
        # kept awake longer is evaluated as at every step, which changes no answer).
        self._search_gap = 1 if asleep else min(2 * self._search_gap, SEARCH_GAP_MOST_STEPS)
        self._next_search = step + self._search_gap
        return asleep

    def _sleep_until(self, vehicle_id: str, wake: int) -> None:
        """Put a vehicle to sleep until ``wake``."""
        self.wake_step[vehicle_id] = wake
        self._waking.setdefault(wake, []).append(vehicle_id)

    def _first_meetings(self, step: int, subjects: np.ndarray) -> np.ndarray:
        """Per subject slot, the first step any other vehicle could be within :attr:`reach_m` of it, up to the
        sleep cap: first among the vehicles near enough to meet it within :data:`FEW_STEPS` (in traffic most
        subjects stay awake there), then, for the others, among those that could meet it before the cap."""
        first = self._meetings_within(step, subjects, FEW_STEPS)
        open_ = np.flatnonzero(first >= step + FEW_STEPS)
        if open_.size:
            first[open_] = self._meetings_within(step, subjects[open_], self.cap_steps)
        return first

    def _meetings_within(self, step: int, subjects: np.ndarray, steps: int) -> np.ndarray:
        """:meth:`_first_meetings` among the vehicles in the grid cells around each subject, cells wide enough
        that every vehicle that could meet it within ``steps`` is in them (a vehicle not read for a while,
        e.g. teleporting, widens them); later meetings may be missed (the first found is then later)."""
        alive = np.flatnonzero(self.alive)
        fastest_mps = float(self.bound_mps[alive].max())
        stale = step - int(self.read_step[alive].min())
        cell_m = self.reach_m + fastest_mps * (2 * steps + stale + 1) * self.step_s / self.position_factor
        x_m, y_m = self.x_m[alive], self.y_m[alive]
        cell_x = ((x_m - x_m.min()) // cell_m).astype(np.int64) + 1
        cell_y = ((y_m - y_m.min()) // cell_m).astype(np.int64) + 1
        owner, other = nearby_pairs(cell_x, cell_y, np.searchsorted(alive, subjects))
        other = alive[other]
        keep = other != subjects[owner]
        owner, other = owner[keep], other[keep]
        me = subjects[owner]
        distance_m = np.hypot(self.x_m[other] - self.x_m[me], self.y_m[other] - self.y_m[me])
        meet = first_meeting_steps(
            distance_m,
            self.reach_m,
            step,
            self.bound_mps[me],
            self.bound_mps[other],
            self.read_step[other],
            self.step_s,
            self.position_factor,
        )
        first = np.full(subjects.size, math.inf)
        np.minimum.at(first, owner, meet)
        return first

    def forget(self, vehicle_ids: Sequence[str]) -> None:
        """Drop vehicles that left (their slots are not given again)."""
        for vehicle_id in vehicle_ids:
            slot = self.slot.get(vehicle_id)
            if slot is not None:
                self.alive[slot] = False
            self.wake([vehicle_id])
            self.speed_bound_mps.pop(vehicle_id, None)
            self.limits_mps2.pop(vehicle_id, None)
