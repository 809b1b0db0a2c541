"""The forward collision warning in SUMO: each equipped vehicle's sensor view of the vehicles around it.

Each step :class:`FleetFcw` reads every SUMO vehicle once, turns the vehicles around each equipped
vehicle into that vehicle's object list (:mod:`csws.cosim.sensor`: the sensor view, with the objects'
lanes from the vehicle's map path where it is map-matched), and calls the object FCW's fleet form
(:func:`csws.fcw.fleet.update_fleet`) once per category (4.3.3: V_max by category,
:meth:`csws.fcw.settings.FcwSettings.for_category`).

The subject's yaw rate is its angle's change over the step (SUMO's angle is its body's heading,
clockwise from north); the brake light is the driver braking (4.5.4), the blinkers the turn signal.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Container, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from csws.fcw.fleet import FleetEgo, FleetFrame, FleetMemory, FleetObjects, update_fleet
from csws.fcw.path import yaw_path_curvature_1pm
from csws.fcw.settings import FcwSettings
from csws.fcw.state import ACTIVE, FCW_STATES, STANDBY, fcw_state_code

from .driver import DriverResponse
from .fcw_schedule import FcwSchedule, steps_state_kept
from .records import StepValues, Summary
from .schedule import speed_bound_mps
from .sensor import (
    BLINKER_LEFT,
    BLINKER_RIGHT,
    BRAKE_LIGHT,
    ID_BITS,
    MAX_ID_MASK,
    SensorPairs,
    SumoVehicles,
    VehicleNumbers,
    map_lanes,
    read_vehicles,
    sensor_view,
)
from .sumo import FleetState

__all__ = [
    "Measure",
    "FcwColumns",
    "FleetFcw",
    "FCW_TIMESERIES_FIELDS",
    "FCW_EVENT_COLUMNS",
    "fcw_events",
]

#: What a sensor makes of the true view (the conformance suite's test equipment): ego and objects in, measured out.
Measure = Callable[[FleetEgo, FleetObjects], tuple[FleetEgo, FleetObjects]]

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
    """The object FCW of every equipped vehicle in SUMO, one :func:`csws.fcw.fleet.update_fleet` per category a step.

    Each vehicle keeps its memory (state, held level, the objects in its path and cutting in, its
    last angle for the yaw rate) by its number between steps, while it drives.

    Parameters
    ----------
    sumo
        libsumo or traci, with a simulation running.
    settings
        The settings of a category (default :meth:`csws.fcw.settings.FcwSettings.for_category`).
    measure
        What the sensor makes of the true view, or None (the truth).
    """

    def __init__(
        self,
        sumo: Any,
        settings: Callable[[str], FcwSettings] = FcwSettings.for_category,
        measure: Measure | None = None,
    ) -> None:
        self.sumo = sumo
        self.settings_of = settings
        self.measure = measure
        self.numbers = VehicleNumbers()
        self.sizes: dict[str, tuple[float, float]] = {}
        self.roads: dict[str, int] = {}
        self.horizons: dict[int, Any] = {}
        self.categories: dict[str, int] = {}
        self.distinct_settings: list[FcwSettings] = []
        self.memory = FleetMemory.new(0)
        self.last_heading_rad = np.zeros(0)
        #: When each vehicle's heading was last read, s (a sleeping subject's too: :meth:`keep_headings`).
        self.heading_time_s = np.zeros(0)
        self.last_time_s = -math.inf
        #: Each subject's category, and the vehicles read in the last call with the subjects' rows among them.
        self.category_of: dict[str, str] = {}
        self.read: SumoVehicles | None = None
        self.subject_rows = np.zeros(0, dtype=np.int64)

    def __call__(
        self,
        vehicle_ids: Sequence[str],
        categories: Sequence[str],
        on_lane: Sequence[bool],
        paths: Sequence[Any | None] | None = None,
        asleep: Container[str] = (),
    ) -> FcwColumns:
        """The warning of every equipped vehicle (``vehicle_ids``, of ``categories``), in order; a vehicle on
        no lane is in fault (4.4.5). ``paths``: each vehicle's map path ahead where it is map-matched (a
        :class:`csws.ahead.horizon.PathAhead`, else None; the curve warning's horizon), which assigns the
        objects' lanes (:func:`sensor_view`). The vehicles ``asleep`` are not read (none can be seen,
        :mod:`csws.cosim.fcw_schedule`)."""
        now_s = float(self.sumo.simulation.getTime())
        if not vehicle_ids:  # no subject: nothing to read or evaluate
            self.read, self.last_time_s = None, now_s
            self.memory.in_path_keys = self.memory.cut_in_keys = np.zeros(0, np.int64)
            return FcwColumns.quiet([])
        vehicles = self.read = read_vehicles(self.sumo, self.numbers, self.sizes, self.roads, asleep)
        row_of = {vehicle_id: row for row, vehicle_id in enumerate(vehicles.vehicle_id)}
        rows = self.subject_rows = np.array([row_of[vehicle_id] for vehicle_id in vehicle_ids], dtype=np.int64)
        self.category_of.update(zip(vehicle_ids, categories, strict=True))
        numbers = vehicles.number[rows]
        self._grow(int(vehicles.number.max()) + 1 if vehicles.number.size else 0)
        yaw_rate = self._yaw_rate_rps(numbers, vehicles.heading_rad[rows], now_s)
        # SUMO's angle is the body's chord (rear and front on the lane): the front runs along the
        # lane's tangent, turned from it by half the length times the path's curvature.
        kappa = yaw_path_curvature_1pm(vehicles.speed_mps[rows], np.nan_to_num(yaw_rate))
        path_turn_rad = kappa * vehicles.length_m[rows] / 2.0
        columns = FcwColumns.quiet([FCW_STATES[STANDBY].value] * len(rows))
        kinds = np.array([self._settings_code(category) for category in categories], dtype=np.int64)
        ranges_m = np.array([settings.range_m for settings in self.distinct_settings])[kinds]
        sensor_ok = np.asarray(on_lane, dtype=bool)
        keys = []
        # One sensor view per range for every subject with it (all categories share 200 m), split by settings.
        for range_m in dict.fromkeys(ranges_m.tolist()):
            viewers = np.flatnonzero(ranges_m == range_m)
            lanes = None
            if paths is not None:
                lanes = map_lanes([paths[i] for i in viewers.tolist()], self.roads, range_m, self.horizons)
            # Objects in another lane change no answer (4.5.5 b); a measuring sensor draws its noise for every one.
            other_lanes = self.measure is not None
            view = sensor_view(vehicles, rows[viewers], range_m, path_turn_rad[viewers], lanes, other_lanes)
            for kind in dict.fromkeys(kinds[viewers].tolist()):
                members = kinds[viewers] == kind
                group = viewers[members]
                ego = _ego(vehicles, rows[group], yaw_rate[group], sensor_ok[group])
                pairs = view.of_subjects(members)
                frame, in_path_keys, cut_in_keys = self._update(
                    self.distinct_settings[kind], numbers[group], now_s, ego, pairs, vehicles
                )
                keys.append((in_path_keys, cut_in_keys))
                _write(columns, group, frame, vehicles.vehicle_id, pairs.seen)
        self.memory.in_path_keys = np.sort(np.concatenate([k[0] for k in keys])) if keys else np.zeros(0, np.int64)
        self.memory.cut_in_keys = np.sort(np.concatenate([k[1] for k in keys])) if keys else np.zeros(0, np.int64)
        self.last_time_s = now_s
        return columns

    def _update(
        self,
        settings: FcwSettings,
        numbers: np.ndarray,
        now_s: float,
        ego: FleetEgo,
        pairs: SensorPairs,
        vehicles: SumoVehicles,
    ) -> tuple[FleetFrame, np.ndarray, np.ndarray]:
        """One :func:`update_fleet` call for the subjects ``numbers`` of one settings, their sensor view
        ``pairs``: the frame, and the objects' keys kept (in the path, cutting in) by number."""
        objects = pairs.objects(vehicles)
        if self.measure is not None:
            ego, objects = self.measure(ego, objects)
        frame, kept = update_fleet(settings, self._recall(numbers), now_s, ego, objects)
        return frame, *self._keep(numbers, kept)

    def _settings_code(self, category: str) -> int:
        """A category's settings as an index into :attr:`distinct_settings`, made once (categories with
        equal settings share one index, so one :func:`update_fleet` call)."""
        code = self.categories.get(category)
        if code is None:
            settings = self.settings_of(category)
            known = self.distinct_settings
            code = self.categories[category] = known.index(settings) if settings in known else len(known)
            if code == len(known):
                known.append(settings)
        return code

    def _grow(self, count: int) -> None:
        """Room in the memory for vehicle numbers below ``count`` (new ones standby, nothing held)."""
        have = self.memory.state.size
        if count <= have:
            return
        more = FleetMemory.new(max(count, 2 * have) - have)
        memory = self.memory
        memory.state = np.concatenate((memory.state, more.state))
        memory.held_level = np.concatenate((memory.held_level, more.held_level))
        memory.hold_until_s = np.concatenate((memory.hold_until_s, more.hold_until_s))
        memory.last_time_s = np.concatenate((memory.last_time_s, more.last_time_s))
        self.last_heading_rad = np.concatenate((self.last_heading_rad, np.full(more.state.size, np.nan)))
        self.heading_time_s = np.concatenate((self.heading_time_s, np.full(more.state.size, -math.inf)))

    def _yaw_rate_rps(self, numbers: np.ndarray, heading_rad: np.ndarray, now_s: float) -> np.ndarray:
        """The yaw rate over the last step (positive turning left; SUMO's angle turns clockwise),
        NaN (not given) where the heading was not read at the last step (a vehicle's first step)."""
        last_time = self.heading_time_s[numbers]
        turn = (heading_rad - self.last_heading_rad[numbers] + math.pi) % (2.0 * math.pi) - math.pi
        with np.errstate(invalid="ignore", divide="ignore"):
            yaw = np.where(last_time == self.last_time_s, -turn / (now_s - last_time), np.nan)
        self.last_heading_rad[numbers] = heading_rad
        self.heading_time_s[numbers] = now_s
        return yaw

    def keep_headings(self, schedule: FcwSchedule) -> None:
        """Read the heading of each sleeping subject not read at this step (one getter each), so that its yaw rate
        over the step is known whenever it wakes: at its wake-up, or at once, when a vehicle appears (departs,
        ends a teleport) already near it (:mod:`csws.cosim.fcw_schedule`)."""
        now_s, subjects = self.last_time_s, self.category_of
        sleeping = [vehicle_id for vehicle_id in schedule.wake_step if vehicle_id in subjects]
        numbers = np.array([self.numbers[vehicle_id] for vehicle_id in sleeping], dtype=np.int64)
        unread = np.flatnonzero(self.heading_time_s[numbers] != now_s)
        if not unread.size:
            return
        get_angle = self.sumo.vehicle.getAngle
        angles_deg = [get_angle(sleeping[k]) for k in unread.tolist()]
        self.last_heading_rad[numbers[unread]] = np.radians(np.array(angles_deg, dtype=float))
        self.heading_time_s[numbers[unread]] = now_s

    def _recall(self, numbers: np.ndarray) -> FleetMemory:
        """The memory of the vehicles ``numbers``, indexed as in this call."""
        memory = self.memory
        index = np.full(memory.state.size, -1, dtype=np.int64)
        index[numbers] = np.arange(numbers.size)

        def local(keys: np.ndarray) -> np.ndarray:
            row = index[keys >> ID_BITS]
            mine = row >= 0
            return np.sort((row[mine] << ID_BITS) | (keys[mine] & MAX_ID_MASK))

        return FleetMemory(
            memory.state[numbers],
            memory.held_level[numbers],
            memory.hold_until_s[numbers],
            memory.last_time_s[numbers],
            local(memory.in_path_keys),
            local(memory.cut_in_keys),
        )

    def _keep(self, numbers: np.ndarray, kept: FleetMemory) -> tuple[np.ndarray, np.ndarray]:
        """Store a call's memory under the vehicles' numbers; its object keys by number."""
        memory = self.memory
        memory.state[numbers], memory.held_level[numbers] = kept.state, kept.held_level
        memory.hold_until_s[numbers], memory.last_time_s[numbers] = kept.hold_until_s, kept.last_time_s

        def by_number(keys: np.ndarray) -> np.ndarray:
            return (numbers[keys >> ID_BITS] << ID_BITS) | (keys & MAX_ID_MASK)

        return by_number(kept.in_path_keys), by_number(kept.cut_in_keys)

    def appeared(
        self, step: int, vehicle_ids: Sequence[str], fastest_lane_mps: float, schedule: FcwSchedule
    ) -> list[str]:
        """Add the vehicles that departed or ended a teleport at ``step`` to ``schedule``: where they are, their
        speed bound (:func:`csws.cosim.schedule.speed_bound_mps`), acceleration and emergency deceleration;
        the sleeping vehicles they woke at once."""
        vehicle = self.sumo.vehicle
        for vehicle_id in vehicle_ids:
            x_m, y_m = vehicle.getPosition(vehicle_id)
            bound_mps = speed_bound_mps(
                vehicle.getMaxSpeed(vehicle_id), vehicle.getSpeedFactor(vehicle_id), fastest_lane_mps
            )
            limits = (float(vehicle.getAccel(vehicle_id)), float(vehicle.getEmergencyDecel(vehicle_id)))
            schedule.add(vehicle_id, x_m, y_m, step, max(bound_mps, vehicle.getSpeed(vehicle_id)), limits)
        return schedule.appeared(step, vehicle_ids)

    def sleep(self, step: int, schedule: FcwSchedule, level: Sequence[int], awake: Container[str]) -> None:
        """Put to sleep the vehicles read in the last call that nothing keeps awake: a subject with a warning
        (``level``, in the subjects' order), a held level, a state other than standby or active, or ``awake``
        (answered by the driver-response model); and read each sleeping subject's speed when its state could
        change (:func:`csws.cosim.fcw_schedule.steps_state_kept`)."""
        vehicles = self.read
        if vehicles is None or not vehicles.vehicle_id:
            return
        numbers = vehicles.number[self.subject_rows]
        state, held = self.memory.state[numbers], self.memory.held_level[numbers]
        quiet = np.ones(len(vehicles.vehicle_id), dtype=bool)
        quiet[self.subject_rows] = (np.asarray(level) == 0) & (held == 0) & ((state == ACTIVE) | (state == STANDBY))
        quiet[self.subject_rows] &= [vehicles.vehicle_id[row] not in awake for row in self.subject_rows.tolist()]
        asleep = schedule.sleep(
            step, vehicles.vehicle_id, vehicles.front_x_m, vehicles.front_y_m, vehicles.speed_mps, quiet
        )
        speed_of = dict(zip(vehicles.vehicle_id, vehicles.speed_mps.tolist(), strict=True))
        for vehicle_id in asleep:
            if vehicle_id in self.category_of:
                self._check_later(step, vehicle_id, speed_of[vehicle_id], schedule)

    def check_states(self, step: int, schedule: FcwSchedule) -> None:
        """4.3: bring the state of the sleeping subjects due a speed read at ``step`` up to date (the state
        :func:`csws.fcw.fleet.update_fleet` would have given them), and schedule their next read."""
        for vehicle_id in schedule.checks_due(step):
            speed_mps = float(self.sumo.vehicle.getSpeed(vehicle_id))
            number = self.numbers[vehicle_id]
            settings = self.distinct_settings[self._settings_code(self.category_of[vehicle_id])]
            self.memory.state[number] = fcw_state_code(
                int(self.memory.state[number]), speed_mps, True, True, True, settings
            )
            self._check_later(step, vehicle_id, speed_mps, schedule)

    def _check_later(self, step: int, vehicle_id: str, speed_mps: float, schedule: FcwSchedule) -> None:
        """Schedule the next speed read of a sleeping subject at ``speed_mps`` now."""
        settings = self.distinct_settings[self._settings_code(self.category_of[vehicle_id])]
        state = int(self.memory.state[self.numbers[vehicle_id]])
        accel_mps2, decel_mps2 = schedule.limits_mps2[vehicle_id]
        steps = steps_state_kept(state, speed_mps, settings, accel_mps2, decel_mps2, schedule.step_s)
        schedule.check_after(step, vehicle_id, max(steps, 1))

    def forget(self, vehicle_ids: Sequence[str]) -> None:
        """Drop vehicles that left (their numbers are not given again)."""
        for vehicle_id in vehicle_ids:
            self.category_of.pop(vehicle_id, None)
            self.sizes.pop(vehicle_id, None)
            number = self.numbers.pop(vehicle_id, None)
            if number is not None and number < self.memory.state.size:
                self.memory.last_time_s[number] = -math.inf


def _ego(vehicles: SumoVehicles, subjects: np.ndarray, yaw_rate_rps: np.ndarray, sensor_ok: np.ndarray) -> FleetEgo:
    """The subjects' own columns (rows ``subjects`` of ``vehicles``): speed, acceleration, yaw rate, the brake
    light as the driver braking (4.5.4), the blinkers as the turn signal, whether the sensor works (4.4.5)."""
    signals = vehicles.signals[subjects]
    return FleetEgo.of(
        vehicles.speed_mps[subjects],
        vehicles.accel_mps2[subjects],
        yaw_rate_rps,
        braking=(signals & BRAKE_LIGHT) > 0,
        turn_signal=_turn_signal(signals),
        sensor_ok=sensor_ok,
    )


def _turn_signal(signals: np.ndarray) -> np.ndarray:
    """SUMO's blinkers as the turn signal: +1 left, -1 right, 0 none (or both)."""
    return ((signals & BLINKER_LEFT) > 0).astype(np.int8) - ((signals & BLINKER_RIGHT) > 0).astype(np.int8)


def _write(columns: FcwColumns, group: np.ndarray, frame: FleetFrame, vehicle_ids: list[str], seen: np.ndarray) -> None:
    """Write one call's answers into ``columns`` at the group's rows: state, level, target and its figures
    (``seen``: each object's row in ``vehicle_ids``)."""
    rows = group.tolist()
    state_names = [state.value for state in FCW_STATES]
    for row, state, level in zip(rows, frame.state.tolist(), frame.level.tolist(), strict=True):
        columns.state[row], columns.level[row] = state_names[state], level
    has = np.flatnonzero(frame.target >= 0)
    targets = seen[frame.target[has]].tolist()
    figures = zip(
        has.tolist(),
        targets,
        frame.clearance_m[has].tolist(),
        frame.relative_speed_mps[has].tolist(),
        frame.ttc_s[has].tolist(),
        strict=True,
    )
    for j, target, range_m, range_rate_mps, ttc_s in figures:
        row = rows[j]
        columns.target_id[row] = vehicle_ids[target]
        columns.range_m[row], columns.range_rate_mps[row] = range_m, range_rate_mps
        columns.ttc_s[row] = ttc_s if math.isfinite(ttc_s) else None


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
