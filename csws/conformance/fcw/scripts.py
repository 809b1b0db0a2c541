"""What the vehicles of an FCW row do, step by step: the test procedures of GB/T 33577 5.4-5.5 as phases.

A script is told each step's true state and the system's level and target, and answers the
speed commands of that step (``setSpeed``: the targets' ``decel`` is 0.3 g, the subject's
``accel`` 1.5 m/s^2 and ``decel`` 4 m/s^2). :attr:`Script.phase` is recorded with every step,
so the judge knows what happened when; :attr:`Script.done` ends the run.
"""

from __future__ import annotations

from csws.fcw.physics import time_to_collision_s

from .rows import STABLE_S, START_CLEARANCE_M, FcwRow

__all__ = ["Script", "script_of", "FIRST_WARNING", "TARGET_BRAKES"]

#: The clearance under which a run is over whatever the system said: the vehicles (almost) touch, m.
CONTACT_M = 0.5
#: The adjacent-lane vehicle brakes to this speed, m/s ("明显低于", well below the others').
ADJACENT_SLOW_MPS = 5.0
#: 5.5.2.2: the subject closes at this speed on the leads, then falls back at ``FALL_BACK_MPS``
#: to a clearance of at least ``FALL_BACK_M`` (headway over T_max = 1.5 s at 20 m/s).
CLOSING_MPS, FALL_BACK_MPS, FALL_BACK_M = 25.0, 15.0, 35.0
#: The subject has passed the adjacent vehicle when its rear is this far beyond the other's front, m.
PASSED_M = 10.0
#: Phases every script shares: the first warning of the two-lead test, and the target braking.
FIRST_WARNING, TARGET_BRAKES = 2, 4


class Script:
    """The phases of one run; subclasses say what each step commands.

    Attributes
    ----------
    phase
        0 while every vehicle holds its speed; then the script's own phases.
    done
        Whether the run is over.
    """

    def __init__(self, row: FcwRow) -> None:
        self.row = row
        self.phase = 0
        self.done = False
        self.since_s: float | None = None

    def step(self, time_s: float, truth: dict[str, float], level: int, target_id: str | None) -> dict[str, float]:
        """The speed commands of this step (m/s by vehicle id)."""
        if self.since_s is None:
            self.since_s = time_s
        if truth["clearance_m"] < CONTACT_M:
            self.done = True
            return {}
        return self.commands(time_s, truth, level, target_id)

    def commands(self, time_s: float, truth: dict[str, float], level: int, target_id: str | None) -> dict[str, float]:
        raise NotImplementedError

    def _next(self, phase: int, time_s: float) -> None:
        self.phase, self.since_s = phase, time_s

    def _held(self, time_s: float, seconds: float = STABLE_S) -> bool:
        """Whether the current phase has lasted ``seconds`` (STABLE_S by default)."""
        return self.since_s is not None and time_s - self.since_s >= seconds - 1e-9


class Approach(Script):
    """Constant speeds (phase 1 from START_CLEARANCE_M); with ``brakes``, the target brakes at
    0.3 g after STABLE_S (phase TARGET_BRAKES). Over at the warning, or when the true TTC is below
    90 % of the least allowed (5.5.2.1: the test ends there)."""

    def __init__(self, row: FcwRow, brakes: bool) -> None:
        super().__init__(row)
        self.brakes = brakes

    def commands(self, time_s: float, truth: dict[str, float], level: int, target_id: str | None) -> dict[str, float]:
        commands: dict[str, float] = {}
        if self.phase == 0 and self.brakes and self._held(time_s):
            self._next(TARGET_BRAKES, time_s)
            commands["tv"] = 0.0
        elif self.phase == 0 and not self.brakes and truth["clearance_m"] <= START_CLEARANCE_M:
            self._next(1, time_s)
        ttc_s = float(time_to_collision_s(truth["clearance_m"], -truth["closing_mps"]))
        late = self.row.least_ttc_s is not None and ttc_s < 0.9 * self.row.least_ttc_s
        self.done = level >= self.row.level or late
        return commands


class TwoLeads(Script):
    """5.5.2.2: close on the leads until the collision warning (phase FIRST_WARNING), fall back
    (3), follow for STABLE_S once the warning is off, then the nearer lead brakes (TARGET_BRAKES)
    until the warning comes again."""

    def commands(self, time_s: float, truth: dict[str, float], level: int, target_id: str | None) -> dict[str, float]:
        if self.phase == 0 and self._held(time_s):
            self._next(1, time_s)
            return {"sv": CLOSING_MPS}
        if self.phase == 1 and level >= 2:
            self._next(FIRST_WARNING, time_s)
            return {"sv": FALL_BACK_MPS}
        if self.phase == FIRST_WARNING and truth["clearance_m"] >= FALL_BACK_M:
            self._next(3, time_s)
            return {"sv": self.row.actor("sv").speed_mps}
        if self.phase == 3 and (level > 0 or not self._held(time_s)):
            self.since_s = time_s if level > 0 else self.since_s
            return {}
        if self.phase == 3:
            self._next(TARGET_BRAKES, time_s)
            return {"tv": 0.0}
        self.done = self.phase == TARGET_BRAKES and level >= 2
        return {}


class Adjacent(Script):
    """5.5.3: the adjacent vehicle brakes to ADJACENT_SLOW_MPS (phase 1) and is passed; two
    seconds later (phase 3) the target brakes at 0.3 g (TARGET_BRAKES) until the warning."""

    def commands(self, time_s: float, truth: dict[str, float], level: int, target_id: str | None) -> dict[str, float]:
        if self.phase == 0 and self._held(time_s):
            self._next(1, time_s)
            return {"adj": ADJACENT_SLOW_MPS}
        lengths_m = 12.0 + 4.5 + PASSED_M
        if self.phase == 1 and truth["adjacent_ahead_m"] < -lengths_m:
            self._next(3, time_s)
        elif self.phase == 3 and self._held(time_s, 2.0):
            self._next(TARGET_BRAKES, time_s)
            return {"tv": 0.0}
        self.done = self.phase == TARGET_BRAKES and level >= self.row.level
        return {}


def script_of(row: FcwRow) -> Script:
    """A fresh script for one run of ``row``."""
    if row.script in ("approach", "lead_brakes"):
        return Approach(row, brakes=row.script == "lead_brakes")
    return {"two_leads": TwoLeads, "adjacent": Adjacent}[row.script](row)
