"""Clause 6 and the release rule for one vehicle, in plain floats.

:func:`csws.warning.rules.evaluate_batch` and :mod:`csws.warning.release` judge the CPOIs of a fleet in
numpy arrays. One vehicle has a few CPOIs (one or two on most roads), and on arrays that
small numpy's cost per call is most of the work: an on-board unit's query, or the service's
answer to one vehicle, would wait on it. :func:`judge_one` applies the same rules with the
same floating-point operations in the same order to Python floats, so its answer and the
memory it leaves are the batch's to the bit (``tests/test_onewarning.py`` holds them
against each other on every kind of CPOI and memory).
"""

from __future__ import annotations

from collections.abc import Sequence

from csws.standard import Category, Level, formula_1_m, kmh_to_mps
from csws.warning.release import NOT_HELD, HeldWarning, Rule, within_hold
from csws.warning.rules import (
    CurvaturePointOfInterest,
    CurveWarning,
    HmiHint,
    PathKind,
    Trigger,
    WarningSettings,
    column_index,
    no_warning,
)

__all__ = ["CpoiPoint", "evaluate", "judge_one"]

#: A CPOI as :meth:`csws.ahead.horizon.PathAhead.cpoi_points` gives it: curve id, part index,
#: distance S (m), radius (m), passed.
CpoiPoint = tuple[str, int, float, float, bool]
_LEVELS = (Level.NONE, Level.LEVEL_1, Level.LEVEL_2)


def evaluate(
    speed_kmh: float,
    category: str | Category,
    cpois: Sequence[CurvaturePointOfInterest],
    path_kind: PathKind = PathKind.ROUTE,
    settings: WarningSettings = WarningSettings(),
) -> CurveWarning:
    """The warning for one vehicle at speed ``speed_kmh`` with ``cpois`` ahead (clause 6), without memory.

    Returns a :class:`CurveWarning` listing every triggering CPOI; below every warning
    speed, or with no CPOI ahead (a straight), the level is 0.
    """
    points = [(p.curve_id, int(p.part_index), float(p.distance_m), float(p.radius_m), False) for p in cpois]
    return judge_one(float(speed_kmh), column_index(category), points, path_kind, NOT_HELD, None, settings)[0]


def judge_one(
    speed_kmh: float,
    column_index: int,
    points: Sequence[CpoiPoint],
    path_kind: PathKind,
    held: HeldWarning,
    now_s: float | None,
    settings: WarningSettings,
) -> tuple[CurveWarning, HeldWarning]:
    """The warning of one vehicle and what it keeps for the release rule.

    Parameters
    ----------
    speed_kmh, column_index
        The vehicle's speed V, km/h, and its column of Tables 1-2.
    points
        Its CPOIs, nearest first.
    path_kind
        Where the CPOIs were found.
    held, now_s
        Its memory from the last update, and this update's timestamp (None where unknown).
    settings
        Policy, latency and release rule.

    Returns
    -------
    tuple
        The :class:`CurveWarning` (as :meth:`csws.warning.rules.BatchWarnings.vehicle_warning` gives
        it) and the vehicle's memory after this update (:func:`csws.warning.release.next_memories`).
    """
    speed_mps = kmh_to_mps(speed_kmh)
    allowance_m = speed_mps * settings.latency_s
    speeds = [settings.policy.warning_speeds_one_kmh(radius_m, column_index) for _, _, _, radius_m, _ in points]
    distances = [[_warning_distance_m(speed_mps, kmh_to_mps(v), settings.g_mps2) for v in pair] for pair in speeds]
    # 6.1: V >= V_w and S <= S_w (+ the distance driven during the latency); nothing where passed.
    rules = [
        [
            Rule.REQUIRED if speed_kmh >= v and point[2] <= s + allowance_m and not point[4] else Rule.OFF
            for v, s in zip(pair, sws, strict=False)
        ]
        for point, pair, sws in zip(points, speeds, distances, strict=False)
    ]
    if held.is_on:
        _apply_release(rules, speed_kmh, speed_mps, allowance_m, points, speeds, held, now_s, settings)
    warning = _warning(rules, points, speeds, distances, path_kind)
    return warning, _next_memory(rules, points, held, now_s)


def _warning_distance_m(speed_mps: float, warning_speed_mps: float, g_mps2: float) -> float:
    """:func:`csws.standard.warning_distance_m` of one speed: formula (1), 0 below V_w."""
    return formula_1_m(speed_mps, warning_speed_mps, g_mps2) if speed_mps >= warning_speed_mps else 0.0


def _apply_release(
    rules: list[list[int]],
    speed_kmh: float,
    speed_mps: float,
    allowance_m: float,
    points: Sequence[CpoiPoint],
    speeds: list[tuple[float, float]],
    held: HeldWarning,
    now_s: float | None,
    settings: WarningSettings,
) -> None:
    """Release rules 1 (margin) and 2 (hold) of :mod:`csws.warning.release` on ``rules``, in place."""
    named = [[(point[0], point[1]) in level_points for level_points in held.points] for point in points]
    for point, pair, point_rules, point_named in zip(points, speeds, rules, named, strict=False):
        for level in (0, 1):
            if point_rules[level] == Rule.OFF and point_named[level]:
                lowered_kmh = max(pair[level] - settings.release_margin_kmh, 0.0)
                lowered_sw_m = _warning_distance_m(speed_mps, kmh_to_mps(lowered_kmh), settings.g_mps2)
                if speed_kmh >= lowered_kmh and point[2] <= lowered_sw_m + allowance_m:
                    point_rules[level] = Rule.MARGIN
    if any(rule for point_rules in rules for rule in point_rules):
        return
    holding = [within_hold(kept_at_s, now_s, settings.release_hold_s) for kept_at_s in held.kept_at_s]
    for point_rules, point_named in zip(rules, named, strict=False):
        for level in (0, 1):
            if holding[level] and point_named[level]:
                point_rules[level] = Rule.HOLD


def _warning(
    rules: list[list[int]],
    points: Sequence[CpoiPoint],
    speeds: list[tuple[float, float]],
    distances: list[list[float]],
    path_kind: PathKind,
) -> CurveWarning:
    """The warning: each triggering CPOI at its highest level; the target the highest level,
    then the nearest (3.12, 6.2.1: level 2 has priority)."""
    triggers = []
    for point, pair, sws, (level_1, level_2) in zip(points, speeds, distances, rules, strict=False):
        level = 2 if level_2 else 1 if level_1 else 0
        if level:
            shown = 1 if level_2 else 0
            triggers.append(
                Trigger(
                    point[0],
                    point[1],
                    point[2],
                    point[3],
                    _LEVELS[level],
                    pair[shown],
                    sws[shown],
                    (level_2 if level_2 else level_1) >= Rule.MARGIN,
                )
            )
    if not triggers:
        return no_warning(path_kind)
    target = min(triggers, key=lambda t: (-t.level, t.distance_m))
    return CurveWarning(
        target.level,
        target,
        tuple(sorted(triggers, key=lambda t: t.distance_m)),
        path_kind,
        HmiHint.for_level(target.level),
    )


def _next_memory(
    rules: list[list[int]], points: Sequence[CpoiPoint], held: HeldWarning, now_s: float | None
) -> HeldWarning:
    """What the release rule keeps after this update (:func:`csws.warning.release.next_memories` of one vehicle)."""
    if not any(rule for point_rules in rules for rule in point_rules):
        return NOT_HELD
    points_on, kept_at_s = [], []
    for level in (0, 1):
        here = [point_rules[level] for point_rules in rules]
        points_on.append(frozenset((point[0], point[1]) for point, rule in zip(points, here, strict=False) if rule))
        if Rule.REQUIRED in here or Rule.MARGIN in here:
            kept_at_s.append(now_s)
        else:
            kept_at_s.append(held.kept_at_s[level] if Rule.HOLD in here else None)
    return HeldWarning((points_on[0], points_on[1]), (kept_at_s[0], kept_at_s[1]))
