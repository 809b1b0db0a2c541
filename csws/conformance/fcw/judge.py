"""Judging the FCW runs against the tests' criteria, with true values from SUMO and the track's truth.

=================  =======================================================================
row                a run passes when
=================  =======================================================================
5.5.2.1, IVISTA    the warning came (for ``tv``) at a true TTC of at least the test's
                   (2.1, 2.4, 2.0 s), before the TTC fell under 90 % of it
5.4.1              the clearance at the collision warning is at least formula (5)'s
5.4.2              the warning distance D = d - V (t1 - t0) (d the clearance at t0, 100 m)
                   is within +-2 m or +-15 % of the set one (4.7.2); a group passes when at
                   least 70 % of its runs do
5.5.2.2            both collision warnings came, and every warning was for the nearer lead
5.5.3.1, 5.5.3.2   no warning before the target braked (while the adjacent vehicle was slowed
                   down and passed), then the warning for ``tv``; the subject less than 0.5 m
                   off the target's axis
NHTSA              as 5.5.2.1 (2.1, 2.4, 2.0 s); a group passes when 5 of its 7 runs do
Euro NCAP CCR      the warning (for ``tv``) came no later than the latest useful warning
                   (:mod:`csws.conformance.fcw.avoidance`: a driver reacting 0.8 s after it
                   and braking at 0.68 g avoids contact), from the true clearance, speeds and
                   target acceleration at the warning; below V_min no warning is required
=================  =======================================================================

Every run also keeps the subject (and a target at constant speed) within the row's speed
tolerance while the vehicles hold their speeds. The standards ask one run per test (IVISTA
5.1, without a pre-test); every repetition at every step length must pass, except 5.4.2's 70 %.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from csws.fcw.settings import STANDARD_GRAVITY_MPS2

from .avoidance import AVOIDANCE_BRAKING_MPS2, AVOIDANCE_REACTION_S, latest_useful_warning_s
from .drive import Trace
from .rows import REFERENCE_CLEARANCE_M, FcwRow
from .scripts import TARGET_BRAKES

__all__ = ["ACCURACY_SHARE", "FcwRunResult", "judge_fcw_run", "warning_margin_s", "group_passes", "criterion"]

#: 5.4.2: the share of runs whose warning distance must be within 4.7.2's accuracy.
ACCURACY_SHARE = 0.7
#: 4.7.2: +-2 m or +-15 %.
ACCURACY_M, ACCURACY_FRACTION = 2.0, 0.15
#: 5.5.3.1: the subject's axis less than this off the target's, m.
MAX_LATERAL_M = 0.5


@dataclass(frozen=True)
class FcwRunResult:
    """How one run did.

    Attributes
    ----------
    repetition, phase
        Which run.
    figure
        What the criterion measures: TTC at the warning (s), the clearance at it (5.4.1, m), the
        warning distance D (5.4.2, m), the margin to the latest useful warning (CCR, s); None
        where the criterion is not a number.
    passed
        Whether the run passed.
    reason
        Why not; empty when it passed.
    """

    repetition: int
    phase: float
    figure: float | None
    passed: bool
    reason: str


def criterion(row: FcwRow) -> str:
    """The row's pass criterion, in a few words."""
    if not row.warning_required:
        return "subject below V_min: the system is in standby (4.3.3), no warning required"
    if row.avoidance:
        return (
            f"warned early enough that a driver reacting {AVOIDANCE_REACTION_S:g} s after it and braking at "
            f"{AVOIDANCE_BRAKING_MPS2 / STANDARD_GRAVITY_MPS2:g} g avoids contact (margin >= 0 s)"
        )
    if row.least_ttc_s is not None:
        runs = f" in >= {row.least_passing_runs} of {row.repetitions} runs" if row.least_passing_runs else ""
        return f"TTC at the warning >= {row.least_ttc_s:g} s{runs}"
    if row.least_clearance_m is not None:
        return f"clearance at the warning >= {row.least_clearance_m:.1f} m (formula (5))"
    if row.set_distance_m is not None:
        return f"D within +-2 m / 15 % of {row.set_distance_m:.1f} m in >= 70 % of runs"
    if row.script == "two_leads":
        return "both warnings, each for the nearer lead"
    return f"no warning passing the adjacent vehicle, then level {row.level} for the target"


def _speed_problem(row: FcwRow, trace: Trace, held: np.ndarray) -> str:
    """Whether the subject (and a moving target) kept its test speed where ``held``."""
    for name, speeds, actor in (
        ("subject", trace.subject_mps, row.actor("sv")),
        ("target", trace.target_mps, row.actor("tv")),
    ):
        if name == "target" and (actor.speed_mps == 0.0 or row.script != "approach"):
            continue
        off = np.abs(speeds[held] - actor.speed_mps)
        if off.size and off.max() > row.speed_tolerance_mps + 1e-9:
            return f"the {name}'s speed was {off.max():.2f} m/s off its test speed"
    return ""


def _first(mask: np.ndarray) -> int | None:
    found = np.flatnonzero(mask)
    return int(found[0]) if found.size else None


def judge_fcw_run(row: FcwRow, trace: Trace) -> FcwRunResult:
    """Judge one run of a row."""
    warned = trace.level >= row.level
    reasons: list[str] = []
    figure: float | None = None
    if row.script in ("approach", "lead_brakes"):
        figure, reasons = _approach(row, trace, warned)
    elif row.script == "two_leads":
        reasons = _two_leads(trace)
    else:
        reasons = _adjacent(row, trace, warned)
    held = trace.phase_index < TARGET_BRAKES if row.script != "two_leads" else np.zeros(len(warned), dtype=bool)
    if row.script == "approach":
        held = np.ones(len(warned), dtype=bool)
    speed = _speed_problem(row, trace, held)
    if speed:
        reasons.append(speed)
    return FcwRunResult(trace.repetition, trace.phase, figure, not reasons, "; ".join(reasons))


def _approach(row: FcwRow, trace: Trace, warned: np.ndarray) -> tuple[float | None, list[str]]:
    """A warning at a constant-speed or braking lead: TTC, clearance or warning distance."""
    first = _first(warned)
    if first is None and not row.warning_required:
        return None, []
    if first is None:
        return None, [f"no level {row.level} before the true TTC was {trace.ttc_s[-1]:.2f} s"]
    reasons = [] if trace.target[first] == "tv" else [f"the warning was for {trace.target[first] or 'no target'}"]
    if row.avoidance:
        margin_s = warning_margin_s(trace, first)
        if margin_s < 0.0 and row.warning_required:
            reasons.append(f"warned {-margin_s:.2f} s after the latest useful warning")
        return margin_s, reasons if row.warning_required else []
    if row.least_ttc_s is not None:
        ttc_s = float(trace.ttc_s[first])
        if ttc_s < row.least_ttc_s:
            reasons.append(f"warned at a TTC of {ttc_s:.2f} s")
        return ttc_s, reasons
    if row.least_clearance_m is not None:
        clearance_m = float(trace.clearance_m[first])
        if clearance_m < row.least_clearance_m:
            reasons.append(f"warned at {clearance_m:.2f} m")
        return clearance_m, reasons
    set_distance_m = row.set_distance_m
    if set_distance_m is None:
        raise ValueError(f"row {row.row_id} names no criterion for its warning")
    reference = _first(trace.clearance_m <= REFERENCE_CLEARANCE_M)
    if reference is None or reference > first:
        return None, reasons + ["warned before the reference clearance"]
    distance_m = float(
        trace.clearance_m[reference] - row.actor("sv").speed_mps * (trace.time_s[first] - trace.time_s[reference])
    )
    if abs(distance_m - set_distance_m) > max(ACCURACY_M, ACCURACY_FRACTION * set_distance_m):
        reasons.append(f"warning distance {distance_m:.2f} m, set {set_distance_m:.2f} m")
    return distance_m, reasons


def warning_margin_s(trace: Trace, index: int) -> float:
    """How long before the latest useful warning the step ``index`` is, s (negative: after it), from the
    true clearance, speeds and target acceleration of that step (:func:`latest_useful_warning_s`)."""
    return latest_useful_warning_s(
        float(trace.clearance_m[index]),
        float(trace.subject_mps[index]),
        float(trace.target_mps[index]),
        float(trace.target_accel_mps2[index]),
    )


def _two_leads(trace: Trace) -> list[str]:
    """5.5.2.2: both collision warnings, every warning for the nearer lead."""
    reasons = []
    collision = trace.level >= 2
    if not (collision & (trace.phase_index == 1)).any():
        reasons.append("no collision warning while closing on the leads")
    if not (collision & (trace.phase_index == TARGET_BRAKES)).any():
        reasons.append("no collision warning when the nearer lead braked")
    others = {target for target, level in zip(trace.target, trace.level, strict=False) if level and target != "tv"}
    if others:
        reasons.append(f"warned for {', '.join(sorted(others))}")
    return reasons


def _adjacent(row: FcwRow, trace: Trace, warned: np.ndarray) -> list[str]:
    """5.5.3: quiet while the adjacent vehicle is slowed down and passed, then the warning for the target."""
    reasons = []
    before = trace.phase_index < TARGET_BRAKES
    if (trace.level[before] > 0).any():
        where = trace.adjacent_ahead_m[_first(before & (trace.level > 0))]
        reasons.append(f"a warning before the target braked, the adjacent vehicle {where:+.1f} m ahead")
    if not (trace.phase_index == 3).any():
        reasons.append("the subject never passed the adjacent vehicle")
    first = _first(warned & ~before)
    if first is None:
        reasons.append(f"no level {row.level} after the target braked")
    elif trace.target[first] != "tv":
        reasons.append(f"the warning was for {trace.target[first] or 'no target'}")
    if np.abs(trace.lateral_m).max() >= MAX_LATERAL_M:
        reasons.append("the subject was 0.5 m or more off the target's axis")
    return reasons


def group_passes(row: FcwRow, runs: Sequence[FcwRunResult]) -> bool:
    """Every run passed; for 5.4.2 at least 70 % of them; for NHTSA at least ``least_passing_runs`` (5 of 7)."""
    if row.least_passing_runs is not None:
        return sum(run.passed for run in runs) >= row.least_passing_runs
    if row.set_distance_m is not None:
        return bool(runs) and sum(run.passed for run in runs) >= math.ceil(ACCURACY_SHARE * len(runs) - 1e-9)
    return all(run.passed for run in runs)
