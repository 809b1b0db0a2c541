"""The SUMO side of the co-simulation: start, step, read every vehicle at once, command speeds.

libsumo runs SUMO inside this process (one simulation per process, the fast default);
TraCI runs it as a separate program (``sumo``, or ``sumo-gui`` to watch). Both offer the
same API; what is read each step is the same, the way it is read is each one's cheapest:

* libsumo: one getter call per vehicle and variable (lane, lane position, speed,
  position, route id; the odometer only for the driver-response model). Subscriptions
  cost more here: SUMO then builds every vehicle's result at every step, which made its
  own step 40 % slower (1,000 vehicles, 0.1 s steps: 4.4 against 3.1 ms) for a read that
  the getters do in about the same time (0.6 ms for three variables);
* TraCI: each vehicle is subscribed once, when it departs, and one call a step returns
  all of them; a getter call there is a round trip to another process.

A route's edges are fetched once per route id (a rerouted vehicle gets a new route id),
a type's category once per type. A scheduled run (:mod:`csws.cosim.schedule`) reads only the
vehicles that are due: getters then cost less still, subscriptions (every vehicle's result
built at every step) no less. Only a vehicle SUMO may reroute (a rerouter on the network, or the
vehicle's rerouting device) has its route id read while it sleeps, every step: a new route wakes it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Container, Sequence
from dataclasses import dataclass
from operator import itemgetter
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from csws.errors import CswsError
from csws.standard import Category
from csws.sumo.binaries import QUIET_OPTIONS, sumo_binary, sumo_home

from .categories import CATEGORY_PARAMETER, category_of
from .schedule import speed_bound_mps

__all__ = ["SumoStopped", "FleetState", "Simulation", "sumo_arguments"]

_VAR_LANE_ID = 0x51
_VAR_LANEPOSITION = 0x56
_VAR_SPEED = 0x40
_VAR_POSITION = 0x42
_VAR_ANGLE = 0x43
_VAR_ROUTE_ID = 0x53
_VAR_DISTANCE = 0x84
#: The parameter that says whether a vehicle has SUMO's rerouting device ("true" or "false").
_REROUTING = "has.rerouting.device"
#: What a call to the SUMO API returns.
T = TypeVar("T")
#: What is read of each vehicle every step; its type (and so its category) is read once, when it departs.
_SUBSCRIBED = (_VAR_LANE_ID, _VAR_LANEPOSITION, _VAR_SPEED, _VAR_POSITION, _VAR_ROUTE_ID, _VAR_DISTANCE)
#: One vehicle's subscription result as a tuple in the order of ``_SUBSCRIBED``.
_subscribed_values = itemgetter(*_SUBSCRIBED)
#: With headings (the FCD export) the angle is read too, after the rest.
_SUBSCRIBED_WITH_ANGLE = (*_SUBSCRIBED, _VAR_ANGLE)
_subscribed_values_with_angle = itemgetter(*_SUBSCRIBED_WITH_ANGLE)


class SumoStopped(RuntimeError, CswsError):
    """SUMO ended before the co-simulation did (it was killed, crashed or closed)."""


@dataclass(frozen=True)
class FleetState:
    """Every evaluated vehicle at one step, as parallel sequences.

    Attributes
    ----------
    time_s
        Simulation time, s.
    vehicle_id, category, lane_id, route_edges
        Per vehicle.
    lane_pos_m, speed_mps, x_m, y_m, odometer_m
        Per vehicle, arrays.
    departed, arrived
        Vehicles that entered and left the simulation in this step.
    skipped
        Departed vehicles of classes outside the standard (not evaluated).
    type_id, angle_deg
        Per vehicle, its vType and heading (degrees, 0 north, clockwise), on a step read with
        positions by a simulation that reads headings; None otherwise.
    """

    time_s: float
    vehicle_id: list[str]
    category: list[str]
    lane_id: list[str]
    route_edges: list[tuple[str, ...]]
    lane_pos_m: np.ndarray
    speed_mps: np.ndarray
    x_m: np.ndarray
    y_m: np.ndarray
    odometer_m: np.ndarray
    departed: tuple[str, ...]
    arrived: tuple[str, ...]
    skipped: tuple[str, ...]
    type_id: list[str] | None = None
    angle_deg: np.ndarray | None = None


class Simulation:
    """A running SUMO simulation.

    Parameters
    ----------
    sumo_args
        SUMO's arguments without the program (``-c cfg`` or ``-n net -r routes`` and options).
    interface
        ``"libsumo"``, ``"traci"`` or ``"gui"`` (TraCI with sumo-gui).
    odometer
        Whether to read each vehicle's odometer (otherwise it reads as 0).
    headings
        Whether a step read with positions also gives each vehicle's type and angle (the FCD export).
    speed_bounds
        Whether each departing vehicle's speed bound is read (:attr:`departed_speed_bounds`) for
        the schedule of evaluations (:mod:`csws.cosim.schedule`).
    """

    def __init__(
        self,
        sumo_args: Sequence[str],
        interface: str = "libsumo",
        odometer: bool = True,
        headings: bool = False,
        speed_bounds: bool = False,
    ) -> None:
        import os

        os.environ.setdefault("SUMO_HOME", str(sumo_home()))
        if interface == "libsumo":
            import libsumo as api
        elif interface in ("traci", "gui"):
            import traci as api
        else:
            raise ValueError(f"unknown SUMO interface {interface!r}; expected libsumo, traci or gui")
        self.api = api
        self.interface = interface
        binary = sumo_binary("sumo-gui" if interface == "gui" else "sumo")
        self._errors = self._error_types()
        try:
            api.start([str(binary), *sumo_args])
        except self._errors as exc:
            raise ValueError(f"SUMO could not start: {_one_line(exc)}") from None
        self._routes: dict[str, tuple[str, ...]] = {}
        self._categories: dict[str, Category | None] = {}
        self._skipped: set[str] = set()
        self._evaluated: dict[str, str] = {}
        self._types: dict[str, str] = {}
        self._odometer = odometer
        self._headings = headings
        self._subscribed = interface != "libsumo"
        #: Whether every step reads x and y whatever :meth:`step` is asked (TraCI's subscriptions hold them).
        self.reads_positions = self._subscribed
        self.closed = False
        #: The fastest lane's speed limit, m/s (read once, with ``speed_bounds``; infinite with variable speed signs).
        self._fastest_lane_mps = self._fastest_lane() if speed_bounds else None
        #: The speed bound (:func:`csws.cosim.schedule.speed_bound_mps`, m/s) and maximum acceleration (m/s^2)
        #: of each vehicle evaluated that departed in the last step (with ``speed_bounds``).
        self.departed_speed_bounds: dict[str, tuple[float, float]] = {}
        #: With ``speed_bounds`` (a scheduled run): whether SUMO may reroute every vehicle (a rerouter on the
        #: network), and the route id each vehicle it may reroute was last read on.
        self._rerouters = speed_bounds and bool(self._call(api.rerouter.getIDList))
        self._reroutable: dict[str, str | None] = {}

    def _fastest_lane(self) -> float:
        """The highest speed limit of the network's lanes, m/s; infinite where a variable speed sign or a
        calibrator may raise one during the run (a vehicle's speed is then bounded by its type's maximum speed
        alone)."""
        if self._call(self.api.variablespeedsign.getIDList) or self._call(self.api.calibrator.getIDList):
            return math.inf
        lane = self.api.lane
        return max(map(lane.getMaxSpeed, self._call(lane.getIDList)), default=0.0)

    def _error_types(self) -> tuple[type[BaseException], ...]:
        """The exceptions the interface raises when SUMO fails or goes away."""
        errors: list[type[BaseException]] = [self.api.TraCIException]
        fatal = getattr(self.api, "FatalTraCIError", None) or getattr(
            getattr(self.api, "exceptions", None), "FatalTraCIError", None
        )
        if fatal is not None:
            errors.append(fatal)
        return (*errors, ConnectionError, EOFError)

    @property
    def vehicle_count(self) -> int:
        """How many vehicles of a covered class are in the simulation."""
        return len(self._evaluated)

    @property
    def fastest_lane_mps(self) -> float:
        """The highest speed limit of the network's lanes, m/s (read with ``speed_bounds``, else 0)."""
        return self._fastest_lane_mps or 0.0

    @property
    def step_length_s(self) -> float:
        """SUMO's step length, s."""
        return float(self.api.simulation.getDeltaT())

    def expected_vehicles(self) -> int:
        """Vehicles running or still to depart."""
        return int(self._call(self.api.simulation.getMinExpectedNumber))

    def step(
        self,
        positions: bool = True,
        asleep: Container[str] = (),
        teleporting: Callable[[tuple[str, ...]], None] | None = None,
        appearing: Callable[[tuple[str, ...]], None] | None = None,
    ) -> FleetState:
        """Advance one step and read every evaluated vehicle but those ``asleep``; its x, y only with
        ``positions`` (NaN otherwise: :meth:`position` reads one vehicle's when it is needed). The vehicles
        that start to teleport in the step, and the sleeping ones SUMO rerouted, are given to ``teleporting``
        first (which may wake them), then those that departed or ended a teleport, of any class, to
        ``appearing`` (which may wake others).

        Raises
        ------
        SumoStopped
            When SUMO is gone or fails.
        """
        api = self.api
        self._call(api.simulationStep)
        arrived = tuple(self._call(api.simulation.getArrivedIDList))
        for vehicle_id in arrived:  # gone (arrived or removed): no route of theirs to read
            self._reroutable.pop(vehicle_id, None)
        if teleporting is not None:
            teleporting(tuple(self._call(api.simulation.getStartingTeleportIDList)) + self._rerouted(asleep))
        departed = tuple(self._call(api.simulation.getDepartedIDList))
        skipped = []
        self.departed_speed_bounds = {}
        for vehicle_id in departed:
            type_id = self._call(api.vehicle.getTypeID, vehicle_id)
            category = self._category(type_id)
            if category is None:
                skipped.append(vehicle_id)
                self._skipped.add(vehicle_id)
                continue
            self._evaluated[vehicle_id] = category.value
            self._types[vehicle_id] = type_id
            if self._fastest_lane_mps is not None:
                self.departed_speed_bounds[vehicle_id] = self._speed_bound(vehicle_id)
                if self._rerouters or self._call(api.vehicle.getParameter, vehicle_id, _REROUTING) == "true":
                    self._reroutable[vehicle_id] = None
            if self._subscribed:
                self._call(api.vehicle.subscribe, vehicle_id, self._variables())
        self._skipped.difference_update(arrived)
        for vehicle_id in arrived:
            self._evaluated.pop(vehicle_id, None)
            self._types.pop(vehicle_id, None)
        if appearing is not None:
            appeared = departed + tuple(self._call(api.simulation.getEndingTeleportIDList))
            appearing(tuple(vehicle_id for vehicle_id in appeared if vehicle_id not in arrived))
        ids, (lane_id, lane_pos_m, speed_mps, position, route_id, odometer_m, angle_deg) = (
            self._subscribed_fleet(asleep) if self._subscribed else self._fleet_by_getters(positions, asleep)
        )
        if not position:
            position = [(math.nan, math.nan)] * len(ids)
        if self._reroutable:
            self._note_routes(ids, route_id)
        evaluated, headings = self._evaluated, self._headings and len(angle_deg) == len(ids)
        return FleetState(
            time_s=float(self._call(api.simulation.getTime)),
            vehicle_id=ids,
            category=[evaluated[vehicle_id] for vehicle_id in ids],
            lane_id=list(lane_id),
            route_edges=self._route_edges(ids, route_id),
            lane_pos_m=np.array(lane_pos_m, dtype=float),
            speed_mps=np.array(speed_mps, dtype=float),
            x_m=np.array([xy[0] for xy in position], dtype=float),
            y_m=np.array([xy[1] for xy in position], dtype=float),
            odometer_m=np.array(odometer_m, dtype=float) if self._odometer else np.zeros(len(ids)),
            departed=departed,
            arrived=arrived,
            skipped=tuple(skipped),
            type_id=[self._types[vehicle_id] for vehicle_id in ids] if headings else None,
            angle_deg=np.array(angle_deg, dtype=float) if headings else None,
        )

    def _rerouted(self, asleep: Container[str]) -> tuple[str, ...]:
        """The sleeping vehicles SUMO may reroute whose route id is no longer the one they were last read on."""
        reroutable = self._reroutable
        sleeping = [vehicle_id for vehicle_id in reroutable if vehicle_id in asleep]
        if not sleeping:
            return ()
        route_ids = self._call(lambda: list(map(self.api.vehicle.getRouteID, sleeping)))
        return tuple(v for v, route_id in zip(sleeping, route_ids, strict=True) if route_id != reroutable[v])

    def _note_routes(self, vehicle_ids: Sequence[str], route_ids: Sequence[str]) -> None:
        """Keep the route id each vehicle SUMO may reroute was read on."""
        reroutable = self._reroutable
        for vehicle_id, route_id in zip(vehicle_ids, route_ids, strict=True):
            if vehicle_id in reroutable:
                reroutable[vehicle_id] = route_id

    def _variables(self) -> tuple[int, ...]:
        """The variables a vehicle is subscribed to (TraCI): with headings, its angle too."""
        return _SUBSCRIBED_WITH_ANGLE if self._headings else _SUBSCRIBED

    def _speed_bound(self, vehicle_id: str) -> tuple[float, float]:
        """The fastest a departing vehicle can drive, m/s (:func:`csws.cosim.schedule.speed_bound_mps`), and its
        maximum acceleration, m/s^2."""
        vehicle = self.api.vehicle
        max_speed_mps = float(self._call(vehicle.getMaxSpeed, vehicle_id))
        speed_factor = float(self._call(vehicle.getSpeedFactor, vehicle_id))
        accel_mps2 = float(self._call(vehicle.getAccel, vehicle_id))
        return speed_bound_mps(max_speed_mps, speed_factor, self._fastest_lane_mps or 0.0), accel_mps2

    def _fleet_by_getters(self, positions: bool, asleep: Container[str]) -> tuple[list[str], tuple[Sequence, ...]]:
        """The evaluated vehicles not ``asleep`` and their values, read by one getter call per vehicle and
        variable (libsumo); x, y (and with headings the angle) only with ``positions`` (empty otherwise)."""
        vehicle = self.api.vehicle
        evaluated = self._evaluated
        ids = [v for v in self._call(vehicle.getIDList) if v in evaluated and v not in asleep]
        getters = [
            vehicle.getLaneID,
            vehicle.getLanePosition,
            vehicle.getSpeed,
            vehicle.getPosition if positions else None,
            vehicle.getRouteID,
            vehicle.getDistance if self._odometer else None,
            vehicle.getAngle if positions and self._headings else None,
        ]
        return ids, tuple(
            self._call(lambda getter=getter: list(map(getter, ids))) if getter else () for getter in getters
        )

    def position(self, vehicle_id: str) -> tuple[float, float]:
        """One vehicle's x, y, m (for a step read without positions)."""
        return tuple(self._call(self.api.vehicle.getPosition, vehicle_id))

    def _subscribed_fleet(self, asleep: Container[str]) -> tuple[list[str], tuple[Sequence, ...]]:
        """The evaluated vehicles not ``asleep`` and their values, from one call for every subscription (TraCI)."""
        results = self._call(self.api.vehicle.getAllSubscriptionResults)
        if asleep:
            results = {vehicle_id: values for vehicle_id, values in results.items() if vehicle_id not in asleep}
        ids = list(results)
        if not ids:
            return ids, ((),) * (len(_SUBSCRIBED) + 1)
        values = _subscribed_values_with_angle if self._headings else _subscribed_values
        columns = tuple(zip(*map(values, results.values()), strict=False))
        return ids, columns if self._headings else (*columns, ())

    def set_speed(self, vehicle_id: str, speed_mps: float) -> None:
        """Command a vehicle's speed (m/s); a negative speed hands it back to SUMO's driver."""
        self._call(self.api.vehicle.setSpeed, vehicle_id, speed_mps)

    def close(self) -> None:
        """End the simulation (quietly if SUMO is already gone)."""
        if self.closed:
            return
        self.closed = True
        gone: tuple[type[BaseException], ...] = (*self._errors, OSError)
        try:
            self.api.close()
        except gone:
            pass

    def _category(self, type_id: str) -> Category | None:
        """The category of a vType, read once per type."""
        if type_id not in self._categories:
            vclass = self._call(self.api.vehicletype.getVehicleClass, type_id)
            declared = self._call(self.api.vehicletype.getParameter, type_id, CATEGORY_PARAMETER)
            try:
                self._categories[type_id] = category_of(vclass, declared)
            except ValueError as exc:
                raise ValueError(f"vType {type_id!r}: {exc}") from None
        return self._categories[type_id]

    def _route_edges(self, vehicle_ids: Sequence[str], route_ids: Sequence[str]) -> list[tuple[str, ...]]:
        """Each vehicle's route edges; a route's edges are fetched once per route id."""
        routes = self._routes
        for vehicle_id, route_id in zip(vehicle_ids, route_ids, strict=False):
            if route_id not in routes:
                routes[route_id] = tuple(self._call(self.api.vehicle.getRoute, vehicle_id))
        return [routes[route_id] for route_id in route_ids]

    def _call(self, function: Callable[..., T], *args: Any) -> T:
        """Call the SUMO API; its failures become :class:`SumoStopped`."""
        try:
            return function(*args)
        except self._errors as exc:
            raise SumoStopped(_one_line(exc)) from None
        except OSError as exc:
            raise SumoStopped(_one_line(exc)) from None


def _one_line(exc: BaseException) -> str:
    """An exception's message on one line."""
    text = " ".join(str(exc).split())
    return text or type(exc).__name__


def sumo_arguments(
    config: Path | None, net: Path | None, routes: Sequence[Path], step_length_s: float, seed: int, end_s: float | None
) -> list[str]:
    """SUMO's arguments for a configuration or a network with route files."""
    arguments = ["-c", str(config)] if config is not None else ["-n", str(net)]
    if routes:
        arguments += ["-r", ",".join(str(r) for r in routes)]
    arguments += [
        "--step-length",
        f"{step_length_s:g}",
        "--seed",
        str(seed),
        *QUIET_OPTIONS,
    ]
    if end_s is not None and math.isfinite(end_s):
        arguments += ["--end", f"{end_s:g}"]
    return arguments
