"""Applies clause 6 and the release rule to one vehicle in plain floats, giving the batch's answer to the bit.

:func:`csws.warning.rules.evaluate_batch` and :mod:`csws.warning.release` judge the CPOIs of a fleet in
numpy arrays. One vehicle has a few CPOIs (one or two on most roads), and on arrays that
small numpy's cost per call is most of the work: an on-board unit's query, or the service's
answer to one vehicle, would wait on it. :func:`judge_one` applies the same rules to Python
floats through the same functions, each of which takes floats or arrays: the table look-up
(:meth:`csws.warning.settings.WarningSettings.warning_speeds_one_kmh`), formula (1)
(:func:`csws.standard.warning_distance_m`), the latency allowance, 6.1's condition
(:func:`csws.warning.rules.meets_clause_6_1`), the margin (:func:`csws.warning.rules.meets_margin`)
and the memory (:func:`csws.warning.release.vehicle_memory`). Its answer and the memory it leaves
are so the batch's to the bit (``tests/test_onewarning.py`` holds them against each other on
random settings, CPOIs and memories).
"""

from __future__ import annotations

from collections.abc import Sequence

from csws.standard import Category, Level, kmh_to_mps, warning_distance_m
from csws.warning.release import (
    NOT_HELD,
    HeldWarning,
    PointKey,
    Rule,
    named_points,
    recalled_points,
    vehicle_memory,
    within_hold,
)
from csws.warning.rules import (
    CurvaturePointOfInterest,
    CurveWarning,
    HmiHint,
    PathKind,
    Trigger,
    WarningSettings,
    by_distance,
    column_index,
    meets_clause_6_1,
    meets_margin,
    no_warning,
)

__all__ = ["CpoiPoint", "evaluate", "judge_one"]

#: A CPOI as :meth:`csws.ahead.horizon.PathAhead.cpoi_points` gives it: curve id, part index,
#: distance S (m), radius (m), passed.
CpoiPoint = tuple[str, int, float, float, bool]


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
    update_period_s: float | None = None,
    age_s: float = 0.0,
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
    update_period_s, age_s
        The vehicle's update period (learnt, :func:`csws.warning.latency.update_period_s`; None for
        the configured one) and its fix's age when answered, s: they lengthen the latency allowance
        and the period the hold (:meth:`csws.warning.rules.WarningSettings.hold_s`).

    The CPOIs the release rule recalls from ``held`` (rule 4, :func:`csws.warning.release.recalled_points`)
    are judged after ``points``, as the batch judges them after the vehicle's own.

    Returns
    -------
    tuple
        The :class:`CurveWarning` (as :meth:`csws.warning.rules.BatchWarnings.vehicle_warning` gives
        it) and the vehicle's memory after this update (:func:`csws.warning.release.next_memories`).
    """
    if not points and not held.is_on:  # a straight ahead, nothing held: nothing to judge, nothing kept
        return no_warning(path_kind), NOT_HELD
    speed_mps = kmh_to_mps(speed_kmh)
    allowance_m = settings.allowance_m(speed_mps, update_period_s, age_s)
    hold_s = settings.hold_s(update_period_s)
    keys = [(point[0], point[1]) for point in points]
    on_path = len(points)
    # Rule 4: CPOIs lost from the path, after those on it, passed: only the hold may keep them on.
    recalled = recalled_points(held, keys, now_s, speed_kmh, hold_s)
    if recalled:
        points = [*points, *((curve_id, part, s, r, True) for curve_id, part, s, r in recalled)]
        keys += [(point[0], point[1]) for point in recalled]
    speeds, distances, rules = _required(points, speed_kmh, column_index, allowance_m, settings)
    distances_m = [point[2] for point in points]
    if held.is_on:
        release = (allowance_m, hold_s, on_path)
        _apply_release(rules, speed_kmh, keys, distances_m, speeds, held, now_s, release, settings)
    warning = _warning(rules, points, speeds, distances, path_kind)
    level_rules = ([point_rules[0] for point_rules in rules], [point_rules[1] for point_rules in rules])
    places = (distances_m, [point[3] for point in points], speed_kmh)
    return warning, vehicle_memory(level_rules, keys, held, now_s, places)


def _required(
    points: Sequence[CpoiPoint], speed_kmh: float, column_index: int, allowance_m: float, settings: WarningSettings
) -> tuple[list[tuple[float, float]], list[list[float]], list[list[int]]]:
    """Each CPOI's V_w (Tables 1-2) and S_w (formula (1)) of both levels, and which levels 6.1 requires
    there (:class:`Rule` codes; nothing where passed), in one pass over the CPOIs."""
    speed_mps = kmh_to_mps(speed_kmh)
    g_mps2 = settings.g_mps2
    speeds, distances, rules = [], [], []
    for _, _, distance_m, radius_m, passed in points:
        pair = settings.warning_speeds_one_kmh(radius_m, column_index)
        sws = [
            warning_distance_m(speed_mps, kmh_to_mps(pair[0]), g_mps2),
            warning_distance_m(speed_mps, kmh_to_mps(pair[1]), g_mps2),
        ]
        speeds.append(pair)
        distances.append(sws)
        if passed:
            rules.append([Rule.OFF, Rule.OFF])
            continue
        level_1 = meets_clause_6_1(speed_kmh, pair[0], distance_m, sws[0], allowance_m)
        level_2 = meets_clause_6_1(speed_kmh, pair[1], distance_m, sws[1], allowance_m)
        rules.append([Rule.REQUIRED if level_1 else Rule.OFF, Rule.REQUIRED if level_2 else Rule.OFF])
    return speeds, distances, rules


def _apply_release(
    rules: list[list[int]],
    speed_kmh: float,
    keys: list[PointKey],
    distances_m: list[float],
    speeds: list[tuple[float, float]],
    held: HeldWarning,
    now_s: float | None,
    release: tuple[float, float, int],
    settings: WarningSettings,
) -> None:
    """Release rules 1 (margin) and 2 (hold) of :mod:`csws.warning.release` on ``rules``, in place;
    ``release`` is the vehicle's latency allowance, m, its hold, s, and how many of the CPOIs are on
    its path (the margin keeps none of those recalled after them, rule 4)."""
    allowance_m, hold_s, on_path = release
    named = named_points(held, keys)
    for point, (distance_m, pair, point_rules) in enumerate(zip(distances_m[:on_path], speeds, rules, strict=False)):
        for level in (0, 1):
            if point_rules[level] == Rule.OFF and named[level][point]:
                if meets_margin(speed_kmh, pair[level], distance_m, allowance_m, settings):
                    point_rules[level] = Rule.MARGIN
    if any(rule for point_rules in rules for rule in point_rules):
        return
    for level in (0, 1):
        if within_hold(held.kept_at_s[level], now_s, hold_s):
            for point, point_rules in enumerate(rules):
                if named[level][point]:
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
                    Level(level),
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
        tuple(sorted(triggers, key=by_distance)),
        path_kind,
        HmiHint.for_level(target.level),
    )
