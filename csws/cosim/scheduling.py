"""The schedules of one scheduled run together: a vehicle is read while the curve warning or the FCW wants it.

The curve warning's schedule (:mod:`csws.cosim.schedule`) and the FCW's (:mod:`csws.cosim.fcw_schedule`)
each keep their own sleeping vehicles; SUMO reads a vehicle unless it sleeps in both. A vehicle read
for one of them is evaluated by both, which each allows at any step: the curve warning's memory of it is
caught up (:func:`csws.cosim.schedule.caught_up`), and the FCW's state was kept up to date while it slept
(no object can be in its range then, so nothing else of its FCW has changed).
"""

from __future__ import annotations

from collections.abc import Container, Sequence

import numpy as np

from csws.engine import Engine, VehicleMemory

from .driver import DriverResponse
from .evaluators import FleetWarnings, LibraryEvaluator
from .fcw import FcwColumns, FleetFcw
from .fcw_schedule import FcwSchedule
from .schedule import WakeSchedule, caught_up
from .sumo import FleetState

__all__ = ["AsleepInAll", "RunSchedule", "asleep_in_all"]


class AsleepInAll:
    """The vehicles asleep in both of two schedules (a live view of their sleeping vehicles).

    SUMO's read asks it once per vehicle and step, so it tests the two directly (a run with one schedule
    passes that schedule's sleeping vehicles instead, :func:`asleep_in_all`).
    """

    def __init__(self, first: Container[str], second: Container[str]) -> None:
        self.first, self.second = first, second

    def __contains__(self, vehicle_id: object) -> bool:
        return vehicle_id in self.first and vehicle_id in self.second

    def __bool__(self) -> bool:
        return bool(self.first) and bool(self.second)


def asleep_in_all(sleeping: Sequence[dict[str, int]]) -> Container[str]:
    """The vehicles asleep in every one of some schedules, by their sleeping vehicles (live): the one
    schedule's own mapping when there is one (the cheapest test of all), else :class:`AsleepInAll`."""
    if len(sleeping) == 1:
        return sleeping[0]
    if len(sleeping) == 2:
        return AsleepInAll(*sleeping)
    return ()


class RunSchedule:
    """Which vehicles a scheduled run reads and evaluates at each step, for the curve warning, the FCW or both.

    Parameters
    ----------
    curve
        The curve warning's schedule with the library's evaluator it schedules, or None without the curve warning.
    fcw
        The FCW's schedule with the FCW it schedules and the network's fastest lane speed (m/s), or None.
    """

    def __init__(
        self,
        curve: tuple[WakeSchedule, LibraryEvaluator] | None,
        fcw: tuple[FcwSchedule, FleetFcw, float] | None,
    ) -> None:
        self.curve = curve
        self.fcw = fcw
        sleeping = [
            schedule.wake_step for schedule in (curve[0] if curve else None, fcw[0] if fcw else None) if schedule
        ]
        #: The vehicles SUMO does not read this step.
        self.asleep = asleep_in_all(sleeping)
        #: The step each vehicle the curve warning woke this step was last evaluated at.
        self.woken: dict[str, int] = {}
        self.step = 0
        #: Vehicle-steps evaluated and vehicle-steps there were.
        self.evaluated = 0
        self.present = 0

    def wake_due(self, step: int, everyone: bool) -> None:
        """Wake the vehicles due at ``step`` (every one with ``everyone``: a step the time series keeps)."""
        self.step = step
        self.woken = self.curve[0].wake_due(step, everyone) if self.curve else {}
        if self.fcw:
            self.fcw[0].wake_due(step, everyone)

    def teleporting(self, vehicle_ids: tuple[str, ...]) -> None:
        """Wake the vehicles SUMO starts to teleport (they may reappear anywhere ahead) or rerouted while they slept
        (their road ahead is not the one their sleep was worked out on)."""
        if self.curve:
            self.woken.update(self.curve[0].wake(vehicle_ids))
        if self.fcw:
            self.fcw[0].wake(vehicle_ids)

    def appearing(self, vehicle_ids: tuple[str, ...]) -> None:
        """Note the vehicles that departed or ended a teleport: the FCW wakes the sleeping ones they could come near."""
        if self.fcw:
            schedule, forward, fastest_lane_mps = self.fcw
            forward.appeared(self.step, vehicle_ids, fastest_lane_mps, schedule)

    def read(self, fleet: FleetState, bounds: dict[str, tuple[float, float]], vehicle_count: int) -> None:
        """After SUMO's read: wake in each schedule the vehicles read for the other, note the departed vehicles'
        speed bounds, and catch up the curve warning's memory of the vehicles it woke."""
        if self.fcw and self.curve:  # with one schedule, no vehicle read sleeps in it
            fcw_sleeping, curve_sleeping = self.fcw[0].wake_step, self.curve[0].wake_step
            self.fcw[0].wake(list(filter(fcw_sleeping.__contains__, fleet.vehicle_id)))
            self.woken.update(self.curve[0].wake(list(filter(curve_sleeping.__contains__, fleet.vehicle_id))))
        if self.curve:
            schedule, library = self.curve
            _catch_up(schedule, library.engine, self.step, fleet, self.woken, bounds)
        self.evaluated += len(fleet.vehicle_id)
        self.present += vehicle_count

    def sleep(
        self, fleet: FleetState, warnings: FleetWarnings, fcw: FcwColumns | None, driver: DriverResponse | None
    ) -> None:
        """Put to sleep the vehicles evaluated this step that no warning, hold or driver keeps awake, and bring
        the FCW state of the sleeping vehicles due a speed read up to date."""
        fcw_sleeping: dict[str, int] | None = None
        if self.fcw and fcw is not None:
            schedule, forward, _ = self.fcw
            forward.check_states(self.step, schedule)
            driven = set(driver.drivers) | set(driver.fcw_drivers) if driver is not None else set()
            forward.sleep(self.step, schedule, fcw.level, driven)
            forward.keep_headings(schedule)
            fcw_sleeping = schedule.wake_step
        if self.curve:
            # A vehicle its FCW keeps awake is read at the next step anyway: the curve warning keeps it too.
            kept = _kept_awake(fleet.vehicle_id, driver.drivers if driver is not None else {}, fcw_sleeping)
            _sleep_curve(*self.curve, self.step, fleet, warnings, kept)

    def forget(self, vehicle_ids: Sequence[str]) -> None:
        """Drop vehicles that left."""
        if self.fcw:
            self.fcw[0].forget(vehicle_ids)

    def evaluated_share(self) -> float | None:
        """The share of vehicle-steps evaluated, None before any."""
        return None if not self.present else self.evaluated / self.present


def _catch_up(
    schedule: WakeSchedule,
    engine: Engine,
    step: int,
    fleet: FleetState,
    woken: dict[str, int],
    bounds: dict[str, tuple[float, float]],
) -> None:
    """Note the step, the departed vehicles' speed bounds, and bring the engine's memory of each vehicle
    woken this step up to the steps it slept through (:func:`csws.cosim.schedule.caught_up`).

    A catch-up is a function of the memory and the step the vehicle fell asleep at alone, so each distinct
    pair is worked out once: vehicles of a fleet on one clock that slept through the same steps share it.
    """
    schedule.stepped(step, fleet.time_s)
    schedule.forget(fleet.arrived)
    for vehicle_id, (bound_mps, accel_mps2) in bounds.items():
        schedule.add(vehicle_id, bound_mps, accel_mps2)
    arrived = set(fleet.arrived)
    caught: dict[tuple[VehicleMemory, int], VehicleMemory] = {}
    for vehicle_id, slept_at in woken.items():
        if vehicle_id not in arrived:
            memory = engine.memory(vehicle_id)
            key = (memory, slept_at)
            after = caught.get(key)
            if after is None:
                after = caught[key] = caught_up(memory, schedule.skipped_times_s(slept_at))
            engine.restore(vehicle_id, after)


def _kept_awake(
    vehicle_ids: Sequence[str], driven: Container[str], fcw_sleeping: Container[str] | None
) -> np.ndarray | None:
    """Per vehicle read, whether the curve warning keeps it awake for another reason than its own warning: a driver
    answers it, or (``fcw_sleeping`` given) its FCW keeps it awake; None where nothing does."""
    count = len(vehicle_ids)
    kept = np.fromiter(map(driven.__contains__, vehicle_ids), bool, count) if driven else None
    if fcw_sleeping is not None:
        fcw_awake = ~np.fromiter(map(fcw_sleeping.__contains__, vehicle_ids), bool, count)
        kept = fcw_awake if kept is None else kept | fcw_awake
    return kept


def _sleep_curve(
    schedule: WakeSchedule,
    library: LibraryEvaluator,
    step: int,
    fleet: FleetState,
    warnings: FleetWarnings,
    kept: np.ndarray | None,
) -> None:
    """Put to sleep the vehicles evaluated this step that no curve warning, release hold, driver or FCW (``kept``,
    per vehicle read) keeps awake.

    Most of the vehicles evaluated are near a curve, where a warning can arise at the next step: one array
    test (:meth:`WakeSchedule.awake_next_step`) keeps those awake, and only the others are scheduled, together.
    """
    engine = library.engine
    ahead, held, vehicle_ids = library.ahead, engine.held, fleet.vehicle_id
    if ahead is None or not vehicle_ids:  # no vehicle was evaluated: the evaluator holds an older step's
        return
    active = np.asarray(library.active, dtype=np.intp)
    awake_now = np.asarray(warnings.level) != 0
    if held:
        awake_now |= np.fromiter(map(held.__contains__, vehicle_ids), bool, len(vehicle_ids))
    if kept is not None:
        awake_now |= kept
    quiet = np.flatnonzero(~awake_now[active])  # positions in the active vehicles (and their roads ahead)
    if not quiet.size:
        return
    rows = active[quiet]
    horizons = [ahead.horizons[k] for k in quiet.tolist()]
    distances_m, factors = schedule.parts.distances_m(horizons, ahead.vehicle_s[quiet])
    speeds_mps = fleet.speed_mps[rows]
    due = np.flatnonzero(~schedule.awake_next_step(speeds_mps, distances_m, factors))
    if due.size:
        ids = [vehicle_ids[row] for row in rows[due].tolist()]
        periods_s = np.array([engine.update_period_s(vehicle_id) for vehicle_id in ids], dtype=float)
        schedule.sleep(step, ids, speeds_mps[due], distances_m[due], factors[due], periods_s)
