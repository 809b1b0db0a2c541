"""The forward collision warning in SUMO: each equipped vehicle's sensor view of the vehicles around it.

Each step :class:`FleetFcw` reads every SUMO vehicle once (:func:`read_vehicles`: the front's
position, the angle, speed, acceleration, road and lane, signals), turns the vehicles around each
equipped vehicle into that vehicle's object list (:func:`sensor_view`, in the frame of
:mod:`csws.fcw.objects`: x ahead from the front bumper to the object's rear, y left to the
object's centre, the longitudinal relative speed, the object's own acceleration, its width, and
the lane SUMO assigns where both drive on the same road), and calls the object FCW's fleet form
(:func:`csws.fcw.fleet.update_fleet`) once per category (4.3.3: V_max by category,
:meth:`csws.fcw.physics.FcwSettings.for_category`). The pairs within the sensor's range are found
on a grid of cells a range wide, sorted once per step: each equipped vehicle looks only at the
3 x 3 cells around it, not at every vehicle.

The subject's yaw rate is its angle's change over the step (SUMO's angle is its body's heading,
clockwise from north); the brake light is the driver braking (4.5.4), the blinkers the turn signal.
Where a vehicle is map-matched, its path ahead (the curve warning's horizon, :mod:`csws.ahead`)
assigns the objects' lanes (4.3.2 d: :func:`map_lanes`): a vehicle on a road the path does not take
is not in the path; one on a road it takes is measured along the path, its distance the road's and its
range rate the speeds' difference (round a hairpin the line of sight is far shorter than the road, and a
leader turning on the path moves away from the line of sight to it).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from csws.fcw.fleet import UNKNOWN_LANE, FleetEgo, FleetFrame, FleetMemory, FleetObjects, update_fleet
from csws.fcw.path import yaw_path_curvature_1pm
from csws.fcw.physics import FCW_STATES, STANDBY, FcwSettings

from .driver import DriverResponse
from .records import StepValues, Summary
from .sumo import FleetState

__all__ = [
    "BRAKE_LIGHT",
    "SumoVehicles",
    "read_vehicles",
    "OFF_PATH_LANE",
    "MapLanes",
    "map_lanes",
    "SensorPairs",
    "sensor_view",
    "Measure",
    "FcwColumns",
    "FleetFcw",
    "FCW_TIMESERIES_FIELDS",
    "FCW_EVENT_COLUMNS",
    "fcw_events",
]

#: SUMO's signal bits of ``vehicle.getSignals``: right and left blinker, brake light (the driver brakes, 4.5.4).
BLINKER_RIGHT, BLINKER_LEFT, BRAKE_LIGHT = 1, 2, 8
#: Beyond the range the sensor reaches to an object's rear, its front may be this much farther, m (the grid's margin).
LONGEST_VEHICLE_M = 30.0
#: An object whose own speed along the line of sight is below minus this comes toward the subject (3.7: no target), m/s.
ONCOMING_MPS = 1.0
#: The lane column's value of an object on a road the subject's map path does not take (never in the path).
OFF_PATH_LANE = 127
#: A key's lower 32 bits hold the object id (:func:`csws.fcw.fleet.update_fleet` keys objects by vehicle and id).
_ID_BITS = 32
MAX_ID_MASK = (1 << _ID_BITS) - 1


@dataclass(frozen=True)
class SumoVehicles:
    """Every SUMO vehicle of one step, read once, as parallel columns.

    Attributes
    ----------
    vehicle_id
        SUMO's ids.
    number
        Each vehicle's number, kept while it drives (its object id in every sensor's list).
    front_x_m, front_y_m
        The front bumper's centre, m (SUMO's position).
    heading_rad
        SUMO's angle in radians: the body's heading, clockwise from north (+y).
    speed_mps, accel_mps2
        Speed and longitudinal acceleration.
    length_m, width_m
        Size.
    road, lane_index
        The road's code (equal codes: the same SUMO edge) and the lane's index on it (0 rightmost).
    signals
        SUMO's signal bits.
    lane_position_m
        The front's position along its lane, m (SUMO's lane position).
    """

    vehicle_id: list[str]
    number: np.ndarray
    front_x_m: np.ndarray
    front_y_m: np.ndarray
    heading_rad: np.ndarray
    speed_mps: np.ndarray
    accel_mps2: np.ndarray
    length_m: np.ndarray
    width_m: np.ndarray
    road: np.ndarray
    lane_index: np.ndarray
    signals: np.ndarray
    lane_position_m: np.ndarray


class _Numbers(dict[str, int]):
    """A number per SUMO vehicle id, given in order of first sight and never reused."""

    def __missing__(self, vehicle_id: str) -> int:
        number = self[vehicle_id] = self.issued = getattr(self, "issued", -1) + 1
        return number


def read_vehicles(
    sumo: Any, numbers: dict[str, int], sizes: dict[str, tuple[float, float]], roads: dict[str, int] | None = None
) -> SumoVehicles:
    """Every SUMO vehicle's values of this step, one getter call per vehicle and value (lengths and
    widths read once per vehicle into ``sizes``; ``numbers`` gives each id its number, ``roads`` each
    road id its code, kept from step to step where given)."""
    vehicle = sumo.vehicle
    ids = list(vehicle.getIDList())
    for vehicle_id in ids:
        if vehicle_id not in sizes:
            sizes[vehicle_id] = (vehicle.getLength(vehicle_id), vehicle.getWidth(vehicle_id))
    position = np.array([vehicle.getPosition(v) for v in ids], dtype=float).reshape(len(ids), 2)
    roads = {} if roads is None else roads
    size = np.array([sizes[v] for v in ids], dtype=float).reshape(len(ids), 2)
    return SumoVehicles(
        ids,
        np.array([numbers[v] for v in ids], dtype=np.int64),
        position[:, 0],
        position[:, 1],
        np.radians(np.array([vehicle.getAngle(v) for v in ids], dtype=float)),
        np.array([vehicle.getSpeed(v) for v in ids], dtype=float),
        np.array([vehicle.getAcceleration(v) for v in ids], dtype=float),
        size[:, 0],
        size[:, 1],
        np.array([roads.setdefault(vehicle.getRoadID(v), len(roads)) for v in ids], dtype=np.int64),
        np.array([vehicle.getLaneIndex(v) for v in ids], dtype=np.int64),
        np.array([vehicle.getSignals(v) for v in ids], dtype=np.int64),
        np.array([vehicle.getLanePosition(v) for v in ids], dtype=float),
    )


@dataclass(frozen=True)
class MapLanes:
    """The lanes of the subjects' map paths ahead (the curve warning's horizon, :mod:`csws.ahead`), flat.

    Attributes
    ----------
    subject
        The subject of each lane (an index into the subjects given to :func:`sensor_view`), in path order.
    road, lane_index
        The lane's road code (as :func:`read_vehicles` codes roads) and its index on that road.
    reach_m
        ``(subjects,)`` how far ahead of each subject's front its path is known, m (0: no path, not map-matched).
    start_m, end_m
        Where the lane starts and ends along the path, from the subject's front, m (the subject's own lane
        starts behind it, at or below 0).
    position_factor
        The lane's SUMO length over its shape's length (a lane position over it is the arc length along it).
    """

    subject: np.ndarray
    road: np.ndarray
    lane_index: np.ndarray
    reach_m: np.ndarray
    start_m: np.ndarray
    end_m: np.ndarray
    position_factor: np.ndarray


@dataclass(frozen=True)
class _HorizonLanes:
    """One horizon's lanes as codes with the stretch of the path each covers (kept while the horizon is)."""

    horizon: Any
    road: np.ndarray
    lane_index: np.ndarray
    start_s: np.ndarray
    end_s: np.ndarray
    position_factor: np.ndarray


def _horizon_lanes(horizon: Any, roads: dict[str, int]) -> _HorizonLanes:
    """A horizon's lanes (``edge_index``, internal via lanes ``:junction_k_index`` too) as road codes and indices."""
    path = horizon.path
    edges, indices = zip(*(lane_id.rsplit("_", 1) for lane_id in path.lane_ids), strict=True)
    start = np.asarray(path.lane_start_s, dtype=float)
    return _HorizonLanes(
        horizon,
        np.array([roads.setdefault(edge, len(roads)) for edge in edges], dtype=np.int64),
        np.array([int(index) for index in indices], dtype=np.int64),
        start,
        start + np.asarray(path.lane_shape_length_m, dtype=float),
        np.asarray(path.lane_position_factor, dtype=float),
    )


def map_lanes(paths: Sequence[Any | None], roads: dict[str, int], range_m: float, cache: dict[int, Any]) -> MapLanes:
    """The lanes each subject's path ahead (a :class:`csws.ahead.horizon.PathAhead`, or None where the
    vehicle is not map-matched) takes within ``range_m`` of its front, as :class:`MapLanes`.

    ``cache`` keeps each horizon's lanes by the horizon (horizons are shared and kept by the look-ahead);
    the step's horizons are joined once and each subject's lanes cut from them in numpy.
    """
    if len(cache) > 4096:
        cache.clear()
    slot_of: dict[int, int] = {}
    pieces: list[_HorizonLanes] = []
    slots = np.full(len(paths), -1, dtype=np.int64)
    vehicle_s = np.zeros(len(paths))
    for k, path in enumerate(paths):
        if path is None:
            continue
        key = id(path.horizon)
        slot = slot_of.get(key)
        if slot is None:
            lanes = cache.get(key)
            if lanes is None or lanes.horizon is not path.horizon:
                lanes = cache[key] = _horizon_lanes(path.horizon, roads)
            slot = slot_of[key] = len(pieces)
            pieces.append(lanes)
        slots[k], vehicle_s[k] = slot, path.vehicle_s
    reach = np.zeros(len(paths))
    mapped = np.flatnonzero(slots >= 0)
    if not mapped.size:
        empty, none = np.zeros(0, dtype=np.int64), np.zeros(0)
        return MapLanes(empty, empty, empty, reach, none, none, none)
    road, index, start_s, end_s, factor = (
        np.concatenate([getattr(piece, name) for piece in pieces])
        for name in ("road", "lane_index", "start_s", "end_s", "position_factor")
    )
    counts = np.array([piece.road.size for piece in pieces], dtype=np.int64)
    first = np.cumsum(counts) - counts
    per = counts[slots[mapped]]
    owner = np.repeat(mapped, per)
    row = np.repeat(first[slots[mapped]], per) + np.arange(per.sum()) - np.repeat(np.cumsum(per) - per, per)
    ahead = (end_s[row] > vehicle_s[owner]) & (start_s[row] < vehicle_s[owner] + range_m)
    reach[mapped] = end_s[first[slots[mapped]] + per - 1] - vehicle_s[mapped]
    owner, row = owner[ahead], row[ahead]
    from_front = vehicle_s[owner]
    return MapLanes(
        owner, road[row], index[row], reach, start_s[row] - from_front, end_s[row] - from_front, factor[row]
    )


def _lane_on_map(
    vehicles: SumoVehicles, owner: np.ndarray, seen: np.ndarray, x_m: np.ndarray, lanes: MapLanes, fallback: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """4.3.2 d, 4.5.5 b, 3.7: each object's lane from the subject's map path, and its rear's distance along it.

    The lane: on a road the path takes, its lane index less the path's there (0: on the path's lane); on
    another road within the path's known reach, :data:`OFF_PATH_LANE` (a vehicle turning off across a
    junction, or on a crossing, diverging or parallel road, is not on the subject's path); beyond it, or for
    a subject without a path, ``fallback``. The distance (NaN off the path's roads): the path's arc length
    from the subject's front to the object's front (its lane position on the path's lane of its road) less
    its length, the clearance along the road the two vehicles close (3.10).
    """
    path_keys = (lanes.subject << _ID_BITS) | lanes.road
    order = np.argsort(path_keys, kind="stable")
    ordered = path_keys[order]
    keys = (owner << _ID_BITS) | vehicles.road[seen]
    reach_m = lanes.reach_m[owner]
    lane = np.where(x_m <= reach_m, OFF_PATH_LANE, UNKNOWN_LANE)
    along_m = np.full(keys.size, np.nan)
    if ordered.size:
        at = np.minimum(np.searchsorted(ordered, keys), ordered.size - 1)
        found, row = ordered[at] == keys, order[at]
        lane = np.where(found, vehicles.lane_index[seen] - lanes.lane_index[row], lane)
        front_m = np.clip(
            vehicles.lane_position_m[seen] / lanes.position_factor[row], 0.0, lanes.end_m[row] - lanes.start_m[row]
        )
        along_m = np.where(found, lanes.start_m[row] + front_m - vehicles.length_m[seen], np.nan)
    mapped = reach_m > 0.0
    return np.where(mapped, lane, fallback), np.where(mapped, along_m, np.nan)


@dataclass(frozen=True)
class SensorPairs:
    """Which vehicle sees which, with the object's columns in the seeing vehicle's frame (:mod:`csws.fcw.objects`).

    ``subject`` indexes the subjects given to :func:`sensor_view`, ``seen`` the vehicles of :class:`SumoVehicles`.
    """

    subject: np.ndarray
    seen: np.ndarray
    x_m: np.ndarray
    y_m: np.ndarray
    relative_speed_mps: np.ndarray
    accel_mps2: np.ndarray
    lane: np.ndarray


def _nearby(cell_x: np.ndarray, cell_y: np.ndarray, subjects: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(subject, vehicle) index pairs of every vehicle in the 3 x 3 cells around each subject's cell.

    The vehicles are sorted by the key cell_x * rows + cell_y, so that one column's three cells
    around a subject are one run of the sorted keys: three binary searches per subject.
    """
    rows = int(cell_y.max()) + 3 if cell_y.size else 1
    keys = cell_x * rows + cell_y
    order = np.argsort(keys, kind="stable")
    ordered = keys[order]
    pairs_subject, pairs_seen = [], []
    for column in (-1, 0, 1):
        centre = (cell_x[subjects] + column) * rows + cell_y[subjects]
        low, high = np.searchsorted(ordered, centre - 1, "left"), np.searchsorted(ordered, centre + 1, "right")
        counts = high - low
        owner = np.repeat(np.arange(subjects.size), counts)
        step = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
        pairs_subject.append(owner)
        pairs_seen.append(order[np.repeat(low, counts) + step])
    return np.concatenate(pairs_subject), np.concatenate(pairs_seen)


def _pairs_within(vehicles: SumoVehicles, subjects: np.ndarray, range_m: float) -> tuple[np.ndarray, np.ndarray]:
    """(subject, vehicle) pairs of the vehicles in the grid cells around each subject, itself left out."""
    cell_m = range_m + LONGEST_VEHICLE_M
    x0 = vehicles.front_x_m.min() if subjects.size else 0.0
    y0 = vehicles.front_y_m.min() if subjects.size else 0.0
    cell_x = ((vehicles.front_x_m - x0) // cell_m).astype(np.int64) + 1
    cell_y = ((vehicles.front_y_m - y0) // cell_m).astype(np.int64) + 1
    owner, seen = _nearby(cell_x, cell_y, subjects)
    other = seen != subjects[owner]
    return owner[other], seen[other]


def sensor_view(
    vehicles: SumoVehicles,
    subjects: np.ndarray,
    range_m: float,
    path_turn_rad: np.ndarray | None = None,
    lanes: MapLanes | None = None,
) -> SensorPairs:
    """The objects each subject (indices into ``vehicles``) sees ahead within ``range_m``, in its frame.

    The frame's x axis is the subject's heading turned left by ``path_turn_rad`` (per subject; none:
    the body's heading), x the distance ahead from its front to the object's rear (the object's front
    less its length along its own heading), y the object's centre to the left; the relative speed is
    the range rate, the two velocities' difference along the line of sight to the object's rear (on
    a straight the object's speed less the subject's; about 0 between two vehicles at one speed on
    one circle), the acceleration the object's own along that line. An object is seen while its rear
    is ahead of the front (x >= 0) and at most ``range_m`` from it, and not while it comes toward the
    subject, its own speed along the line of sight below -:data:`ONCOMING_MPS` (3.7: the target is a
    vehicle ahead, 前车; a lead on a curve, however far round, moves away along that line). The lane is the
    difference of the lane indices (+1 left) where both are on the same road, else unknown (the
    predicted path decides); with the subjects' map paths (``lanes``), the lane on the map path
    (:func:`_lane_on_map`), and for an object on a road the path takes, the road's measures instead of
    the line of sight's: x the distance along the path (a leader round a hairpin, near in the line of
    sight, is as far as the road between them), the relative speed the two speeds' difference and the
    acceleration the object's own (both drive along the path: a leader turning on it closes at the
    speeds' difference, not at its velocity's change of direction along the line of sight), seen while
    that x is within [0, ``range_m``]. Pairs come from a grid of cells ``range_m`` plus
    :data:`LONGEST_VEHICLE_M` wide, so each subject looks at its 3 x 3 cells only.
    """
    owner, seen = _pairs_within(vehicles, subjects, range_m)
    me = subjects[owner]
    heading = vehicles.heading_rad[subjects] - (0.0 if path_turn_rad is None else path_turn_rad)
    ahead_x, ahead_y = np.sin(heading)[owner], np.cos(heading)[owner]
    # The fronts first: a rear ahead (x >= 0) within the range has its front at most a vehicle's length
    # farther and at most a length behind the subject's front, so the rest is computed for those only.
    front_x = vehicles.front_x_m[seen] - vehicles.front_x_m[me]
    front_y = vehicles.front_y_m[seen] - vehicles.front_y_m[me]
    near = np.flatnonzero(
        (front_x * front_x + front_y * front_y <= (range_m + LONGEST_VEHICLE_M) ** 2)
        & (front_x * ahead_x + front_y * ahead_y >= -LONGEST_VEHICLE_M)
    )
    owner, me, seen, ahead_x, ahead_y = owner[near], me[near], seen[near], ahead_x[near], ahead_y[near]
    own_x, own_y = np.sin(vehicles.heading_rad)[seen], np.cos(vehicles.heading_rad)[seen]
    back = vehicles.length_m[seen]
    sight_x = vehicles.front_x_m[seen] - back * own_x - vehicles.front_x_m[me]
    sight_y = vehicles.front_y_m[seen] - back * own_y - vehicles.front_y_m[me]
    sight_m = np.hypot(sight_x, sight_y)
    apart = sight_m > 0.0
    unit_x = np.where(apart, sight_x / np.where(apart, sight_m, 1.0), ahead_x)
    unit_y = np.where(apart, sight_y / np.where(apart, sight_m, 1.0), ahead_y)
    own_along = own_x * unit_x + own_y * unit_y
    x_m = sight_x * ahead_x + sight_y * ahead_y
    oncoming = vehicles.speed_mps[seen] * own_along < -ONCOMING_MPS
    keep = (x_m >= 0.0) & (sight_m <= range_m) & ~oncoming
    y_m = (sight_y + back / 2.0 * own_y) * ahead_x - (sight_x + back / 2.0 * own_x) * ahead_y
    same_road = vehicles.road[seen] == vehicles.road[me]
    lane = np.where(same_road, vehicles.lane_index[seen] - vehicles.lane_index[me], UNKNOWN_LANE)
    range_rate = vehicles.speed_mps[seen] * own_along - vehicles.speed_mps[me] * (ahead_x * unit_x + ahead_y * unit_y)
    accel = vehicles.accel_mps2[seen] * own_along
    if lanes is not None:
        lane, along_m = _lane_on_map(vehicles, owner, seen, x_m, lanes, lane)
        on_path = ~np.isnan(along_m)
        keep = np.where(on_path, (along_m >= 0.0) & (along_m <= range_m), keep)
        x_m = np.where(on_path, along_m, x_m)
        range_rate = np.where(on_path, vehicles.speed_mps[seen] - vehicles.speed_mps[me], range_rate)
        accel = np.where(on_path, vehicles.accel_mps2[seen], accel)
    k = np.flatnonzero(keep)
    return SensorPairs(owner[k], seen[k], x_m[k], y_m[k], range_rate[k], accel[k], lane[k])


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
        The settings of a category (default :meth:`csws.fcw.physics.FcwSettings.for_category`).
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
        self.numbers = _Numbers()
        self.sizes: dict[str, tuple[float, float]] = {}
        self.roads: dict[str, int] = {}
        self.horizons: dict[int, Any] = {}
        self.categories: dict[str, int] = {}
        self.distinct_settings: list[FcwSettings] = []
        self.memory = FleetMemory.new(0)
        self.last_heading_rad = np.zeros(0)
        self.last_time_s = -math.inf

    def __call__(
        self,
        vehicle_ids: Sequence[str],
        categories: Sequence[str],
        on_lane: Sequence[bool],
        paths: Sequence[Any | None] | None = None,
    ) -> FcwColumns:
        """The warning of every equipped vehicle (``vehicle_ids``, of ``categories``), in order; a vehicle on
        no lane is in fault (4.4.5). ``paths``: each vehicle's map path ahead where it is map-matched (a
        :class:`csws.ahead.horizon.PathAhead`, else None; the curve warning's horizon), which assigns the
        objects' lanes (:func:`sensor_view`)."""
        now_s = float(self.sumo.simulation.getTime())
        vehicles = read_vehicles(self.sumo, self.numbers, self.sizes, self.roads)
        row_of = {vehicle_id: row for row, vehicle_id in enumerate(vehicles.vehicle_id)}
        rows = np.array([row_of[vehicle_id] for vehicle_id in vehicle_ids], dtype=np.int64)
        numbers = vehicles.number[rows]
        self._grow(int(vehicles.number.max()) + 1 if vehicles.number.size else 0)
        yaw_rate = self._yaw_rate_rps(numbers, vehicles.heading_rad[rows], now_s)
        # SUMO's angle is the body's chord (rear and front on the lane): the front runs along the
        # lane's tangent, turned from it by half the length times the path's curvature.
        kappa = yaw_path_curvature_1pm(vehicles.speed_mps[rows], np.nan_to_num(yaw_rate))
        path_turn_rad = kappa * vehicles.length_m[rows] / 2.0
        columns = FcwColumns.quiet([FCW_STATES[STANDBY].value] * len(rows))
        kinds = np.array([self._settings_code(category) for category in categories], dtype=np.int64)
        keys = []
        for kind in dict.fromkeys(kinds.tolist()):
            settings = self.distinct_settings[kind]
            group = np.flatnonzero(kinds == kind)
            subjects = rows[group]
            lanes = None
            if paths is not None:
                lanes = map_lanes([paths[i] for i in group.tolist()], self.roads, settings.range_m, self.horizons)
            pairs = sensor_view(vehicles, subjects, settings.range_m, path_turn_rad[group], lanes)
            ego = FleetEgo.of(
                vehicles.speed_mps[subjects],
                vehicles.accel_mps2[subjects],
                yaw_rate[group],
                braking=(vehicles.signals[subjects] & BRAKE_LIGHT) > 0,
                turn_signal=_turn_signal(vehicles.signals[subjects]),
                sensor_ok=np.asarray(on_lane, dtype=bool)[group],
            )
            objects = FleetObjects.of(
                pairs.subject,
                vehicles.number[pairs.seen],
                pairs.x_m,
                pairs.y_m,
                pairs.relative_speed_mps,
                pairs.accel_mps2,
                width_m=vehicles.width_m[pairs.seen],
                lane=pairs.lane,
            )
            if self.measure is not None:
                ego, objects = self.measure(ego, objects)
            frame, kept = update_fleet(settings, self._recall(numbers[group]), now_s, ego, objects)
            keys.append(self._keep(numbers[group], kept))
            _write(columns, group, frame, vehicles.vehicle_id, pairs.seen)
        self.memory.in_path_keys = np.sort(np.concatenate([k[0] for k in keys])) if keys else np.zeros(0, np.int64)
        self.memory.cut_in_keys = np.sort(np.concatenate([k[1] for k in keys])) if keys else np.zeros(0, np.int64)
        self.last_time_s = now_s
        return columns

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

    def _yaw_rate_rps(self, numbers: np.ndarray, heading_rad: np.ndarray, now_s: float) -> np.ndarray:
        """The yaw rate over the last step (positive turning left; SUMO's angle turns clockwise),
        NaN (not given) in a vehicle's first step."""
        last_time = self.memory.last_time_s[numbers]
        turn = (heading_rad - self.last_heading_rad[numbers] + math.pi) % (2.0 * math.pi) - math.pi
        with np.errstate(invalid="ignore", divide="ignore"):
            yaw = np.where(last_time == self.last_time_s, -turn / (now_s - last_time), np.nan)
        self.last_heading_rad[numbers] = heading_rad
        return yaw

    def _recall(self, numbers: np.ndarray) -> FleetMemory:
        """The memory of the vehicles ``numbers``, indexed as in this call."""
        memory = self.memory
        index = np.full(memory.state.size, -1, dtype=np.int64)
        index[numbers] = np.arange(numbers.size)

        def local(keys: np.ndarray) -> np.ndarray:
            row = index[keys >> _ID_BITS]
            mine = row >= 0
            return np.sort((row[mine] << _ID_BITS) | (keys[mine] & MAX_ID_MASK))

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
            return (numbers[keys >> _ID_BITS] << _ID_BITS) | (keys & MAX_ID_MASK)

        return by_number(kept.in_path_keys), by_number(kept.cut_in_keys)

    def forget(self, vehicle_ids: Sequence[str]) -> None:
        """Drop vehicles that left (their numbers are not given again)."""
        for vehicle_id in vehicle_ids:
            self.sizes.pop(vehicle_id, None)
            number = self.numbers.pop(vehicle_id, None)
            if number is not None and number < self.memory.state.size:
                self.memory.last_time_s[number] = -math.inf


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
