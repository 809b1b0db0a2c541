"""The latest useful warning: how late a warning may come for a driver who reacts and brakes to avoid contact.

The physical criterion of the Euro NCAP car-to-car rear rows (Euro NCAP's own FCW criterion is a
table of warning times; this suite judges by the run's own trajectories instead). At an instant
(t = 0) the subject drives at ``subject_mps`` with ``clearance_m`` to the target's rear, the target
at ``target_mps`` with a constant ``target_accel_mps2`` (braking targets stop and stay stopped; a
target's acceleration forward is not counted on). A warning at t = tau makes the driver brake at
``braking_mps2`` from t_b = tau + ``reaction_s``; until then the subject holds its speed (as the
tests' subject does; the clearance lost in the reaction is formula (4)'s x_r). The latest useful
warning is the largest tau for which the clearance never falls below zero.

With a = max(0, -target_accel_mps2), w0 = v_SV - v_TV and D = braking_mps2 (D > a), the closing
speed grows until t_b and shrinks after it, so the least clearance comes when the speeds are equal,
either

* while the target still moves: x_c - w0 t_b - a t_b^2 / 2 - (w0 + a t_b)^2 / (2 (D - a)) >= 0,
  that is D a t_b^2 + 2 D w0 t_b - (2 (D - a) x_c - w0^2) <= 0, whose larger root is the latest
  t_b (t_b = x_c / w0 - w0 / (2 D) for a = 0); or
* when the subject stops behind a target already stopped: x_c + v_TV^2 / (2 a) >= v_SV t_b + v_SV^2 / (2 D).

The first holds while the speeds meet before the target stops: t_m = (w0 + D t_b) / (D - a) <= v_TV / a.
"""

from __future__ import annotations

import math

from csws.fcw.settings import MIN_REACTION_TIME_S, STANDARD_GRAVITY_MPS2

__all__ = ["AVOIDANCE_REACTION_S", "AVOIDANCE_BRAKING_MPS2", "latest_useful_warning_s"]

#: The driver reacts this long after the warning (4.5.4's least reaction time), s.
AVOIDANCE_REACTION_S = MIN_REACTION_TIME_S
#: And brakes at this deceleration (4.5.3's largest collision threshold, 0.68 g), m/s^2.
AVOIDANCE_BRAKING_MPS2 = 0.68 * STANDARD_GRAVITY_MPS2


def latest_useful_warning_s(
    clearance_m: float,
    subject_mps: float,
    target_mps: float,
    target_accel_mps2: float,
    reaction_s: float = AVOIDANCE_REACTION_S,
    braking_mps2: float = AVOIDANCE_BRAKING_MPS2,
) -> float:
    """The latest useful warning time after this instant, s: a driver warned then, reacting ``reaction_s`` later
    and braking at ``braking_mps2``, just avoids contact (negative: already too late; ``inf``: never needed).

    Parameters
    ----------
    clearance_m
        Clearance from the subject's front to the target's rear now, m.
    subject_mps, target_mps
        Their speeds now, m/s.
    target_accel_mps2
        The target's acceleration, m/s^2 (negative while it brakes).
    """
    target_mps = max(target_mps, 0.0)
    decel_mps2 = max(-target_accel_mps2, 0.0) if target_mps > 0.0 else 0.0
    if decel_mps2 >= braking_mps2:
        raise ValueError("the driver's braking must exceed the target's deceleration")
    closing_mps = subject_mps - target_mps
    if decel_mps2 == 0.0 and target_mps > 0.0 and closing_mps <= 0.0:
        return math.inf
    stopped_bound_s = _behind_stopped_target_s(clearance_m, subject_mps, target_mps, decel_mps2, braking_mps2)
    if target_mps == 0.0 or subject_mps <= 0.0:
        return stopped_bound_s - reaction_s
    moving_bound_s = _speeds_meet_s(clearance_m, closing_mps, decel_mps2, braking_mps2)
    if decel_mps2 == 0.0:
        return moving_bound_s - reaction_s
    # the speeds meet after the target has stopped from this brake start on
    regime_change_s = ((braking_mps2 - decel_mps2) * target_mps / decel_mps2 - closing_mps) / braking_mps2
    brake_start_s = stopped_bound_s if stopped_bound_s >= regime_change_s else moving_bound_s
    return brake_start_s - reaction_s


def _behind_stopped_target_s(
    clearance_m: float, subject_mps: float, target_mps: float, decel_mps2: float, braking_mps2: float
) -> float:
    """The latest brake start at which the subject stops at or behind where the target stops (or stands), s."""
    target_stop_m = target_mps**2 / (2.0 * decel_mps2) if decel_mps2 > 0.0 else 0.0
    if subject_mps <= 0.0:
        return math.inf
    return (clearance_m + target_stop_m - subject_mps**2 / (2.0 * braking_mps2)) / subject_mps


def _speeds_meet_s(clearance_m: float, closing_mps: float, decel_mps2: float, braking_mps2: float) -> float:
    """The latest brake start at which the clearance is still >= 0 when the speeds meet with the target moving, s."""
    reserve = 2.0 * (braking_mps2 - decel_mps2) * clearance_m - closing_mps**2
    if decel_mps2 == 0.0:
        return reserve / (2.0 * braking_mps2 * closing_mps)
    discriminant = (braking_mps2 * closing_mps) ** 2 + braking_mps2 * decel_mps2 * reserve
    if discriminant < 0.0:
        return -math.inf
    return (-braking_mps2 * closing_mps + math.sqrt(discriminant)) / (braking_mps2 * decel_mps2)
