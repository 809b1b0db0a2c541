"""Judging the runs of the test procedure: 7.5.2.x.2 and 7.5.3.x.2 per run, three in a row per row, 7.6 overall.

A run passes a check when the required level (or a higher one) is on at the first step
where the vehicle's true distance to the named curve is below the table's S_w, and stays
on at every later step until the vehicle reaches that curve. The one exception is the
braking of Table 7: once the vehicle is no longer at the test speed, the warning is due
only while clause 6.1's condition holds for its true state, V >= V_w and a distance
within formula (1)'s S_w at its current speed (each with a margin for the measurement
noise and the map): a driver who brakes as warned makes the warning go off.

A run also passes only when the vehicle was stable at the test speed for at least 3 s
before the first warning distance (7.5.1) and no warning at all was given on the straight
run-out after the last curve. A negative check passes when its level was never given.

A row passes when, on each of its tracks at each step length, three consecutive runs pass
(7.5.2.1.2 and the others); the system passes the test when every row of Tables 5 to 9
passes (7.6).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from csws.standard import kmh_to_mps, warning_distance_m

from .drive import STABLE_S, Trace, Truth
from .rows import Check, Row

__all__ = [
    "CONSECUTIVE_PASSES",
    "RUNOUT_MARGIN_M",
    "HOLD_MARGIN_KMH",
    "HOLD_MARGIN_M",
    "CheckResult",
    "RunResult",
    "judge_run",
    "consecutive_passes",
]

#: Runs in a row that must pass (7.5.2.1.2 and the other evaluation clauses).
CONSECUTIVE_PASSES = 3
#: The straight run-out begins this far after the end of the last curve, m: the curve's end
#: as the system's map sees it may lie up to 1 m off, and the position noise is 0.2 m.
RUNOUT_MARGIN_M = 5.0
#: While braking (Table 7) a warning must stay on while the true speed is at least its warning
#: speed plus this margin, km/h (ten times the speed accuracy of 7.2.2).
HOLD_MARGIN_KMH = 0.5
#: While braking (Table 7) a warning must stay on while the true distance is at least this much
#: within formula (1)'s S_w at the current speed, m (the map's curve start may lie 1 m off).
HOLD_MARGIN_M = 1.0
#: Speeds within this of the test speed count as stable (7.5.1), km/h.
STABLE_TOLERANCE_KMH = 0.01


@dataclass(frozen=True)
class CheckResult:
    """How one run did on one check.

    Attributes
    ----------
    label, level, table_distance_m
        The check.
    passed
        Whether the run passed it.
    onset_distance_m
        Distance to the named curve at which the warning (this level or higher) came on, m:
        the start of the warning that was on when the table's S_w was crossed, else the first
        warning after it; None when there was none. For a negative check, None.
    earlier_m
        ``onset_distance_m - table_distance_m``: how much earlier than the table, m.
    max_level
        The highest level given during the run (for negative checks).
    reason
        Why the run failed the check; empty when it passed.
    """

    label: str
    level: int
    table_distance_m: float | None
    passed: bool
    onset_distance_m: float | None
    earlier_m: float | None
    max_level: int
    reason: str


@dataclass(frozen=True)
class RunResult:
    """How one run did.

    Attributes
    ----------
    repetition, phase
        Which run.
    stable_s
        How long the vehicle held the test speed before the first warning distance, s (7.5.1).
    runout_level
        The highest level given on the straight run-out (0 is right).
    checks
        One result per check of the row.
    passed
        Whether the run passed: stable, every check, and a quiet run-out.
    """

    repetition: int
    phase: float
    stable_s: float
    runout_level: int
    checks: tuple[CheckResult, ...]
    passed: bool


def _positive(row: Row, check: Check, trace: Trace, distance_m: np.ndarray) -> CheckResult:
    """A check that a warning of ``check.level`` is on from the table's S_w to the curve."""
    table_distance_m = check.table_distance_m
    if table_distance_m is None:
        raise ValueError(f"{check.label} is a negative check: it has no S_w to be on from")
    on = trace.level >= check.level
    below = np.flatnonzero(distance_m < table_distance_m)
    max_level = int(trace.level.max(initial=0))
    if below.size == 0:
        return CheckResult(
            check.label,
            int(check.level),
            table_distance_m,
            False,
            None,
            None,
            max_level,
            "the run never came within the table's S_w",
        )
    first = below[0]
    window = np.flatnonzero((np.arange(on.size) >= first) & (distance_m > 0))
    due = window[(window == first) | _still_due(row, check, trace.speed_kmh[window], distance_m[window])]
    missing = due[~on[due]]
    onset = _onset_index(on, first, window)
    onset_m = None if onset is None else float(distance_m[onset])
    earlier_m = None if onset_m is None else onset_m - table_distance_m
    if missing.size == 0:
        reason = ""
    elif missing[0] == first:
        reason = f"level {int(check.level)} was not on at {distance_m[first]:.2f} m (table S_w {table_distance_m:g} m)"
    else:
        reason = f"level {int(check.level)} went off at {distance_m[missing[0]]:.2f} m before the curve"
    return CheckResult(
        check.label, int(check.level), table_distance_m, missing.size == 0, onset_m, earlier_m, max_level, reason
    )


def _still_due(row: Row, check: Check, speed_kmh: np.ndarray, distance_m: np.ndarray) -> np.ndarray:
    """Where the warning is due after the table's S_w: at the test speed always, else while 6.1 holds."""
    warning_speed_kmh = row.warning_speed_kmh(check)
    at_test_speed = np.abs(speed_kmh - row.speed_kmh) <= STABLE_TOLERANCE_KMH
    formula_m = warning_distance_m(kmh_to_mps(speed_kmh), kmh_to_mps(warning_speed_kmh))
    holds = (speed_kmh >= warning_speed_kmh + HOLD_MARGIN_KMH) & (distance_m <= formula_m - HOLD_MARGIN_M)
    return at_test_speed | holds


def _onset_index(on: np.ndarray, first: int, window: np.ndarray) -> int | None:
    """Where the warning that was on at ``first`` began; else the first warning after ``first`` in ``window``."""
    if on[first]:
        off_before = np.flatnonzero(~on[:first])
        return int(off_before[-1] + 1) if off_before.size else 0
    later = window[on[window]]
    return int(later[0]) if later.size else None


def _negative(check: Check, trace: Trace) -> CheckResult:
    """A check that no warning of ``check.level`` is ever given."""
    max_level = int(trace.level.max(initial=0))
    passed = max_level < check.level
    reason = "" if passed else f"level {max_level} was given"
    return CheckResult(check.label, int(check.level), None, passed, None, None, max_level, reason)


def _stable_s(row: Row, trace: Trace, track_truth: Truth) -> float:
    """How long the vehicle held the test speed before the first warning distance (or the curve), s (7.5.1)."""
    reach_m = [track_truth.curve_start_s_m[c.curve_number - 1] - (c.table_distance_m or 0.0) for c in row.checks]
    before = np.flatnonzero(trace.route_s_m < min(reach_m))
    if before.size == 0:
        return 0.0
    last = before[-1]
    unsteady = np.flatnonzero(np.abs(trace.speed_kmh[: last + 1] - row.speed_kmh) > STABLE_TOLERANCE_KMH)
    start = unsteady[-1] + 1 if unsteady.size else 0
    return float(trace.time_s[last] - trace.time_s[start]) if start <= last else 0.0


def judge_run(row: Row, trace: Trace, track_truth: Truth) -> RunResult:
    """Judge one run of a row against the track's truth."""
    checks = []
    for check in row.checks:
        distance_m = track_truth.curve_start_s_m[check.curve_number - 1] - trace.route_s_m
        checks.append(_negative(check, trace) if check.negative else _positive(row, check, trace, distance_m))
    runout = trace.route_s_m > track_truth.curve_end_s_m[-1] + RUNOUT_MARGIN_M
    runout_level = int(trace.level[runout].max(initial=0))
    stable_s = _stable_s(row, trace, track_truth)
    passed = all(c.passed for c in checks) and runout_level == 0 and stable_s >= STABLE_S
    return RunResult(trace.repetition, trace.phase, stable_s, runout_level, tuple(checks), passed)


def consecutive_passes(runs: Sequence[RunResult], needed: int = CONSECUTIVE_PASSES) -> bool:
    """Whether ``needed`` consecutive runs (in repetition order) passed."""
    streak = 0
    for run in sorted(runs, key=lambda r: r.repetition):
        streak = streak + 1 if run.passed else 0
        if streak >= needed:
            return True
    return False
