"""The least-demanding forward collision warning a conforming system may give (GB/T 33577-2017 4.5.3-4.5.6).

GB/T 33577 asks the collision warning once the required deceleration a_req (3.22, formula (4))
reaches a threshold of at most 0.68 g (4.5.3), computed with a driver's reaction time of at least
0.8 s (4.5.4; 0 while the driver brakes), and its warning-distance test (5.4.1) checks the warning
distance against formula (5), that same a_req of 6.67 m/s^2 after 0.8 s for a steady subject.
4.5.5 lists where a system must or may stay silent. :func:`standard_requires_warning` is the latest
warning any conforming system may give: those least figures, and every suppression 4.5.5 allows.
Any conforming system warns at least there, so on given traffic its warnings are a floor (the
traffic benchmark, ``benchmarks/fcw_traffic.py``, counts how many of them turn out unneeded).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from csws.fcw.physics import FORMULA_5_A_REQ_MPS2, required_deceleration_mps2
from csws.fcw.settings import HIGHEST_MIN_SPEED_MPS, LOWEST_MAX_SPEED_MPS, MIN_REACTION_TIME_S

__all__ = ["STANDARD_A_REQ_MPS2", "SUPPRESS_ABOVE_TTC_S", "Lead", "warning_due", "standard_requires_warning"]

#: 4.5.3, formula (5): the highest collision threshold a conforming system may have (0.68 g), m/s^2.
STANDARD_A_REQ_MPS2 = FORMULA_5_A_REQ_MPS2
#: 4.5.5 e: above this TTC a warning may be suppressed, s.
SUPPRESS_ABOVE_TTC_S = 4.0


@dataclass(frozen=True)
class Lead:
    """A subject vehicle and the vehicle it follows in its lane, in one instant (``leader_id`` None without one).

    Attributes
    ----------
    leader_id
        The vehicle followed, or None.
    clearance_m
        x_c, the subject's front to the leader's rear, m.
    subject_mps, lead_mps
        The two speeds, m/s.
    subject_accel_mps2, lead_accel_mps2
        The two accelerations, signed (negative braking), m/s^2.
    braking
        The subject's driver brakes (4.5.4).
    """

    leader_id: str | None
    clearance_m: float
    subject_mps: float
    lead_mps: float = 0.0
    subject_accel_mps2: float = 0.0
    lead_accel_mps2: float = 0.0
    braking: bool = False

    @property
    def ttc_s(self) -> float:
        """TTC, formula (2); ``inf`` without a leader or while not closing."""
        closing_mps = self.subject_mps - self.lead_mps
        if self.leader_id is None or closing_mps <= 0.0:
            return math.inf
        return max(self.clearance_m, 0.0) / closing_mps


def warning_due(
    lead: Lead,
    reaction_time_s: float = MIN_REACTION_TIME_S,
    threshold_mps2: float = STANDARD_A_REQ_MPS2,
    min_speed_mps: float = HIGHEST_MIN_SPEED_MPS,
    silent_while_braking: bool = False,
) -> bool:
    """4.5.3-4.5.5: whether a warning on a_req alone, at ``threshold_mps2`` after ``reaction_time_s``, is due now.

    a_req (3.22, :func:`csws.fcw.physics.required_deceleration_mps2`) after the reaction (0 while the driver
    brakes, 4.5.4), holding only a deceleration of the subject through it (Annex A.1 takes the subject at its
    speed: :func:`csws.fcw.physics.reaction_accel_mps2`), at or above
    the threshold; for a steady subject and lead at the standard's
    least figures that is x_c at or below formula (5)'s distance. Not due where 4.5.5 lets a system be silent:
    below ``min_speed_mps`` or above V_max 27.8 m/s (4.3.3, 4.5.5 g), TTC above 4 s (4.5.5 e), the subject
    decelerating at the threshold (4.5.5 a), and with ``silent_while_braking`` while the driver brakes (4.5.5 d).
    """
    if lead.leader_id is None or not min_speed_mps <= lead.subject_mps <= LOWEST_MAX_SPEED_MPS:
        return False
    if lead.ttc_s > SUPPRESS_ABOVE_TTC_S or -lead.subject_accel_mps2 >= threshold_mps2:
        return False
    if silent_while_braking and lead.braking:
        return False
    a_req_mps2 = required_deceleration_mps2(
        max(lead.clearance_m, 0.0),
        lead.lead_mps - lead.subject_mps,
        lead.lead_accel_mps2,
        0.0 if lead.braking else reaction_time_s,
        lead.subject_accel_mps2,
        lead.subject_mps,
    )
    return bool(a_req_mps2 >= threshold_mps2)


def standard_requires_warning(lead: Lead, silent_while_braking: bool = False) -> bool:
    """4.5.3-4.5.6: whether the least-demanding conforming system must give the collision warning now:
    :func:`warning_due` with the standard's least figures, T_resp 0.8 s (4.5.4), the threshold 0.68 g of
    formula (5) (4.5.3) and V_min 11.2 m/s, the highest 4.3.3 allows (with ``silent_while_braking``, also
    silent while the driver brakes, 4.5.5 d)."""
    return warning_due(lead, silent_while_braking=silent_while_braking)
