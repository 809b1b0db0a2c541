"""The forward collision warning's settings: its thresholds and the bounds GB/T 33577-2017 (ISO 15623) sets on them.

The standard caps the collision warning's threshold at 0.68 g (4.5.3) with a driver's reaction
time T_resp of at least 0.8 s (4.5.4); warning only at those limits is too late for its own tests
(a lead braking at 0.3 g from 30 m at 20 m/s is warned at a TTC of 1.96 s, 2.4 s is required), so
the defaults of :class:`FcwSettings` are a commercial vehicle's: T_resp 1.2 s and 0.5 g, the mean
hard braking of commercial vehicles in Annex A (5.3 m/s^2) rounded down. The system is active
between V_min and V_max (4.3.3), V_max by the vehicle's category (:data:`MAX_SPEED_BY_CATEGORY_MPS`).
The formulas that read these settings are :mod:`csws.fcw.physics`, the system state :mod:`csws.fcw.state`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from csws.standard import Category

__all__ = [
    "STANDARD_GRAVITY_MPS2",
    "MAX_COLLISION_A_REQ_MPS2",
    "MIN_REACTION_TIME_S",
    "PRELIMINARY_SHARE",
    "EARLY_PRELIMINARY_A_REQ_MPS2",
    "HIGHEST_MIN_SPEED_MPS",
    "LOWEST_MAX_SPEED_MPS",
    "MAX_SPEED_BY_CATEGORY_MPS",
    "FcwSettings",
]

STANDARD_GRAVITY_MPS2 = 9.80665
#: 4.5.3: the collision warning's a_req threshold may not exceed 0.68 g.
MAX_COLLISION_A_REQ_MPS2 = 0.68 * STANDARD_GRAVITY_MPS2
#: 4.5.4: the driver's reaction time to a warning is at least 0.8 s.
MIN_REACTION_TIME_S = 0.8
#: 4.5.3: the preliminary warning's threshold, unless set, as a share of the collision's (0.45 g of 0.5 g;
#: :attr:`FcwSettings.preliminary_a_req_mps2` gives the evidence).
PRELIMINARY_SHARE = 0.9
#: The preliminary threshold before the traffic run showed its false warnings (0.3 g, m/s^2): a cue 0.068 s per
#: m/s of closing speed before the collision warning on a steady approach, at 0.90 false warnings per
#: vehicle-hour in SUMO's traffic; a fleet that wants that earlier cue sets it (``preliminary_a_req_mps2``).
EARLY_PRELIMINARY_A_REQ_MPS2 = 0.3 * STANDARD_GRAVITY_MPS2
#: 4.3.3: the system works from at most 11.2 m/s up to at least 27.8 m/s.
HIGHEST_MIN_SPEED_MPS, LOWEST_MAX_SPEED_MPS = 11.2, 27.8
#: 4.3.3: V_max is at least 27.8 m/s *or the highest speed the vehicle can reach*; by category (GB/T 15089),
#: the highest speed such vehicles reach, never below 27.8 m/s. M1: 250 km/h, where most fast cars are
#: electronically limited; M2 and M3: the buses' speed limiter, 100 km/h (EU 92/6/EEC as amended by
#: 2002/85/EC), which rounds to 27.8 m/s; N and O: the trucks' limiter, 90 km/h, held up to 27.8 m/s,
#: whose 2.8 m/s over the limiter cover a truck rolling faster downhill. A van (N1) without a limiter
#: or any vehicle faster than its category's value sets its own V_max.
MAX_SPEED_BY_CATEGORY_MPS = {
    Category.M1: 250.0 / 3.6,
    Category.M2: LOWEST_MAX_SPEED_MPS,
    Category.M3: LOWEST_MAX_SPEED_MPS,
    Category.N: LOWEST_MAX_SPEED_MPS,
    Category.O: LOWEST_MAX_SPEED_MPS,
}


@dataclass(frozen=True)
class FcwSettings:
    """The thresholds of the forward collision warning.

    Attributes
    ----------
    collision_a_req_mps2
        a_req at which the collision warning comes on (4.5.3: at most 0.68 g).
    preliminary_a_req_mps2
        a_req at which the preliminary warning comes on (4.5.3: lower than the collision's; the warning is
        optional, 4.5.1, its threshold the designer's). Unless set (NaN), :data:`PRELIMINARY_SHARE` of the
        collision threshold, 0.45 g at its 0.5 g, so that a fleet that moves its collision warning moves the
        preliminary one with it. 0.45 g because in SUMO's mixed traffic (``python -m benchmarks.fcw_traffic``,
        17.85 equipped vehicle-hours) every false warning at 0.3 g began as a preliminary one (0.90 per
        vehicle-hour; a queue's last car approached at 10-15 m/s by drivers who brake at about 2.2 m/s^2), and
        0.45 g takes the object FCW to 0.056 with the subject at its speed through the reaction (the same rule on
        SUMO's true leader from 0.896 to 0.056; at 0.4 g 0.784; docs/fcw.md), while every run
        of the FCW conformance suite gives the same figure as at 0.3 g (its rows judge the collision warning;
        GB/T 33577 5.5.3.1 asks for the preliminary one, not its timing). On a steady approach at a closing
        speed c it comes c (1/a_pre - 1/a_col) / 2 before the collision warning (0.23 s at 20 m/s), where
        4.5.5 e lets it: T_resp + c / (2 a_pre) <= 4 s. :data:`EARLY_PRELIMINARY_A_REQ_MPS2` is the earlier
        0.3 g, a fleet's setting.
    reaction_time_s
        T_resp, the driver's reaction time to a warning (4.5.4: at least 0.8 s).
    brake_response_s
        T_b, the brake system's response time (4.5.4: chosen by the designer).
    max_ttc_s
        4.5.5 e: the TTC (and ETTC) above which a warning may be suppressed (4.0 s); only while a_req
        is also below the preliminary threshold (:func:`warning_level`).
    min_speed_mps, max_speed_mps
        V_min and V_max, the subject speeds the system is active between (4.3.3: V_min at most
        11.2 m/s, V_max at least 27.8 m/s or the highest speed the vehicle reaches). The default is
        a commercial vehicle's (a truck's or bus's speed limiter); :meth:`for_category` takes the
        category's (:data:`MAX_SPEED_BY_CATEGORY_MPS`).
    hysteresis_mps
        delta of Figure 2: an active system goes to standby only this far outside [V_min, V_max].
    path_half_width_m
        An object is in the path while its centre is at most this far from the predicted path
        (half a 3.5 m lane: Table 3's detection width at d_max is the lane width).
    object_half_length_m
        The in-path test takes an object's centre this far beyond its rear (a car's half length):
        the sensor gives the rear's range and the centre's lateral position, and on a curve the two
        points lie on different headings (on R 125 m, 40 m ahead, 0.7 m apart across the path).
    range_m
        d_max, the farthest object assessed ahead, m.
    level_hold_s
        A level, once on, stays on this long after the thresholds stop requiring it (one noisy
        frame does not switch it off and on); never lower than what they require now.
    """

    collision_a_req_mps2: float = 0.5 * STANDARD_GRAVITY_MPS2
    preliminary_a_req_mps2: float = math.nan
    reaction_time_s: float = 1.2
    brake_response_s: float = 0.0
    max_ttc_s: float = 4.0
    min_speed_mps: float = 10.0
    max_speed_mps: float = LOWEST_MAX_SPEED_MPS
    hysteresis_mps: float = 1.0
    path_half_width_m: float = 1.75
    object_half_length_m: float = 2.25
    range_m: float = 200.0
    level_hold_s: float = 0.4

    @classmethod
    def for_category(cls, category: str | Category, **changes: Any) -> FcwSettings:
        """The settings of a vehicle of ``category`` (4.3.3: V_max from :data:`MAX_SPEED_BY_CATEGORY_MPS`),
        with ``changes`` (any field, e.g. the vehicle's own ``max_speed_mps``) applied over them."""
        return cls(**{"max_speed_mps": MAX_SPEED_BY_CATEGORY_MPS[Category.parse(category)], **changes})

    def __post_init__(self) -> None:
        if math.isnan(self.preliminary_a_req_mps2):
            object.__setattr__(self, "preliminary_a_req_mps2", PRELIMINARY_SHARE * self.collision_a_req_mps2)
        if not 0.0 < self.collision_a_req_mps2 <= MAX_COLLISION_A_REQ_MPS2:
            raise ValueError(f"the collision threshold must be in (0, 0.68 g], got {self.collision_a_req_mps2!r} m/s^2")
        if not 0.0 < self.preliminary_a_req_mps2 < self.collision_a_req_mps2:
            raise ValueError(
                f"the preliminary threshold ({self.preliminary_a_req_mps2!r} m/s^2) must be positive and below "
                f"the collision threshold ({self.collision_a_req_mps2!r} m/s^2)"
            )
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
        if not (self.path_half_width_m > 0.0 and self.range_m > 0.0):
            raise ValueError("the path half-width and the range must be positive")
        if not (self.level_hold_s >= 0.0 and self.object_half_length_m >= 0.0):
            raise ValueError("the level hold and the object half length must be >= 0")
