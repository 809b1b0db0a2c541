"""Real-road tracks in the test procedure: their rows, and their judge, formula (1) on the constructed truth.

The standard's tables judge the warning at a few distances to a curve start. On a road
with clothoids, compound curves and S-bends every point of a curve has its own radius,
V_w and S_w, so these tracks (:mod:`csws.networks.real_roads`) are judged at every step
against every point: level L is **required** at route position s and speed V where some
curve point p ahead of or under the vehicle has V >= V_w(R(p), L) and a distance
s_p - s <= S_w(V, V_w) of formula (1), with R(p) from the authored pieces. A run fails a
level when, at any step,

* it is off although required with the distance shortened by one update's travel plus
  :data:`LATE_EXTRA_M` and the speed above V_w by :data:`SPEED_TOLERANCE_KMH` (late, or
  released too soon), where the point requiring it is more than
  :data:`RELEASE_TOLERANCE_M` ahead (released before the last point that requires it,
  with that tolerance);
* it comes on although not required with the distance lengthened by the latency
  allowance, one update's travel and :data:`EARLY_EXTRA_M`, and the speed lowered by
  :data:`SPEED_TOLERANCE_KMH` (early, or raised where formula (1) never requires it).

A level that stays on after nothing requires it (the release rule, :mod:`csws.warning.release`)
is not judged, but the straight run-out after the last curve must be quiet, as for every
row. Each track runs for every category at two speeds: between the level-1 and level-2
warning speeds of its smallest radius (level 1 due, level 2 never) and
:data:`LEVEL2_EXCESS_KMH` above the level-2 one (both due).
"""

from __future__ import annotations

import json
from functools import cache

import numpy as np

from csws.geometry import curvature_at
from csws.networks import networks_dir
from csws.networks.real_roads import REAL_ROADS_DIR
from csws.standard import DEFAULT_POLICY, Category, Level, formula_1_m, kmh_to_mps, warning_speed
from csws.warning.rules import WarningSettings

from .drive import STABLE_S, Trace, Truth, authored_pieces, track_file
from .judge import RUNOUT_MARGIN_M, STABLE_TOLERANCE_KMH, CheckResult, RunResult
from .rows import Check, Row

__all__ = ["REAL_ROAD_TABLE", "real_road_rows", "judge_real_road_run", "required_levels"]

#: The ``table`` of the real-road rows.
REAL_ROAD_TABLE = 10
#: Late: allowed beyond one update's travel, m.
LATE_EXTRA_M = 0.5
#: Early: allowed beyond the latency allowance and one update's travel, m.
EARLY_EXTRA_M = 1.0
#: A level may go off this far before the last point that requires it, m.
RELEASE_TOLERANCE_M = 2.0
#: Speed margin of both judgements, km/h: four times the speed accuracy of 7.2.2.
SPEED_TOLERANCE_KMH = 0.2
#: The truth's curves are judged at points this far apart, m.
POINT_SPACING_M = 0.1
#: The faster of a track's two speeds lies this far above the level-2 V_w of its smallest radius, km/h.
LEVEL2_EXCESS_KMH = 8.0
#: Steps judged together (memory: steps x points).
CHUNK_STEPS = 256


@cache
def _index() -> tuple[dict, ...]:
    return tuple(json.loads((networks_dir() / REAL_ROADS_DIR / "index.json").read_text("utf-8"))["tracks"])


def real_road_rows() -> list[Row]:
    """Every real-road track for every category at its two speeds."""
    rows = []
    for track in _index():
        radius_m = float(track["min_radius_m"])
        for category in Category:
            level1, level2 = (warning_speed(radius_m, category, level) for level in (1, 2))
            for speed_kmh in (round((level1 + level2) / 2.0, 1), round(level2 + LEVEL2_EXCESS_KMH, 1)):
                rows.append(
                    Row(
                        row_id=f"RR-{track['name'].removeprefix('rr_')}-{category}-V{speed_kmh:g}",
                        table=REAL_ROAD_TABLE,
                        clause="6.1, 6.2.1",
                        category=category,
                        test=None,
                        radius_m=(radius_m,),
                        speed_kmh=speed_kmh,
                        final_speed_kmh=None,
                        decel_trigger_m=None,
                        checks=tuple(
                            Check(1, level, None, f"level {int(level)} where formula (1) requires it")
                            for level in (Level.LEVEL_1, Level.LEVEL_2)
                        ),
                        tracks=(track["name"],),
                    )
                )
    return rows


@cache
def _curve_points(track: str) -> tuple[np.ndarray, np.ndarray]:
    """Route positions and radii of the truth's curve points, every :data:`POINT_SPACING_M`."""
    content = json.loads(track_file(track, ".truth.json").read_text("utf-8"))
    pieces = authored_pieces(content)
    s = np.concatenate(
        [np.append(np.arange(c["start_s"], c["end_s"], POINT_SPACING_M), c["end_s"]) for c in content["curves"]]
    )
    return s, 1.0 / np.abs(curvature_at(pieces, s))


def required_levels(
    row: Row,
    track: str,
    route_s_m: np.ndarray,
    speed_kmh: np.ndarray,
    reach_extra_m: np.ndarray,
    speed_extra_kmh: float,
    min_ahead_m: float,
) -> np.ndarray:
    """Per step, the highest level formula (1) requires at some curve point ``min_ahead_m`` or
    more ahead, its S_w lengthened by ``reach_extra_m`` (per step) and V_w raised by ``speed_extra_kmh``."""
    point_s, radius_m = _curve_points(track)
    levels = np.zeros(len(route_s_m), dtype=np.int8)
    for level in (Level.LEVEL_1, Level.LEVEL_2):
        threshold_kmh = DEFAULT_POLICY.warning_speed_kmh(radius_m, row.category.column, level) + speed_extra_kmh
        for first in range(0, len(route_s_m), CHUNK_STEPS):
            rows = slice(first, first + CHUNK_STEPS)
            ahead_m = point_s[None, :] - route_s_m[rows, None]
            speed = speed_kmh[rows, None]
            reach_m = formula_1_m(kmh_to_mps(speed), kmh_to_mps(threshold_kmh[None, :])) + reach_extra_m[rows, None]
            due = (ahead_m >= min_ahead_m) & (ahead_m <= reach_m) & (speed >= threshold_kmh[None, :])
            levels[rows] = np.where(due.any(axis=1), int(level), levels[rows])
    return levels


def _step_s(trace: Trace) -> float:
    return float(np.median(np.diff(trace.time_s))) if len(trace.time_s) > 1 else 0.0


def judge_real_road_run(row: Row, trace: Trace, track_truth: Truth) -> RunResult:
    """Judge one run of a real-road row: each level against formula (1) at every step."""
    track = track_truth.name
    travel_m = kmh_to_mps(trace.speed_kmh) * _step_s(trace)
    allowance_m = kmh_to_mps(trace.speed_kmh) * (_step_s(trace) + WarningSettings().system_delay_s)
    must = required_levels(
        row,
        track,
        trace.route_s_m,
        trace.speed_kmh,
        -(travel_m + LATE_EXTRA_M),
        SPEED_TOLERANCE_KMH,
        RELEASE_TOLERANCE_M,
    )
    may = required_levels(
        row, track, trace.route_s_m, trace.speed_kmh, allowance_m + travel_m + EARLY_EXTRA_M, -SPEED_TOLERANCE_KMH, 0.0
    )
    exact = required_levels(row, track, trace.route_s_m, trace.speed_kmh, np.zeros(len(travel_m)), 0.0, 0.0)
    checks = tuple(_check(check, trace, track_truth, must, may, exact) for check in row.checks)
    runout = trace.route_s_m > track_truth.curve_end_s_m[-1] + RUNOUT_MARGIN_M
    runout_level = int(trace.level[runout].max(initial=0))
    stable_s = _stable_s(row, trace, may)
    passed = all(c.passed for c in checks) and runout_level == 0 and stable_s >= STABLE_S
    return RunResult(trace.repetition, trace.phase, stable_s, runout_level, checks, passed)


def _check(
    check: Check, trace: Trace, track_truth: Truth, must: np.ndarray, may: np.ndarray, exact: np.ndarray
) -> CheckResult:
    """One level of one run: never off where required, never raised where not."""
    level = int(check.level)
    on = trace.level >= level
    raised = on & ~np.concatenate(([False], on[:-1]))
    missing = np.flatnonzero((must >= level) & ~on)
    wrong = np.flatnonzero(raised & (may < level))
    start_s = track_truth.curve_start_s_m[0]
    onset = np.flatnonzero(on)
    first_exact = np.flatnonzero(exact >= level)
    onset_m = float(start_s - trace.route_s_m[onset[0]]) if onset.size else None
    earlier_m = (
        float(trace.route_s_m[first_exact[0]] - trace.route_s_m[onset[0]]) if onset.size and first_exact.size else None
    )
    reasons = []
    if missing.size:
        where = float(trace.route_s_m[missing[0]] - start_s)
        late = not onset.size or onset[0] > missing[0]
        reasons.append(
            f"level {level} {'not yet on' if late else 'off'} at {where:+.2f} m from the first curve's "
            f"start, where formula (1) requires it"
        )
    if wrong.size:
        where = float(trace.route_s_m[wrong[0]] - start_s)
        reasons.append(
            f"level {level} raised at {where:+.2f} m from the first curve's start, "
            f"where formula (1) does not require it"
        )
    return CheckResult(
        check.label, level, None, not reasons, onset_m, earlier_m, int(trace.level.max(initial=0)), "; ".join(reasons)
    )


def _stable_s(row: Row, trace: Trace, may: np.ndarray) -> float:
    """How long the vehicle held the test speed before any level could be due, s (7.5.1)."""
    due = np.flatnonzero(may > 0)
    last = (due[0] if due.size else len(may)) - 1
    if last < 0:
        return 0.0
    unsteady = np.flatnonzero(np.abs(trace.speed_kmh[: last + 1] - row.speed_kmh) > STABLE_TOLERANCE_KMH)
    start = unsteady[-1] + 1 if unsteady.size else 0
    return float(trace.time_s[last] - trace.time_s[start]) if start <= last else 0.0
