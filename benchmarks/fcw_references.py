"""Reference warning rules on SUMO's true leader, and how a warning onset is judged false, for the FCW traffic run.

A warning onset (level 0 -> >= 1) is judged by what follows it within :data:`FOLLOW_S`: false where the
vehicle's true TTC never fell below :data:`NEAR_TTC_S` and it did not collide (:func:`settle`), with the
situation it came in (:func:`situation_of`).

The reference systems (:data:`REFERENCES`, each a :class:`Reference` per run) warn on a_req alone
(:func:`csws.fcw.conforming.warning_due`) to SUMO's true leader, with perfect perception, their level held
as the design holds its own. The first two are the least-demanding conforming warning of GB/T 33577-2017
(4.5.3-4.5.6: 0.8 s, 0.68 g, V_min 11.2 m/s, every suppression 4.5.5 allows; the second also silent while
the driver brakes, 4.5.5 d): the floor of any conforming system. The others say which of the design's
choices (:class:`csws.fcw.settings.FcwSettings`) its false warnings come from: its collision warning alone,
its preliminary warning, and preliminary warnings at the earlier 0.3 g (the default until the traffic run
showed its false warnings), after shorter reaction times or at thresholds between. Every rule, as the design,
holds only a deceleration of the subject through the reaction (:func:`csws.fcw.physics.reaction_accel_mps2`).
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

from csws.fcw.conforming import STANDARD_A_REQ_MPS2, Lead, warning_due
from csws.fcw.settings import (
    EARLY_PRELIMINARY_A_REQ_MPS2,
    HIGHEST_MIN_SPEED_MPS,
    MIN_REACTION_TIME_S,
    STANDARD_GRAVITY_MPS2,
    FcwSettings,
)

__all__ = ["FOLLOW_S", "NEAR_TTC_S", "DESIGN", "REFERENCES", "Pending", "Reference", "settle", "situation_of"]

#: A warning is judged by what follows it within this time, s.
FOLLOW_S = 4.0
#: A warning is false if the true TTC stays above this in the following FOLLOW_S, s.
NEAR_TTC_S = 1.5
#: The design's settings (a commercial vehicle's, :class:`FcwSettings`).
DESIGN = FcwSettings()
#: A rule: a reaction time (s), a threshold (m/s^2), a least speed (m/s), silent or not while the driver brakes
#: (:func:`warning_due`).
Rule = tuple[float, float, float, bool]


def _design_rule(reaction_s: float, threshold_mps2: float) -> Rule:
    """A rule at the design's least speed, warning while the driver brakes."""
    return (reaction_s, threshold_mps2, DESIGN.min_speed_mps, False)


def _g(threshold_mps2: float) -> str:
    """A threshold in g, as the rules' names give it."""
    return f"{threshold_mps2 / STANDARD_GRAVITY_MPS2:g} g"


#: The reference systems by name (the floor first: ``benchmarks.__main__`` reports it).
REFERENCES: dict[str, Rule] = {
    "standard's latest warning (0.8 s, 0.68 g)": (
        MIN_REACTION_TIME_S,
        STANDARD_A_REQ_MPS2,
        HIGHEST_MIN_SPEED_MPS,
        False,
    ),
    "standard's latest warning, silent while braking": (
        MIN_REACTION_TIME_S,
        STANDARD_A_REQ_MPS2,
        HIGHEST_MIN_SPEED_MPS,
        True,
    ),
    **{
        f"design's {what} ({DESIGN.reaction_time_s:g} s, {_g(threshold_mps2)})": (
            _design_rule(DESIGN.reaction_time_s, threshold_mps2)
        )
        for what, threshold_mps2 in (
            ("collision warning alone", DESIGN.collision_a_req_mps2),
            ("preliminary warning", DESIGN.preliminary_a_req_mps2),
        )
    },
    **{
        f"preliminary warning at {reaction_s:g} s, {_g(EARLY_PRELIMINARY_A_REQ_MPS2)}": (
            _design_rule(reaction_s, EARLY_PRELIMINARY_A_REQ_MPS2)
        )
        for reaction_s in (DESIGN.reaction_time_s, 1.0, MIN_REACTION_TIME_S)
    },
    **{
        f"preliminary warning at {DESIGN.reaction_time_s:g} s, {g:g} g": _design_rule(
            DESIGN.reaction_time_s, g * STANDARD_GRAVITY_MPS2
        )
        for g in (0.35, 0.4)
    },
}


@dataclass
class Pending:
    """A warning onset waiting for what follows it (``required_after_s``: when, after it, the least-demanding
    conforming warning was first due, None while it was not)."""

    vehicle_id: str
    time_s: float
    situation: str
    near: bool = False
    required_after_s: float | None = None


def settle(pending: list[Pending], now_s: float) -> tuple[list[Pending], list[Pending]]:
    """The onsets still waiting for FOLLOW_S to pass, and those judged false (none near in FOLLOW_S)."""
    waiting = [onset for onset in pending if now_s - onset.time_s < FOLLOW_S]
    judged = [onset for onset in pending if now_s - onset.time_s >= FOLLOW_S]
    return waiting, [onset for onset in judged if not onset.near]


def situation_of(sumo: Any, vehicle_id: str, target_id: str | None, leader_id: str | None, yaw_turning: bool) -> str:
    """Where a warning came: its target stopped or moving, the subject's leader or another vehicle, turning."""
    if target_id is None:
        return "no target"
    vehicle = sumo.vehicle
    parts = ["target stopped" if vehicle.getSpeed(target_id) < 0.5 else "target moving"]
    if target_id != leader_id:
        parts.append("not the leader (other lane or road)")
    elif vehicle.getRoadID(target_id) != vehicle.getRoadID(vehicle_id):
        parts.append("leader across a junction")
    if yaw_turning:
        parts.append("subject turning")
    return ", ".join(parts)


@dataclass
class Reference:
    """A reference system's warnings in one run (a rule of :data:`REFERENCES`), held as the design holds its level."""

    rule: Rule
    hold_s: float = DESIGN.level_hold_s
    required_at: dict[str, float] = field(default_factory=dict)
    on: set[str] = field(default_factory=set)
    pending: list[Pending] = field(default_factory=list)
    onsets: int = 0
    false_warnings: int = 0
    false_situations: Counter[str] = field(default_factory=Counter)

    def step(self, sumo: Any, now_s: float, vehicle_id: str, lead: Lead, turning: bool) -> None:
        """One vehicle's step: whether its rule's warning is due (held); an onset waits to be judged."""
        if warning_due(lead, *self.rule):
            self.required_at[vehicle_id] = now_s
        on = now_s - self.required_at.get(vehicle_id, -math.inf) <= self.hold_s + 1e-9
        if on and vehicle_id not in self.on:
            self.onsets += 1
            where = situation_of(sumo, vehicle_id, lead.leader_id, lead.leader_id, turning)
            self.pending.append(Pending(vehicle_id, now_s, where))
        if on:
            self.on.add(vehicle_id)
        else:
            self.on.discard(vehicle_id)

    def settle(self, now_s: float) -> None:
        """Judge the onsets whose FOLLOW_S has passed."""
        self.pending, false = settle(self.pending, now_s)
        self.false_warnings += len(false)
        self.false_situations.update(onset.situation for onset in false)
