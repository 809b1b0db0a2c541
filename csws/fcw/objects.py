"""What the forward collision warning reads each frame, a sensor's object list, and what it answers.

Frame conventions (the subject vehicle's, SI units): x forward, y to the left; an object's ``x_m``
is the distance ahead from the subject's front to the object's rear (the clearance x_c of 3.10
as a radar or camera track gives it), ``y_m`` the lateral position of the object's centre;
``relative_speed_mps`` is the object's longitudinal speed minus the subject's (v_r of formula (1),
negative while closing); the acceleration is the object's own (a_TV) or, with
``accel_is_relative``, the object's minus the subject's. ``lane`` is the sensor's lane
assignment where it makes one (0 the subject's lane, +1 left, -1 right); it then decides
whether the object is in the path instead of the predicted path.

The rules an object is judged by, written once for floats (one vehicle) and arrays (a fleet):
:func:`in_path` and :func:`cut_in` (4.5.5 b and c), :func:`hold_level` (the level's hysteresis).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from csws.fcw.numeric import fmax, where
from csws.fcw.path import PathCurvature
from csws.state import SystemState

__all__ = ["EgoMotion", "SensorObject", "FcwFrame", "in_path", "cut_in", "hold_level", "MAX_OBJECT_ID"]

#: Object ids are taken in [0, 2^31) (a fleet keys each object by vehicle and id in one int64).
MAX_OBJECT_ID = 2**31 - 1


def _require_finite(owner: str, **values: float) -> None:
    """ValueError naming the first value that is not a finite number."""
    for name, value in values.items():
        if not (isinstance(value, float | int) and math.isfinite(value)):
            raise ValueError(f"{owner}: {name} must be a finite number, got {value!r}")


@dataclass(frozen=True, slots=True)
class EgoMotion:
    """The subject vehicle in one frame.

    Attributes
    ----------
    speed_mps, accel_mps2
        Its speed and longitudinal acceleration a_SV (signed, negative braking).
    yaw_rate_rps, curvature_1pm
        Yaw rate (rad/s, positive turning left) and/or the path's curvature (1/m); the curvature,
        where given, is used before the yaw rate; neither: straight ahead.
    braking
        The driver presses the brake pedal (4.5.4: T_resp and T_b are then 0).
    turn_signal
        -1 right, 0 none, +1 left: with a signal on, the map path (the lane being left) is not used.
    switched_on, forward_gear, sensor_ok
        The driver's switch (off: state off), a forward gear engaged (reverse or park: standby,
        4.3.2), the forward sensor working (else fault, 4.4.5).
    map_path
        The road ahead's curvature where the vehicle is map-matched (:mod:`csws.fcw.path`).
    """

    speed_mps: float
    accel_mps2: float = 0.0
    yaw_rate_rps: float | None = None
    curvature_1pm: float | None = None
    braking: bool = False
    turn_signal: int = 0
    switched_on: bool = True
    forward_gear: bool = True
    sensor_ok: bool = True
    map_path: PathCurvature | None = None

    def __post_init__(self) -> None:
        _require_finite("ego", speed_mps=self.speed_mps, accel_mps2=self.accel_mps2)
        optional = {"yaw_rate_rps": self.yaw_rate_rps, "curvature_1pm": self.curvature_1pm}
        _require_finite("ego", **{name: value for name, value in optional.items() if value is not None})
        if self.speed_mps < 0.0 or self.turn_signal not in (-1, 0, 1):
            raise ValueError("ego: speed_mps must be >= 0 and turn_signal one of -1, 0, 1")


@dataclass(frozen=True, slots=True)
class SensorObject:
    """One object of the sensor's list (see the module's frame conventions).

    Attributes
    ----------
    id
        The sensor's track id, unique in a frame, in [0, :data:`MAX_OBJECT_ID`].
    x_m, y_m
        Ahead of the subject's front to the object's rear, and left to its centre, m.
    relative_speed_mps
        The object's longitudinal speed minus the subject's, m/s.
    accel_mps2, accel_is_relative
        The object's acceleration, m/s^2: its own, or with ``accel_is_relative`` its minus the subject's.
    width_m
        Its width, m.
    lane
        The sensor's lane assignment (0 own, +1 left, -1 right) or None.
    """

    id: int
    x_m: float
    y_m: float
    relative_speed_mps: float
    accel_mps2: float = 0.0
    accel_is_relative: bool = False
    width_m: float = 1.8
    lane: int | None = None

    def __post_init__(self) -> None:
        name = f"object {self.id!r}"
        if not (isinstance(self.id, int) and 0 <= self.id <= MAX_OBJECT_ID):
            raise ValueError(f"{name}: id must be an int in [0, 2^31)")
        _require_finite(
            name,
            x_m=self.x_m,
            y_m=self.y_m,
            relative_speed_mps=self.relative_speed_mps,
            accel_mps2=self.accel_mps2,
            width_m=self.width_m,
        )
        if self.width_m <= 0.0:
            raise ValueError(f"{name}: width_m must be positive, got {self.width_m!r}")


@dataclass(slots=True)
class FcwFrame:
    """The answer of one frame (a new record each frame, which the system does not keep: not frozen, as a frozen
    dataclass's construction would be a tenth of one vehicle's frame).

    Attributes
    ----------
    time_s, state
        The frame's time and the system's state (4.3).
    level, required_level
        The level shown (0 none, 1 preliminary, 2 collision warning) and the level the thresholds
        require now (the shown one is never lower; it is higher while a level is held).
    target_id
        The most demanding object in the path (the highest level required, then the highest a_req, then
        the nearest), or None.
    clearance_m, relative_speed_mps, ttc_s, ettc_s, a_req_mps2, path_offset_m
        The target's x_c, v_r, TTC, ETTC, a_req and lateral offset from the predicted path
        (NaN without a target; TTC, ETTC and a_req ``inf`` where they are).
    """

    time_s: float
    state: SystemState
    level: int
    required_level: int
    target_id: int | None
    clearance_m: float = math.nan
    relative_speed_mps: float = math.nan
    ttc_s: float = math.nan
    ettc_s: float = math.nan
    a_req_mps2: float = math.nan
    path_offset_m: float = math.nan


def in_path(x_m: Any, offset_m: Any, lane: Any, lane_known: Any, half_width_m: float, range_m: float) -> Any:
    """4.5.5 b, 4.7.3: an object is in the path while ahead within the range and, where the sensor
    assigns lanes, in lane 0, else with its centre within ``half_width_m`` of the predicted path."""
    beside = where(lane_known, lane == 0, abs(offset_m) <= half_width_m)
    return beside & (x_m >= 0.0) & (x_m <= range_m)


def cut_in(inside: Any, relative_speed_mps: Any, was_in_path: Any, was_cut_in: Any) -> Any:
    """4.5.5 c: an object faster than the subject that came into the path (was not in it in the
    previous frame) is a cut-in, and stays one while in the path and faster; it is not warned of."""
    return inside & (relative_speed_mps > 0.0) & where(was_in_path, was_cut_in, True)


def hold_level(
    required: Any, held: Any, hold_until_s: Any, time_s: Any, holdable: Any, hold_s: float
) -> tuple[Any, Any, Any]:
    """The level shown and the hold kept: a level stays on ``hold_s`` after it was last required.

    The shown level is the larger of the required one and the held one, so it is never lower
    than what the thresholds require now and rises at once. The hold is dropped where it may not
    apply (``holdable`` false: the system not active, or 4.5.5 a, the subject braking at the
    collision threshold). Returns (shown, held level, hold until).
    """
    kept = where(holdable & (time_s < hold_until_s), held, 0)
    shown = fmax(required, kept)
    refresh = (required > 0) & (required >= kept)
    until = where(refresh, time_s + hold_s, where(kept > 0, hold_until_s, -math.inf))
    return shown, where(refresh, required, kept), until
