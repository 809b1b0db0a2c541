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
  d_TV the target's deceleration and x_r "the total reduction of the clearance caused by the
  driver's reaction time to the warning" (3.22), read at the end of the reaction
  T = T_resp + T_b with the target's acceleration and the subject's deceleration held through it
  (a positive subject acceleration taken as 0, as Annex A.1 takes the subject at its speed:
  :func:`reaction_accel_mps2`): x_r = -v_r T - (a_TV - a_SV) T^2 / 2, and the closing speed is
  then v_r + (a_TV - a_SV) T, not v_r (:func:`required_deceleration_mps2`). For a steady lead
  and subject that is the standard's x_r = -v_r T, which formula (5) writes as 0.8 v_r; for a
  lead that brakes during the reaction it is what a driver who reacts T after the warning and
  then brakes at a_req needs to just avoid it. Given the subject's speed, where the target stops
  before the speeds meet, a_req is 3.22's value for the stopped target (stopping at its stopping
  point), never above formula (4).

Where GB/T 33577 and the Russian text of ISO 15623 differ, this module follows GB/T 33577:
the factor 2 under the root of (3) and x_c - x_r in (4) (docs/fcw.md).

The warning (4.4.4, 4.5.3-4.5.5): a collision warning when a_req reaches
:attr:`FcwSettings.collision_a_req_mps2`, a preliminary warning (level 1) when it reaches
:attr:`FcwSettings.preliminary_a_req_mps2` (the thresholds and their defaults: :mod:`csws.fcw.settings`).
No warning (4.5.5) while the subject vehicle already decelerates at the collision threshold or
more, or (4.5.5 e) only while no measure shows a threat: TTC and ETTC above
:attr:`FcwSettings.max_ttc_s` and a_req below the preliminary threshold (:func:`warning_level`),
and the preliminary warning above a TTC of 4 s; while the driver brakes, T_resp and T_b are 0
(4.5.4). :func:`evaluate_fcw` keeps, for its callers, the older rule that TTC above the limit alone
suppresses.

Every formula takes Python floats or numpy arrays and gives the same value to the bit either way
(:mod:`csws.fcw.numeric`), so one vehicle's warning (:mod:`csws.fcw.tracker`) runs on floats.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from csws.fcw.numeric import fmax, fmin, isfinite, sqrt, where
from csws.fcw.settings import MIN_REACTION_TIME_S, FcwSettings

__all__ = [
    "FcwBatch",
    "time_to_collision_s",
    "enhanced_time_to_collision_s",
    "required_deceleration_mps2",
    "warning_clearance_m",
    "formula_5_clearance_m",
    "reaction_accel_mps2",
    "warning_level",
    "evaluate_fcw",
]

#: Formula (5), the shortest warning distance (5.4.1): the least reaction time of 4.5.4 and this a_req, m/s^2.
FORMULA_5_A_REQ_MPS2 = 6.67
#: A target braking harder than this stops within a float's time (3.22's stopped-target a_req applies), m/s^2.
STOPPING_MPS2 = 1e-9


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


def _operands(*values: Any) -> tuple[Any, ...]:
    """Floats where every value is a number, else float arrays (the formulas take either)."""
    if all(isinstance(value, float | int) for value in values):
        return tuple(float(value) for value in values)
    return tuple(np.asarray(value, dtype=float) for value in values)


def time_to_collision_s(clearance_m: Any, relative_velocity_mps: Any) -> Any:
    """TTC = -x_c / v_r, formula (2); ``inf`` where the vehicles are not closing (v_r >= 0).

    Floats give a float, anything else an array (the same values to the bit)."""
    with np.errstate(over="ignore"):  # beyond the largest float: inf, as on floats
        return ttc_core(*_operands(clearance_m, relative_velocity_mps))


def ttc_core(x_c: Any, v_r: Any) -> Any:
    """:func:`time_to_collision_s` on floats or float arrays as they are."""
    closing = v_r < 0.0
    return where(closing, -x_c / where(closing, v_r, -1.0), math.inf)


def enhanced_time_to_collision_s(clearance_m: Any, relative_velocity_mps: Any, relative_accel_mps2: Any) -> Any:
    """ETTC, formula (3), with the relative acceleration a_TV - a_SV held: the first time the
    clearance reaches 0; ``inf`` where it never does (the root of (3) is negative or complex).

    Formula (3) is the smaller root of x_c + v_r t + a t^2 / 2 = 0 with a = a_TV - a_SV; it is
    written here in the form that stays exact as a tends to 0, where ETTC tends to TTC:
    (-v_r - root) / a == 2 x_c / (-v_r + root). Floats give a float, anything else an array.
    """
    with np.errstate(over="ignore"):  # beyond the largest float: inf, as on floats
        return ettc_core(*_operands(clearance_m, relative_velocity_mps, relative_accel_mps2))


def ettc_core(x_c: Any, v_r: Any, a: Any) -> Any:
    """:func:`enhanced_time_to_collision_s` on floats or float arrays as they are."""
    discriminant = v_r * v_r - 2.0 * a * x_c
    denominator = sqrt(where(discriminant >= 0.0, discriminant, 0.0)) - v_r
    real = (discriminant >= 0.0) & (denominator > 0.0)
    ettc = where(real, 2.0 * x_c / where(real, denominator, 1.0), math.inf)
    return where(ettc >= 0.0, ettc, math.inf)


def required_deceleration_mps2(
    clearance_m: Any,
    relative_velocity_mps: Any,
    target_accel_mps2: Any,
    lost_time_s: Any,
    subject_accel_mps2: Any = 0.0,
    subject_speed_mps: Any = math.inf,
) -> Any:
    """a_req = d_TV + v_r'^2 / (2 (x_c - x_r)), formula (4) at the end of the driver's reaction and the
    brakes' response (``lost_time_s``, T), with d_TV = -a_TV the target's deceleration; with the subject's
    speed, 3.22's a_req also where the target stops first.

    3.22: x_r is the clearance lost during the reaction; with the accelerations held through it
    (a = a_TV - a_SV, a_SV a deceleration only: a positive one is taken as 0 through the reaction,
    Annex A.1, :func:`reaction_accel_mps2`), x_r = -v_r T - a T^2 / 2, and the closing speed at its
    end is v_r' = v_r + a T (0 where the vehicles stop closing, and T is cut where that happens
    first). On a steady lead this is the standard's x_r = -v_r T. ``inf`` where the reaction uses
    up the clearance.

    3.22 defines a_req as the least deceleration that brings the subject to the target's speed
    without a collision. Formula (4) is that value while the target still moves when the speeds
    meet; it holds d_TV for ever, so for a target that brakes to a stop before then (a lead braking
    gently far ahead) it asks for at least d_TV however far ahead the target stops. Given
    ``subject_speed_mps`` (finite), where the target stops first the value is 3.22's for a stopped
    target: the subject, after T with its deceleration held, stops at the target's stopping
    point, a_req = v_SV'^2 / (2 (x_c + v_TV^2 / (2 d_TV) - s_SV)) (:func:`a_req_core`). Without it
    (``inf``), formula (4) alone. Floats give a float, anything else an array.
    """
    with np.errstate(over="ignore"):  # beyond the largest float: inf, as on floats
        return a_req_core(
            *_operands(
                clearance_m,
                relative_velocity_mps,
                target_accel_mps2,
                subject_accel_mps2,
                lost_time_s,
                subject_speed_mps,
            )
        )


def a_req_core(x_c: Any, v_r: Any, a_tv: Any, a_sv: Any, lost_s: Any, v_sv: Any = math.inf) -> Any:
    """:func:`required_deceleration_mps2` on floats or float arrays as they are (``v_sv`` inf: formula (4) alone)."""
    a_sv = reaction_accel_mps2(a_sv)
    a_f = _formula_4(x_c, v_r, a_tv, a_sv, lost_s)
    target_brakes = a_tv < -STOPPING_MPS2
    if target_brakes is False:  # one vehicle's target that does not brake: formula (4) alone, nothing to discard
        return a_f
    stops = target_brakes & isfinite(v_sv) & isfinite(a_f) & (v_sv + v_r >= 0.0)
    if stops is False:  # nor where 3.22's stopped-target value cannot apply (no speed given, no room, no stop)
        return a_f
    a_s, binds = _stopped_target_a_req(x_c, v_r, where(stops, a_tv, -1.0), a_sv, lost_s, where(stops, v_sv, 0.0))
    return where(stops & binds, where(isfinite(a_s), fmin(a_s, a_f), a_s), a_f)


def reaction_accel_mps2(subject_accel_mps2: Any) -> Any:
    """The subject's acceleration held through the driver's reaction: its deceleration, a positive acceleration as 0.

    GB/T 33577 Annex A (A.1, normative; ISO 15623 A.1 the same) takes the subject at its speed through the
    reaction, D = v_SV T + ..., and formula (5) (4.5.6) x_r = 0.8 v_r: a subject that accelerates is not taken
    to keep accelerating. A deceleration is held: 4.4.4 makes the warning depend on the vehicles' possible
    braking decelerations and 4.5.5 a on the subject's own, and a subject already slowing does not speed up
    while its driver reacts (docs/fcw.md, "The subject's acceleration through the reaction").
    """
    return fmin(subject_accel_mps2, 0.0)


def _formula_4(x_c: Any, v_r: Any, a_tv: Any, a_sv: Any, lost_s: Any) -> Any:
    """Formula (4) with a_TV and ``a_sv`` held through the reaction (:func:`required_deceleration_mps2`)."""
    a_rel = a_tv - a_sv
    stops_closing = (v_r < 0.0) & (a_rel > 0.0) & (-v_r < a_rel * lost_s)
    reaction_s = where(stops_closing, -v_r / where(stops_closing, a_rel, 1.0), lost_s)
    closing = fmin(v_r + a_rel * reaction_s, 0.0)
    left_m = x_c + v_r * reaction_s + a_rel * reaction_s * reaction_s / 2.0
    room = left_m > 0.0
    return where(room, -a_tv + closing * closing / (2.0 * where(room, left_m, 1.0)), math.inf)


def _stopped_target_a_req(x_c: Any, v_r: Any, a_tv: Any, a_sv: Any, lost_s: Any, v_sv: Any) -> tuple[Any, Any]:
    """3.22 for a braking target (a_TV < 0) that stops before the speeds meet: the deceleration that stops
    the subject, after ``lost_s`` with a_SV (<= 0) held (cut where it stops), at the target's stopping point
    (``inf`` where the subject is past that point by then: contact is certain); and whether that value
    binds: the target stops first (at or before the subject braking so), or there is no room.

    While the target moves the closing speed changes linearly; once it stops the closing speed is the
    subject's own speed, so if the subject still moves then, the clearance falls until the subject stops
    and the stopping point binds (the reaction's part is formula (4)'s, finite: no contact in it).
    """
    v_tv = fmax(v_sv + v_r, 0.0)
    target_stop_m = v_tv * v_tv / (-2.0 * a_tv)
    target_stop_s = v_tv / -a_tv
    subject_stops = (a_sv < 0.0) & (v_sv + a_sv * lost_s < 0.0)
    held_s = where(subject_stops, v_sv / where(subject_stops, -a_sv, 1.0), lost_s)
    subject_m = v_sv * held_s + a_sv * held_s * held_s / 2.0
    speed_after = fmax(v_sv + a_sv * held_s, 0.0)
    room_m = x_c + target_stop_m - subject_m
    room = room_m > 0.0
    a_s = where(room, speed_after * speed_after / (2.0 * where(room, room_m, 1.0)), math.inf)
    return a_s, (room_m <= 0.0) | (where(room, a_s, 0.0) * (target_stop_s - held_s) <= speed_after)


def warning_level(
    subject_accel_mps2: Any,
    ttc_s: Any,
    ettc_s: Any,
    a_req_mps2: Any,
    settings: FcwSettings,
    suppress_above_max_ttc: bool = False,
) -> Any:
    """The level a target requires (0 none, 1 preliminary, 2 collision; 4.5.3) after the suppressions of 4.5.5.

    a_req at the collision threshold gives 2, at the preliminary one 1. 4.5.5 a: none while the
    subject decelerates at the collision threshold or more. 4.5.5 e: suppressed only where no
    measure shows a threat, TTC and ETTC above ``max_ttc_s`` and a_req below the preliminary
    threshold; with ``suppress_above_max_ttc`` (the rule :func:`evaluate_fcw` keeps for its
    callers), TTC above it alone suppresses. The preliminary warning (optional, 4.5.1; its threshold
    the designer's, 4.5.3) is suppressed while TTC is above ``max_ttc_s`` (4.5.5 e): it comes only
    while the subject closes on the target within that time; a target that brakes ahead of a
    subject at its own speed (TTC infinite) gets the collision warning once a_req reaches its
    threshold. Floats give an int, arrays an int8 array.
    """
    may_warn = -subject_accel_mps2 < settings.collision_a_req_mps2
    if suppress_above_max_ttc:
        may_warn = may_warn & (ttc_s <= settings.max_ttc_s)
    else:
        no_threat = (
            (ttc_s > settings.max_ttc_s)
            & (ettc_s > settings.max_ttc_s)
            & (a_req_mps2 < settings.preliminary_a_req_mps2)
        )
        may_warn = where(no_threat, False, may_warn)
    preliminary = may_warn & (ttc_s <= settings.max_ttc_s) & (a_req_mps2 >= settings.preliminary_a_req_mps2)
    level = where(may_warn & (a_req_mps2 >= settings.collision_a_req_mps2), 2, where(preliminary, 1, 0))
    return level if isinstance(level, int) else np.asarray(level, dtype=np.int8)


def evaluate_fcw(
    subject_accel_mps2: ArrayLike,
    clearance_m: ArrayLike,
    relative_velocity_mps: ArrayLike,
    target_accel_mps2: ArrayLike,
    driver_braking: ArrayLike,
    settings: FcwSettings = FcwSettings(),
    suppress_above_max_ttc: bool = True,
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
    suppress_above_max_ttc
        4.5.5 e as these callers had it, TTC above the limit alone suppresses; False: only where no
        measure shows a threat (:func:`warning_level`, the rule of :mod:`csws.fcw.tracker`).
    """
    a_sv, a_tv = np.asarray(subject_accel_mps2, dtype=float), np.asarray(target_accel_mps2, dtype=float)
    x_c, v_r = np.asarray(clearance_m, dtype=float), np.asarray(relative_velocity_mps, dtype=float)
    lost_s = np.where(np.asarray(driver_braking, dtype=bool), 0.0, settings.reaction_time_s + settings.brake_response_s)
    ttc = time_to_collision_s(x_c, v_r)
    ettc = enhanced_time_to_collision_s(x_c, v_r, a_tv - a_sv)
    a_req = required_deceleration_mps2(x_c, v_r, a_tv, lost_s, a_sv)
    level = warning_level(a_sv, ttc, ettc, a_req, settings, suppress_above_max_ttc)
    return FcwBatch(np.asarray(level, dtype=np.int8), ttc, ettc, a_req)


def warning_clearance_m(
    closing_mps: ArrayLike, target_accel_mps2: ArrayLike, settings: FcwSettings = FcwSettings(), level: int = 2
) -> np.ndarray:
    """The clearance at which a level comes on at a closing speed ``closing_mps`` (= -v_r > 0), a
    target acceleration a_TV and a steady subject: formula (4) as :func:`required_deceleration_mps2`
    reads it, solved for x_c at the level's threshold, x_c = c T - a_TV T^2 / 2 + c'^2 / (2 (a_thr + a_TV))
    with c' = c - a_TV T the closing speed at the end of the reaction (where the vehicles still close
    then). The system's set warning distance (4.7.2, 5.4.2)."""
    threshold = settings.collision_a_req_mps2 if level == 2 else settings.preliminary_a_req_mps2
    lost_s = settings.reaction_time_s + settings.brake_response_s
    closing, a_tv = np.asarray(closing_mps, dtype=float), np.asarray(target_accel_mps2, dtype=float)
    closing_after = closing - a_tv * lost_s
    return closing * lost_s - a_tv * lost_s**2 / 2.0 + closing_after**2 / (2.0 * (threshold + a_tv))


def formula_5_clearance_m(closing_mps: ArrayLike, target_accel_mps2: ArrayLike = 0.0) -> np.ndarray:
    """Formula (5), the shortest warning distance a system may have (5.4.1), as the standard writes it:
    x = v_r^2 / (2 (6.67 - d_TV)) + 0.8 v_r at a closing speed ``closing_mps`` (= -v_r > 0)."""
    closing, a_tv = np.asarray(closing_mps, dtype=float), np.asarray(target_accel_mps2, dtype=float)
    return closing * MIN_REACTION_TIME_S + closing**2 / (2.0 * (FORMULA_5_A_REQ_MPS2 + a_tv))
