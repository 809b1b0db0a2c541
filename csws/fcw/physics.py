"""Forward collision warning physics (GB/T 33577-2017, ISO 15623): TTC, ETTC, a_req and the warning.

Time to collision, enhanced time to collision, required deceleration, and the warning they
give, for many vehicles at once.

The quantities, in the standard's symbols (3.10-3.12, 3.22; SI units, accelerations signed,
positive forward):

* relative velocity v_r = v_TV - v_SV, formula (1): negative while the subject vehicle
  (SV) closes on the target vehicle (TV);
* TTC = -x_c / v_r, formula (2), with x_c the clearance; defined only while closing;
* ETTC, formula (3): the time to collision with both accelerations held, the smaller
  positive root of x_c + v_r t + (a_TV - a_SV) t^2 / 2 = 0; TTC when the accelerations
  are equal;
* the required deceleration a_req = d_TV + v_r^2 / (2 (x_c - x_r)), formula (4), with
  d_TV the target's deceleration and x_r = -v_r (T_resp + T_b) the clearance lost while
  the driver reacts and the brakes respond (formula (5) uses the same, 0.8 v_r).

Where GB/T 33577 and the Russian text of ISO 15623 differ, this module follows GB/T 33577:
the factor 2 under the root of (3) and x_c - x_r in (4) (docs/fcw.md).

The warning (4.4.4, 4.5.3-4.5.5): a collision warning when a_req reaches
:attr:`FcwSettings.collision_a_req_mps2`, a preliminary warning (level 1) when it reaches
:attr:`FcwSettings.preliminary_a_req_mps2`. The standard caps the collision threshold at
0.68 g with T_resp >= 0.8 s; warning only at those limits is too late for its own tests (a
lead braking at 0.3 g from 30 m at 20 m/s is warned at a TTC of 1.96 s, 2.4 s is required),
so the defaults are a commercial vehicle's: T_resp 1.2 s and 0.5 g, the mean hard braking of
commercial vehicles in Annex A (5.3 m/s^2) rounded down. No warning (4.5.5) while the subject
vehicle already decelerates at the collision threshold or more, while it is not closing, or
while TTC exceeds :attr:`FcwSettings.max_ttc_s`; while the driver brakes, T_resp and T_b
are 0 (4.5.4).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from csws.state import SystemState

__all__ = [
    "STANDARD_GRAVITY_MPS2",
    "FCW_STATES",
    "FcwSettings",
    "FcwBatch",
    "time_to_collision_s",
    "enhanced_time_to_collision_s",
    "required_deceleration_mps2",
    "warning_clearance_m",
    "formula_5_clearance_m",
    "evaluate_fcw",
    "next_fcw_states",
]

STANDARD_GRAVITY_MPS2 = 9.80665
#: 4.5.3: the collision warning's a_req threshold may not exceed 0.68 g.
MAX_COLLISION_A_REQ_MPS2 = 0.68 * STANDARD_GRAVITY_MPS2
#: 4.5.4: the driver's reaction time to a warning is at least 0.8 s.
MIN_REACTION_TIME_S = 0.8
#: Formula (5), the shortest warning distance (5.4.1): the least reaction time of 4.5.4 and this a_req, m/s^2.
FORMULA_5_A_REQ_MPS2 = 6.67
#: 4.3.3: the system works from at most 11.2 m/s up to at least 27.8 m/s.
HIGHEST_MIN_SPEED_MPS, LOWEST_MAX_SPEED_MPS = 11.2, 27.8
#: The system states by code (4.3.2; fault as CSWS's, :class:`csws.state.SystemState`): ``FCW_STATES[code]``.
FCW_STATES = (SystemState.OFF, SystemState.STANDBY, SystemState.ACTIVE, SystemState.FAULT)
OFF, STANDBY, ACTIVE, FAULT = range(4)


@dataclass(frozen=True)
class FcwSettings:
    """The thresholds of the forward collision warning.

    Attributes
    ----------
    collision_a_req_mps2
        a_req at which the collision warning comes on (4.5.3: at most 0.68 g).
    preliminary_a_req_mps2
        a_req at which the preliminary warning comes on (4.5.3: lower than the collision's).
    reaction_time_s
        T_resp, the driver's reaction time to a warning (4.5.4: at least 0.8 s).
    brake_response_s
        T_b, the brake system's response time (4.5.4: chosen by the designer).
    max_ttc_s
        No warning while TTC exceeds this (4.5.5: 4.0 s).
    min_speed_mps, max_speed_mps
        V_min and V_max, the subject speeds the system is active between (4.3.3: V_min at most
        11.2 m/s, V_max at least 27.8 m/s; a truck's or bus's speed limiter keeps it below 27.8 m/s).
    hysteresis_mps
        delta of Figure 2: an active system goes to standby only this far outside [V_min, V_max].
    """

    collision_a_req_mps2: float = 0.5 * STANDARD_GRAVITY_MPS2
    preliminary_a_req_mps2: float = 0.3 * STANDARD_GRAVITY_MPS2
    reaction_time_s: float = 1.2
    brake_response_s: float = 0.0
    max_ttc_s: float = 4.0
    min_speed_mps: float = 10.0
    max_speed_mps: float = LOWEST_MAX_SPEED_MPS
    hysteresis_mps: float = 1.0

    def __post_init__(self) -> None:
        if not 0.0 < self.collision_a_req_mps2 <= MAX_COLLISION_A_REQ_MPS2:
            raise ValueError(f"the collision threshold must be in (0, 0.68 g], got {self.collision_a_req_mps2!r} m/s^2")
        if not 0.0 < self.preliminary_a_req_mps2 < self.collision_a_req_mps2:
            raise ValueError("the preliminary threshold must be positive and below the collision threshold")
        if not self.reaction_time_s >= MIN_REACTION_TIME_S:
            raise ValueError(f"the reaction time must be at least 0.8 s (4.5.4), got {self.reaction_time_s!r}")
        if not (self.brake_response_s >= 0.0 and self.max_ttc_s > 0.0):
            raise ValueError("the brake response time must be >= 0 and the TTC limit > 0")
        if not (
            0.0 <= self.min_speed_mps <= HIGHEST_MIN_SPEED_MPS
            and self.max_speed_mps >= LOWEST_MAX_SPEED_MPS
            and self.hysteresis_mps >= 0.0
        ):
            raise ValueError("4.3.3: V_min must be in [0, 11.2] m/s, V_max at least 27.8 m/s, the hysteresis >= 0")


@dataclass(frozen=True)
class FcwBatch:
    """The forward collision warning of many vehicles, as arrays ``(n,)``.

    Attributes
    ----------
    level
        0 none, 1 preliminary warning, 2 collision warning.
    ttc_s, ettc_s
        TTC and ETTC, s; ``inf`` where no collision follows under their assumptions.
    a_req_mps2
        The required deceleration, m/s^2 (``inf`` where the clearance is used up in the reaction).
    """

    level: np.ndarray
    ttc_s: np.ndarray
    ettc_s: np.ndarray
    a_req_mps2: np.ndarray


def time_to_collision_s(clearance_m: ArrayLike, relative_velocity_mps: ArrayLike) -> np.ndarray:
    """TTC = -x_c / v_r, formula (2); ``inf`` where the vehicles are not closing (v_r >= 0)."""
    clearance_m, v_r = np.asarray(clearance_m, dtype=float), np.asarray(relative_velocity_mps, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(v_r < 0.0, -clearance_m / v_r, np.inf)


def enhanced_time_to_collision_s(
    clearance_m: ArrayLike, relative_velocity_mps: ArrayLike, relative_accel_mps2: ArrayLike
) -> np.ndarray:
    """ETTC, formula (3), with the relative acceleration a_TV - a_SV held: the first time the
    clearance reaches 0; ``inf`` where it never does (the root of (3) is negative or complex).

    Formula (3) is the smaller root of x_c + v_r t + a t^2 / 2 = 0 with a = a_TV - a_SV; it is
    written here in the form that stays exact as a tends to 0, where ETTC tends to TTC.
    """
    x_c, v_r, a = (
        np.asarray(value, dtype=float) for value in (clearance_m, relative_velocity_mps, relative_accel_mps2)
    )
    discriminant = v_r**2 - 2.0 * a * x_c
    root = np.sqrt(np.fmax(discriminant, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        # (-v_r - root) / a == 2 x_c / (-v_r + root): the same root, without cancellation.
        ettc = np.where(-v_r + root > 0.0, 2.0 * x_c / (-v_r + root), np.inf)
    return np.where((discriminant >= 0.0) & (ettc >= 0.0), ettc, np.inf)


def required_deceleration_mps2(
    clearance_m: ArrayLike, relative_velocity_mps: ArrayLike, target_accel_mps2: ArrayLike, lost_time_s: ArrayLike
) -> np.ndarray:
    """a_req = d_TV + v_r^2 / (2 (x_c - x_r)), formula (4), with d_TV = -a_TV the target's
    deceleration and x_r = -v_r ``lost_time_s`` the clearance lost while closing during the
    driver's reaction and the brakes' response (0 while not closing). ``inf`` where that
    uses up the clearance."""
    x_c, v_r, a_tv, lost_s = (
        np.asarray(value, dtype=float) for value in (clearance_m, relative_velocity_mps, target_accel_mps2, lost_time_s)
    )
    closing = np.fmin(v_r, 0.0)
    left_m = x_c + closing * lost_s
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(left_m > 0.0, -a_tv + closing**2 / (2.0 * left_m), np.inf)


def evaluate_fcw(
    subject_accel_mps2: ArrayLike,
    clearance_m: ArrayLike,
    relative_velocity_mps: ArrayLike,
    target_accel_mps2: ArrayLike,
    driver_braking: ArrayLike,
    settings: FcwSettings = FcwSettings(),
) -> FcwBatch:
    """The forward collision warning of many subject vehicles, each with its target vehicle
    (arrays ``(n,)``; the target selection is the caller's, 4.4.3).

    Parameters
    ----------
    subject_accel_mps2
        a_SV, signed (negative while braking), m/s^2.
    clearance_m
        x_c, from the subject's front to the target's rear, m.
    relative_velocity_mps
        v_r = v_TV - v_SV, m/s (the clearance's rate of change).
    target_accel_mps2
        a_TV, signed, m/s^2.
    driver_braking
        Whether the subject's driver brakes (T_resp and T_b are then 0, 4.5.4).
    settings
        The thresholds.
    """
    a_sv, a_tv = np.asarray(subject_accel_mps2, dtype=float), np.asarray(target_accel_mps2, dtype=float)
    x_c, v_r = np.asarray(clearance_m, dtype=float), np.asarray(relative_velocity_mps, dtype=float)
    lost_s = np.where(np.asarray(driver_braking, dtype=bool), 0.0, settings.reaction_time_s + settings.brake_response_s)
    ttc = time_to_collision_s(x_c, v_r)
    ettc = enhanced_time_to_collision_s(x_c, v_r, a_tv - a_sv)
    a_req = required_deceleration_mps2(x_c, v_r, a_tv, lost_s)
    # 4.5.5: no warning while the subject already brakes at the collision threshold, while
    # it is not closing, or while TTC is above the limit.
    may_warn = (-a_sv < settings.collision_a_req_mps2) & (ttc <= settings.max_ttc_s)
    level = np.where(
        may_warn & (a_req >= settings.collision_a_req_mps2),
        2,
        np.where(may_warn & (a_req >= settings.preliminary_a_req_mps2), 1, 0),
    ).astype(np.int8)
    return FcwBatch(level, ttc, ettc, a_req)


def warning_clearance_m(
    closing_mps: ArrayLike, target_accel_mps2: ArrayLike, settings: FcwSettings = FcwSettings(), level: int = 2
) -> np.ndarray:
    """The clearance at which a level comes on at a closing speed ``closing_mps`` (= -v_r > 0)
    and a target acceleration a_TV: formula (4) solved for x_c at the level's threshold,
    x_c = x_r + v_r^2 / (2 (a_thr + a_TV)). The system's set warning distance (4.7.2, 5.4.2); with
    T_resp 0.8 s and 6.67 m/s^2 it is formula (5)."""
    threshold = settings.collision_a_req_mps2 if level == 2 else settings.preliminary_a_req_mps2
    lost_s = settings.reaction_time_s + settings.brake_response_s
    return _clearance_at_m(closing_mps, target_accel_mps2, threshold, lost_s)


def formula_5_clearance_m(closing_mps: ArrayLike, target_accel_mps2: ArrayLike = 0.0) -> np.ndarray:
    """Formula (5), the shortest warning distance a system may have (5.4.1): formula (4) solved for
    x_c with T_resp 0.8 s and a_req 6.67 m/s^2, at a closing speed ``closing_mps`` (= -v_r > 0)."""
    return _clearance_at_m(closing_mps, target_accel_mps2, FORMULA_5_A_REQ_MPS2, MIN_REACTION_TIME_S)


def _clearance_at_m(
    closing_mps: ArrayLike, target_accel_mps2: ArrayLike, a_req_mps2: float, lost_time_s: float
) -> np.ndarray:
    """Formula (4) solved for x_c: the clearance at which a_req reaches ``a_req_mps2``,
    x_c = x_r + v_r^2 / (2 (a_req + a_TV)) with x_r = -v_r ``lost_time_s``."""
    closing, a_tv = np.asarray(closing_mps, dtype=float), np.asarray(target_accel_mps2, dtype=float)
    return closing * lost_time_s + closing**2 / (2.0 * (a_req_mps2 + a_tv))


def next_fcw_states(
    previous: ArrayLike,
    speed_mps: ArrayLike,
    switched_on: ArrayLike,
    measured: ArrayLike,
    settings: FcwSettings = FcwSettings(),
) -> np.ndarray:
    """The system state of many subject vehicles after one update (4.3, Figure 2), as codes into
    :data:`FCW_STATES` (arrays ``(n,)``).

    Off while switched off; fault while the forward sensor gives no valid measurement (4.4.5:
    the driver is told; it clears with the next good one, as CSWS's faults do); else active
    between V_min and V_max, standby outside, widened by the hysteresis delta for a system that
    was active or in fault (so that a short fault does not drop an active system to standby).
    """
    previous = np.asarray(previous, dtype=np.int8)
    speed = np.asarray(speed_mps, dtype=float)
    margin = np.where(previous >= ACTIVE, settings.hysteresis_mps, 0.0)
    inside = (speed >= settings.min_speed_mps - margin) & (speed <= settings.max_speed_mps + margin)
    state = np.where(inside, ACTIVE, STANDBY)
    state = np.where(np.asarray(measured, dtype=bool) & np.isfinite(speed), state, FAULT)
    return np.where(np.asarray(switched_on, dtype=bool), state, OFF).astype(np.int8)
