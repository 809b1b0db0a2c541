"""What each equipped vehicle's sensor sees of the SUMO vehicles around it, in the frame of the object FCW.

:func:`read_vehicles` reads every SUMO vehicle once a step (the front's position, the angle, speed,
acceleration, road and lane, signals); :func:`sensor_view` turns the vehicles around each equipped
vehicle into its object list (the frame of :mod:`csws.fcw.objects`: x ahead from the front bumper to
the object's rear, y left to the object's centre, the longitudinal relative speed, the object's own
acceleration, its width, and the lane SUMO assigns where both drive on the same road). The pairs
within the sensor's range are found on a grid of cells a range wide, sorted once per step: each
equipped vehicle looks only at the 3 x 3 cells around it, not at every vehicle.

Where a vehicle is map-matched, its path ahead (the curve warning's horizon, :mod:`csws.ahead`)
assigns the objects' lanes (4.3.2 d: :func:`map_lanes`): a vehicle on a road the path does not take
is not in the path; one on a road it takes is measured along the path, its distance the road's and its
range rate the speeds' difference (round a hairpin the line of sight is far shorter than the road, and a
leader turning on the path moves away from the line of sight to it).
"""

from __future__ import annotations

from collections.abc import Container, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from csws.fcw.fleet import UNKNOWN_LANE, FleetObjects

__all__ = [
    "BLINKER_LEFT",
    "BLINKER_RIGHT",
    "BRAKE_LIGHT",
    "ID_BITS",
    "MAX_ID_MASK",
    "VehicleNumbers",
    "OFF_PATH_LANE",
    "SumoVehicles",
    "read_vehicles",
    "MapLanes",
    "nearby_pairs",
    "map_lanes",
    "SensorPairs",
    "sensor_view",
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
ID_BITS = 32
MAX_ID_MASK = (1 << ID_BITS) - 1


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


class VehicleNumbers(dict[str, int]):
    """A number per SUMO vehicle id, given in order of first sight and never reused."""

    def __missing__(self, vehicle_id: str) -> int:
        number = self[vehicle_id] = self.issued = getattr(self, "issued", -1) + 1
        return number


def read_vehicles(
    sumo: Any,
    numbers: dict[str, int],
    sizes: dict[str, tuple[float, float]],
    roads: dict[str, int] | None = None,
    asleep: Container[str] = (),
) -> SumoVehicles:
    """Every SUMO vehicle's values of this step but those ``asleep``, in SUMO's order, one getter call per
    vehicle and value (lengths and widths read once per vehicle into ``sizes``; ``numbers`` gives each id
    its number, ``roads`` each road id its code, kept from step to step where given)."""
    vehicle = sumo.vehicle
    ids = [v for v in vehicle.getIDList() if v not in asleep] if asleep else list(vehicle.getIDList())
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
    path_keys = (lanes.subject << ID_BITS) | lanes.road
    order = np.argsort(path_keys, kind="stable")
    ordered = path_keys[order]
    keys = (owner << ID_BITS) | vehicles.road[seen]
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

    def of_subjects(self, chosen: np.ndarray) -> SensorPairs:
        """The pairs of the subjects ``chosen`` (a mask over the subjects), the subjects renumbered among them
        in order (the view of a part of the subjects, as :func:`sensor_view` gives it for that part alone)."""
        number = np.cumsum(chosen) - 1
        keep = chosen[self.subject]
        return SensorPairs(
            number[self.subject[keep]],
            self.seen[keep],
            self.x_m[keep],
            self.y_m[keep],
            self.relative_speed_mps[keep],
            self.accel_mps2[keep],
            self.lane[keep],
        )

    def objects(self, vehicles: SumoVehicles) -> FleetObjects:
        """The objects the subjects see, as the FCW's fleet batch takes them: each seen vehicle by its number,
        with its width (:func:`csws.fcw.fleet.update_fleet`)."""
        return FleetObjects.of(
            self.subject,
            vehicles.number[self.seen],
            self.x_m,
            self.y_m,
            self.relative_speed_mps,
            self.accel_mps2,
            width_m=vehicles.width_m[self.seen],
            lane=self.lane,
        )


def nearby_pairs(cell_x: np.ndarray, cell_y: np.ndarray, subjects: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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
    owner, seen = nearby_pairs(cell_x, cell_y, subjects)
    other = seen != subjects[owner]
    return owner[other], seen[other]


def _near_pairs(
    vehicles: SumoVehicles, subjects: np.ndarray, range_m: float, path_turn_rad: np.ndarray | None
) -> tuple[np.ndarray, ...]:
    """The (subject, vehicle) pairs whose fronts are near enough for the vehicle's rear to be ahead within
    ``range_m``: the subject index, its row, the vehicle's row, and the subject's frame's x axis (:func:`sensor_view`).

    A rear ahead (x >= 0) within the range has its front at most a vehicle's length farther and at most a
    length behind the subject's front, so the rest is computed for those only.
    """
    owner, seen = _pairs_within(vehicles, subjects, range_m)
    me = subjects[owner]
    heading = vehicles.heading_rad[subjects] - (0.0 if path_turn_rad is None else path_turn_rad)
    ahead_x, ahead_y = np.sin(heading)[owner], np.cos(heading)[owner]
    front_x = vehicles.front_x_m[seen] - vehicles.front_x_m[me]
    front_y = vehicles.front_y_m[seen] - vehicles.front_y_m[me]
    near = np.flatnonzero(
        (front_x * front_x + front_y * front_y <= (range_m + LONGEST_VEHICLE_M) ** 2)
        & (front_x * ahead_x + front_y * ahead_y >= -LONGEST_VEHICLE_M)
    )
    return owner[near], me[near], seen[near], ahead_x[near], ahead_y[near]


def sensor_view(
    vehicles: SumoVehicles,
    subjects: np.ndarray,
    range_m: float,
    path_turn_rad: np.ndarray | None = None,
    lanes: MapLanes | None = None,
    other_lanes: bool = True,
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

    Without ``other_lanes`` the objects in a known lane other than the subject's (SUMO's on the same road,
    the map path's, :data:`OFF_PATH_LANE` included) are left out: 4.5.5 b puts such an object out of the
    path whatever its position (:func:`csws.fcw.objects.in_path`), so it is never a target, a cut-in or
    remembered, and the FCW answers the same without it (the co-simulation's view, which then builds the
    columns of the few objects that can matter only).
    """
    owner, me, seen, ahead_x, ahead_y = _near_pairs(vehicles, subjects, range_m, path_turn_rad)
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
    same_road = vehicles.road[seen] == vehicles.road[me]
    lane = np.where(same_road, vehicles.lane_index[seen] - vehicles.lane_index[me], UNKNOWN_LANE)
    on_path = np.zeros(seen.size, dtype=bool)
    if lanes is not None:
        lane, along_m = _lane_on_map(vehicles, owner, seen, x_m, lanes, lane)
        on_path = ~np.isnan(along_m)
        keep = np.where(on_path, (along_m >= 0.0) & (along_m <= range_m), keep)
        x_m = np.where(on_path, along_m, x_m)
    if not other_lanes:
        keep = keep & ((lane == 0) | (lane == UNKNOWN_LANE))
    # In SUMO's order of the vehicles per subject, whichever grid cells they fell in (ties go to the first listed);
    # the rest of the columns for the pairs seen only.
    k = np.flatnonzero(keep)
    k = k[np.lexsort((seen[k], owner[k]))]
    owner, me, seen, ahead_x, ahead_y, on_path = owner[k], me[k], seen[k], ahead_x[k], ahead_y[k], on_path[k]
    own_x, own_y, back, sight_x, sight_y = own_x[k], own_y[k], back[k], sight_x[k], sight_y[k]
    y_m = (sight_y + back / 2.0 * own_y) * ahead_x - (sight_x + back / 2.0 * own_x) * ahead_y
    range_rate = np.where(
        on_path,
        vehicles.speed_mps[seen] - vehicles.speed_mps[me],
        vehicles.speed_mps[seen] * own_along[k] - vehicles.speed_mps[me] * (ahead_x * unit_x[k] + ahead_y * unit_y[k]),
    )
    accel = np.where(on_path, vehicles.accel_mps2[seen], vehicles.accel_mps2[seen] * own_along[k])
    return SensorPairs(owner, seen, x_m[k], y_m, range_rate, accel, lane[k])
