"""The forward collision warning of a fleet from its sensors' object lists, in numpy arrays.

:func:`update_fleet` is :meth:`csws.fcw.tracker.ForwardCollisionWarning.update` for many vehicles
at once, through the same formulas, with the same answers to the bit: the subjects as columns
``(n,)`` (:class:`FleetEgo`), the objects of all of them as flat columns ``(m,)`` with the owning
vehicle's index (:class:`FleetObjects`), the map paths, where any, as flat knot columns
(:class:`FleetPaths`), and what each vehicle keeps between frames as arrays (:class:`FleetMemory`).
One settings object applies to the call; a fleet of several categories calls once per group.
In the optional columns ``yaw_rate_rps`` and ``curvature_1pm`` NaN means "not given"; everywhere
else a NaN is an error.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from csws.fcw.objects import MAX_OBJECT_ID, cut_in, hold_level, in_path
from csws.fcw.path import curvature_tables, fleet_equivalent_curvature_1pm, offset_from_circle_m, yaw_path_curvature_1pm
from csws.fcw.physics import a_req_core, ettc_core, ttc_core, warning_level
from csws.fcw.settings import FcwSettings
from csws.fcw.state import ACTIVE, STANDBY, fcw_state_code

__all__ = ["FleetEgo", "FleetObjects", "FleetPaths", "FleetMemory", "FleetFrame", "UNKNOWN_LANE", "update_fleet"]

#: The lane column's value where the sensor assigns no lane.
UNKNOWN_LANE = -128


def _column(name: str, values: ArrayLike, dtype: type, size: int | None = None) -> np.ndarray:
    """A 1-d column as ``dtype``; ValueError naming it if its length is wrong or a float is not finite."""
    column: np.ndarray = np.asarray(values, dtype=dtype)
    if column.ndim != 1 or (size is not None and column.size != size):
        raise ValueError(f"{name}: expected a 1-d column of {size if size is not None else 'any'} values")
    if dtype is float and not np.all(np.isfinite(column)):
        raise ValueError(
            f"{name}: every value must be finite (NaN or inf at index {np.flatnonzero(~np.isfinite(column))[0]})"
        )
    return column


@dataclass(frozen=True)
class FleetEgo:
    """The subjects of one frame, columns ``(n,)`` (the fields of :class:`csws.fcw.objects.EgoMotion`)."""

    speed_mps: np.ndarray
    accel_mps2: np.ndarray
    yaw_rate_rps: np.ndarray
    curvature_1pm: np.ndarray
    braking: np.ndarray
    turn_signal: np.ndarray
    switched_on: np.ndarray
    forward_gear: np.ndarray
    sensor_ok: np.ndarray

    @classmethod
    def of(
        cls,
        speed_mps: ArrayLike,
        accel_mps2: ArrayLike | None = None,
        yaw_rate_rps: ArrayLike | None = None,
        curvature_1pm: ArrayLike | None = None,
        braking: ArrayLike = False,
        turn_signal: ArrayLike = 0,
        switched_on: ArrayLike = True,
        forward_gear: ArrayLike = True,
        sensor_ok: ArrayLike = True,
    ) -> FleetEgo:
        """Columns checked and broadcast to the speeds' length (absent: 0 acceleration, no yaw rate or curvature)."""
        speed = _column("ego speed_mps", speed_mps, float)
        n = speed.size
        if np.any(speed < 0.0):
            raise ValueError("ego speed_mps: must be >= 0")

        def full(name: str, value: ArrayLike | None, dtype: type, fill: ArrayLike) -> np.ndarray:
            return _column(name, np.broadcast_to(fill if value is None else value, (n,)), dtype, n)

        optional = [
            np.broadcast_to(np.nan if v is None else np.asarray(v, float), (n,)) for v in (yaw_rate_rps, curvature_1pm)
        ]
        for name, column in zip(("ego yaw_rate_rps", "ego curvature_1pm"), optional, strict=True):
            if np.any(np.isinf(column)):
                raise ValueError(f"{name}: must be finite or NaN (not given)")
        signal = full("ego turn_signal", turn_signal, np.int8, 0)
        if np.any(np.abs(signal) > 1):
            raise ValueError("ego turn_signal: must be -1, 0 or 1")
        return cls(
            speed,
            full("ego accel_mps2", accel_mps2, float, 0.0),
            np.array(optional[0], dtype=float),
            np.array(optional[1], dtype=float),
            full("ego braking", braking, bool, False),
            signal,
            full("ego switched_on", switched_on, bool, True),
            full("ego forward_gear", forward_gear, bool, True),
            full("ego sensor_ok", sensor_ok, bool, True),
        )


@dataclass(frozen=True)
class FleetObjects:
    """The objects of all vehicles of one frame, flat columns ``(m,)`` (:class:`csws.fcw.objects.SensorObject`)."""

    vehicle: np.ndarray
    id: np.ndarray
    x_m: np.ndarray
    y_m: np.ndarray
    relative_speed_mps: np.ndarray
    accel_mps2: np.ndarray
    accel_is_relative: np.ndarray
    width_m: np.ndarray
    lane: np.ndarray

    @classmethod
    def of(
        cls,
        vehicle: ArrayLike,
        id: ArrayLike,  # noqa: A002 - the field's name
        x_m: ArrayLike,
        y_m: ArrayLike,
        relative_speed_mps: ArrayLike,
        accel_mps2: ArrayLike = 0.0,
        accel_is_relative: ArrayLike = False,
        width_m: ArrayLike = 1.8,
        lane: ArrayLike = UNKNOWN_LANE,
    ) -> FleetObjects:
        """Columns checked: finite values, ids in [0, 2^31), positive widths, broadcast to the vehicles' length."""
        owner = _column("objects vehicle", vehicle, np.int64)
        m = owner.size
        ids = _column("objects id", id, np.int64, m)
        if np.any((ids < 0) | (ids > MAX_OBJECT_ID)):
            raise ValueError("objects id: must be in [0, 2^31)")
        floats = [
            _column(f"objects {name}", np.broadcast_to(np.asarray(value, dtype=float), (m,)), float, m)
            for name, value in (
                ("x_m", x_m),
                ("y_m", y_m),
                ("relative_speed_mps", relative_speed_mps),
                ("accel_mps2", accel_mps2),
                ("width_m", width_m),
            )
        ]
        if np.any(floats[4] <= 0.0):
            raise ValueError("objects width_m: must be positive")
        relative = _column("objects accel_is_relative", np.broadcast_to(accel_is_relative, (m,)), bool, m)
        lanes = _column("objects lane", np.broadcast_to(lane, (m,)), np.int64, m)
        x, y, v_r, accel, width = floats
        return cls(owner, ids, x, y, v_r, accel, relative, width, lanes)


@dataclass(frozen=True)
class FleetPaths:
    """The map paths (:class:`csws.fcw.path.PathCurvature`) of some vehicles as flat knots, grouped by vehicle."""

    vehicle: np.ndarray
    s_m: np.ndarray
    curvature_1pm: np.ndarray


@dataclass
class FleetMemory:
    """What each vehicle keeps between frames, as :class:`csws.fcw.tracker.ForwardCollisionWarning` does."""

    state: np.ndarray
    held_level: np.ndarray
    hold_until_s: np.ndarray
    last_time_s: np.ndarray
    in_path_keys: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    cut_in_keys: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    @classmethod
    def new(cls, vehicles: int) -> FleetMemory:
        """A fleet of ``vehicles`` systems just switched on (standby, nothing held)."""
        return cls(
            np.full(vehicles, STANDBY, dtype=np.int8),
            np.zeros(vehicles, dtype=np.int8),
            np.full(vehicles, -math.inf),
            np.full(vehicles, -math.inf),
        )


@dataclass(frozen=True)
class FleetFrame:
    """The answers of one frame, arrays ``(n,)`` (the fields of :class:`csws.fcw.objects.FcwFrame`;
    ``state`` as codes into :data:`csws.fcw.state.FCW_STATES`, ``target`` the target's index into
    the objects or -1, ``target_id`` its id or -1)."""

    state: np.ndarray
    level: np.ndarray
    required_level: np.ndarray
    target: np.ndarray
    target_id: np.ndarray
    clearance_m: np.ndarray
    relative_speed_mps: np.ndarray
    ttc_s: np.ndarray
    ettc_s: np.ndarray
    a_req_mps2: np.ndarray
    path_offset_m: np.ndarray


def _padded_paths(paths: FleetPaths, vehicles: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The paths as rows padded with ``s = inf``, the row of each vehicle (-1 without a path)."""
    owner = _column("paths vehicle", paths.vehicle, np.int64)
    s = _column("paths s_m", paths.s_m, float, owner.size)
    kappa = _column("paths curvature_1pm", paths.curvature_1pm, float, owner.size)
    if np.any((owner < 0) | (owner >= vehicles)) or np.any(np.diff(owner) < 0):
        raise ValueError("paths vehicle: must be vehicle indices, grouped in increasing order")
    first = np.concatenate(([True], owner[1:] != owner[:-1])) if owner.size else np.zeros(0, dtype=bool)
    if np.any(s[first] != 0.0) or np.any(np.diff(s)[~first[1:]] <= 0.0):
        raise ValueError("paths s_m: each path must start at 0 (the subject's front) and increase strictly")
    starts = np.flatnonzero(first)
    counts = np.diff(np.append(starts, owner.size))
    column = np.arange(owner.size) - np.repeat(starts, counts)
    rows = np.repeat(np.arange(starts.size), counts)
    width = int(counts.max()) if counts.size else 1
    s_rows, kappa_rows = np.full((starts.size, width), np.inf), np.zeros((starts.size, width))
    s_rows[rows, column], kappa_rows[rows, column] = s, kappa
    row_of = np.full(vehicles, -1, dtype=np.int64)
    row_of[owner[starts]] = np.arange(starts.size)
    return s_rows, kappa_rows, row_of


def _object_curvature(
    ego: FleetEgo, objects: FleetObjects, centre_x_m: np.ndarray, paths: FleetPaths | None, active: np.ndarray
) -> np.ndarray:
    """Each object's path curvature: its vehicle's map path (κ_eq, without a turn signal), else the
    curvature given, else yaw rate / speed, else 0 (:func:`csws.fcw.tracker.ego_curvature_1pm`)."""
    yaw = yaw_path_curvature_1pm(ego.speed_mps, np.nan_to_num(ego.yaw_rate_rps))
    own = np.where(np.isnan(ego.curvature_1pm), np.where(np.isnan(ego.yaw_rate_rps), 0.0, yaw), ego.curvature_1pm)
    kappa = own[objects.vehicle]
    if paths is None:
        return kappa
    s_rows, kappa_rows, row_of = _padded_paths(paths, ego.speed_mps.size)
    row = row_of[objects.vehicle]
    mapped = np.flatnonzero((row >= 0) & (ego.turn_signal[objects.vehicle] == 0) & active[objects.vehicle])
    if mapped.size:
        tables = curvature_tables(s_rows, kappa_rows)
        kappa[mapped] = fleet_equivalent_curvature_1pm(
            s_rows, kappa_rows, tables, row[mapped], centre_x_m[mapped], objects.y_m[mapped]
        )
    return kappa


def _keys(objects: FleetObjects, chosen: np.ndarray) -> np.ndarray:
    """The sorted keys (vehicle, id) of the chosen objects."""
    return np.sort((objects.vehicle[chosen] << 32) | objects.id[chosen])


def _member(keys: np.ndarray, sorted_keys: np.ndarray) -> np.ndarray:
    """Whether each key is among the sorted keys."""
    if not sorted_keys.size:
        return np.zeros(keys.size, dtype=bool)
    return sorted_keys[np.minimum(np.searchsorted(sorted_keys, keys), sorted_keys.size - 1)] == keys


def _targets(
    owner: np.ndarray, candidate: np.ndarray, level: np.ndarray, a_req: np.ndarray, x_m: np.ndarray, n: int
) -> np.ndarray:
    """Per vehicle the candidate requiring the highest level, then with the highest rank (a_req, at least the
    preliminary threshold), ties the nearest, then the first listed; -1 without one."""
    target = np.full(n, -1, dtype=np.int64)
    index = np.flatnonzero(candidate)
    if index.size:
        ordered = index[np.lexsort((index, x_m[index], -a_req[index], -level[index], owner[index]))]
        first = np.concatenate(([True], owner[ordered][1:] != owner[ordered][:-1]))
        target[owner[ordered][first]] = ordered[first]
    return target


def update_fleet(
    settings: FcwSettings,
    memory: FleetMemory,
    time_s: ArrayLike,
    ego: FleetEgo,
    objects: FleetObjects,
    paths: FleetPaths | None = None,
) -> tuple[FleetFrame, FleetMemory]:
    """One frame of every vehicle's forward collision warning: the answers and the memory for the next frame.

    The same steps as :meth:`csws.fcw.tracker.ForwardCollisionWarning.update`, vehicle by vehicle.
    ``time_s`` is the frame's time, one for all or one per vehicle, increasing per vehicle.
    """
    n = ego.speed_mps.size
    now = _column("time_s", np.broadcast_to(np.asarray(time_s, dtype=float), (n,)), float, n)
    if np.any(now <= memory.last_time_s):
        raise ValueError("time_s: must increase from frame to frame")
    if objects.vehicle.size and (objects.vehicle.min() < 0 or objects.vehicle.max() >= n):
        raise ValueError("objects vehicle: indices must be in [0, number of vehicles)")
    keys = (objects.vehicle << 32) | objects.id
    ordered = np.sort(keys)
    if np.any(ordered[1:] == ordered[:-1]):
        raise ValueError("objects: duplicate object ids within a vehicle")
    state = np.asarray(
        fcw_state_code(memory.state, ego.speed_mps, ego.switched_on, ego.sensor_ok, ego.forward_gear, settings),
        dtype=np.int8,
    )
    active = state == ACTIVE
    owner = objects.vehicle
    centre_x_m = objects.x_m + settings.object_half_length_m
    kappa = _object_curvature(ego, objects, centre_x_m, paths, active)
    offset = offset_from_circle_m(centre_x_m, objects.y_m, kappa)
    known = objects.lane != UNKNOWN_LANE
    inside = in_path(objects.x_m, offset, objects.lane, known, settings.path_half_width_m, settings.range_m)
    inside &= active[owner]
    was_in = _member(keys, memory.in_path_keys)
    cutting = cut_in(inside, objects.relative_speed_mps, was_in, _member(keys, memory.cut_in_keys))
    a_sv = ego.accel_mps2[owner]
    a_tv = np.where(objects.accel_is_relative, objects.accel_mps2 + a_sv, objects.accel_mps2)
    lost = np.where(ego.braking[owner], 0.0, settings.reaction_time_s + settings.brake_response_s)
    with np.errstate(over="ignore"):  # a_req beyond the largest float is inf, as on floats
        a_req = a_req_core(objects.x_m, objects.relative_speed_mps, a_tv, a_sv, lost, ego.speed_mps[owner])
    rank = np.maximum(a_req, settings.preliminary_a_req_mps2)  # below a threat every object ties: the nearest
    with np.errstate(over="ignore"):  # beyond the largest float: inf, as on floats
        ttc = ttc_core(objects.x_m, objects.relative_speed_mps)
        ettc = ettc_core(objects.x_m, objects.relative_speed_mps, a_tv - a_sv)
    level = warning_level(a_sv, ttc, ettc, a_req, settings)
    target = _targets(owner, inside & ~cutting, level, rank, objects.x_m, n)
    return _frame(settings, memory, now, ego, objects, state, target, (a_tv, offset, a_req), inside, cutting)


def _frame(
    settings: FcwSettings,
    memory: FleetMemory,
    now: np.ndarray,
    ego: FleetEgo,
    objects: FleetObjects,
    state: np.ndarray,
    target: np.ndarray,
    figures: tuple[np.ndarray, np.ndarray, np.ndarray],
    inside: np.ndarray,
    cutting: np.ndarray,
) -> tuple[FleetFrame, FleetMemory]:
    """The targets' figures and levels, the hold, and the memory for the next frame."""
    a_tv, offset, a_req = figures
    has = target >= 0

    def pick(column: np.ndarray, fill: float) -> np.ndarray:
        """The target's value of an object column per vehicle, ``fill`` without a target."""
        return np.where(has, column[np.where(has, target, 0)], fill) if column.size else np.full(has.size, fill)

    x_c, v_r = pick(objects.x_m, math.nan), pick(objects.relative_speed_mps, math.nan)
    target_a_req, target_a_tv = pick(a_req, math.nan), pick(a_tv, 0.0)
    with np.errstate(over="ignore"):  # beyond the largest float: inf, as on floats
        ttc = np.where(has, ttc_core(np.nan_to_num(x_c), np.nan_to_num(v_r)), math.nan)
        ettc = np.where(has, ettc_core(np.nan_to_num(x_c), np.nan_to_num(v_r), target_a_tv - ego.accel_mps2), math.nan)
    required = np.where(has, warning_level(ego.accel_mps2, ttc, ettc, target_a_req, settings), 0).astype(np.int8)
    active = state == ACTIVE
    holdable = active & (-ego.accel_mps2 < settings.collision_a_req_mps2)
    held = np.where(active, memory.held_level, 0)
    level, held, until = hold_level(required, held, memory.hold_until_s, now, holdable, settings.level_hold_s)
    until = np.where(active, until, -math.inf)
    frame = FleetFrame(
        state,
        np.asarray(level, dtype=np.int8),
        required,
        target,
        pick(objects.id, -1).astype(np.int64),
        x_c,
        v_r,
        ttc,
        ettc,
        target_a_req,
        pick(offset, math.nan),
    )
    kept = FleetMemory(
        state, np.asarray(held, dtype=np.int8), until, now, _keys(objects, inside), _keys(objects, cutting)
    )
    return frame, kept
