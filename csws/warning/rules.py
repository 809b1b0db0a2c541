"""Decides for many vehicles at once which warning level of clause 6 is due and for which target CPOI.

Given a vehicle's speed and category and the curvature points of interest (CPOIs,
3.11) ahead of it, decide which warning level is due and for which target CPOI (3.12):

* 6.1: a level is triggered at a CPOI when V >= V_w(R, category, level) and the
  distance S to the CPOI is <= S_w of formula (1), plus the distance driven during the
  system's latency (see :class:`WarningSettings`);
* 6.2.1: level 2 has priority over level 1; several curves triggering together keep
  the warning on; the target is the triggering CPOI of the highest level, then the
  nearest;
* 5.5.1: the two levels are shown distinctly (level 1 visual, level 2 visual and audible).

A CPOI here is the first point of a constant-radius part of a curve (or of a piece of a
clothoid short enough that V_w changes along it by under 1 km/h): along a part V_w and S_w
hardly change, and its first point is the nearest, so it is the one that decides the part.
A vehicle inside a part is at distance 0 from it, at the radius of the road under it
(:func:`csws.ahead.horizon.radius_under`).

This module is clause 6 at one instant. How long a level stays on once 6.1 no longer
requires it is the release rule of :mod:`csws.warning.release`, which the engine applies through
``cpoi_latched``, ``cpoi_hold`` and ``cpoi_passed``.

The core, :func:`evaluate_batch`, works on flat numpy arrays for many vehicles at once;
:mod:`csws.warning.single` is the same computation for one vehicle, in plain floats.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum
from operator import attrgetter

import numpy as np

from csws.standard import (
    Category,
    Column,
    Level,
    kmh_to_mps,
    warning_distance_m,
)
from csws.warning.release import Rule, lowered_warning_speed_kmh
from csws.warning.settings import WarningSettings

__all__ = [
    "CurvaturePointOfInterest",
    "HmiHint",
    "PathKind",
    "Trigger",
    "WarningSettings",
    "CurveWarning",
    "evaluate_batch",
    "BatchWarnings",
    "column_index",
    "column_indices",
    "meets_clause_6_1",
    "meets_margin",
    "no_warning",
]


class PathKind(StrEnum):
    """Where the path ahead came from: the vehicle's known route, or the most probable path."""

    ROUTE = "route"
    PREDICTED = "predicted"


@dataclass(frozen=True)
class CurvaturePointOfInterest:
    """A CPOI (3.11): the start of a constant-radius part of a curve, ahead of the vehicle.

    Attributes
    ----------
    curve_id
        Identifier of the curve the point belongs to.
    part_index
        Index of the constant-radius part within the curve (0 for a single curve, 3.7).
    distance_m
        Distance S along the path from the vehicle to the point, m; 0 when the vehicle
        is already inside the part.
    radius_m
        Radius of the part, m.
    """

    curve_id: str
    part_index: int
    distance_m: float
    radius_m: float


@dataclass(frozen=True)
class HmiHint:
    """How an on-board unit should present a warning level (5.5.1: the levels differ clearly).

    Attributes
    ----------
    visual
        The visual cue, or None.
    audible
        The audible cue, or None.
    """

    visual: str | None
    audible: str | None

    @classmethod
    def for_level(cls, level: Level) -> HmiHint:
        """The hint of a warning level: level 1 visual, level 2 visual and audible."""
        return _HMI_HINTS[Level(level)]


_HMI_HINTS = {
    Level.NONE: HmiHint(visual=None, audible=None),
    Level.LEVEL_1: HmiHint(visual="curve-warning-amber", audible=None),
    Level.LEVEL_2: HmiHint(visual="curve-warning-red-flashing", audible="warning-tone"),
}


@dataclass(frozen=True)
class Trigger:
    """A CPOI whose warning condition (6.1) holds at one level.

    Attributes
    ----------
    curve_id, part_index, distance_m, radius_m
        The CPOI.
    level
        The highest level triggered at this CPOI.
    warning_speed_kmh
        V_w of that level at the CPOI's radius.
    warning_distance_m
        S_w of formula (1) at the vehicle's speed, m (without the latency allowance).
    held
        Whether the level is kept on here by the release rule (:mod:`csws.warning.release`)
        rather than required by 6.1's condition now.
    """

    curve_id: str
    part_index: int
    distance_m: float
    radius_m: float
    level: Level
    warning_speed_kmh: float
    warning_distance_m: float
    held: bool = False


@dataclass(frozen=True)
class CurveWarning:
    """The warning for one vehicle at one instant.

    Attributes
    ----------
    level
        0 (none), 1 or 2; level 2 has priority (6.2.1).
    target
        The target CPOI (3.12): highest level, then nearest; None without a warning.
    triggers
        Every triggering CPOI, nearest first.
    path_kind
        Whether the CPOIs were found on the known route or on the predicted path.
    hmi
        The presentation of ``level`` (5.5.1).
    """

    level: Level
    target: Trigger | None
    triggers: tuple[Trigger, ...]
    path_kind: PathKind
    hmi: HmiHint


@dataclass(frozen=True)
class BatchWarnings:
    """Warnings of many vehicles as arrays: one entry per vehicle, target index into the CPOIs.

    Attributes
    ----------
    level
        ``(n_vehicles,)`` warning level 0, 1 or 2.
    target
        ``(n_vehicles,)`` index of the target CPOI in the flat CPOI arrays, -1 without one.
    cpoi_level
        ``(n_cpois,)`` highest level triggered at each CPOI, 0 where none.
    warning_speed_kmh
        ``(n_cpois,)`` V_w of ``cpoi_level`` at each CPOI (level 1's where none is triggered).
    warning_distance_m
        ``(n_cpois,)`` S_w of formula (1) for that V_w, m.
    cpoi_distance_m, cpoi_radius_m
        ``(n_cpois,)`` the CPOIs' distances and radii as given, m.
    cpoi_rule
        ``(2, n_cpois)`` what keeps level 1 (row 0) and level 2 (row 1) on at each CPOI:
        a :class:`csws.warning.release.Rule` code, 0 where the level is off there.
    """

    level: np.ndarray
    target: np.ndarray
    cpoi_level: np.ndarray
    warning_speed_kmh: np.ndarray
    warning_distance_m: np.ndarray
    cpoi_distance_m: np.ndarray
    cpoi_radius_m: np.ndarray
    cpoi_rule: np.ndarray

    def vehicle_warning(
        self,
        vehicle: int,
        first_cpoi: int,
        curve_ids: Sequence[str],
        part_indices: Sequence[int],
        path_kind: PathKind,
    ) -> CurveWarning:
        """The :class:`CurveWarning` of one vehicle, whose CPOIs are the rows from ``first_cpoi`` on.

        ``curve_ids`` and ``part_indices`` name the vehicle's CPOIs in order.
        """
        if not self.level[vehicle]:  # nothing triggered
            return _NO_WARNINGS[path_kind]
        return self.vehicle_warnings((vehicle,), (first_cpoi,), (curve_ids,), (part_indices,), (path_kind,))[0]

    def vehicle_warnings(
        self,
        vehicles: Sequence[int],
        first_cpoi: Sequence[int],
        curve_ids: Sequence[Sequence[str]],
        part_indices: Sequence[Sequence[int]],
        path_kinds: Sequence[PathKind],
    ) -> list[CurveWarning]:
        """The :class:`CurveWarning` of each of ``vehicles`` (see :meth:`vehicle_warning`), the arrays read once."""
        vehicle_levels, targets, levels, distances, radii, speeds, warning_distances = (
            array.tolist()
            for array in (
                self.level,
                self.target,
                self.cpoi_level,
                self.cpoi_distance_m,
                self.cpoi_radius_m,
                self.warning_speed_kmh,
                self.warning_distance_m,
            )
        )
        columns = np.arange(self.cpoi_level.size)
        held = (self.cpoi_rule[np.fmax(self.cpoi_level - 1, 0), columns] >= Rule.MARGIN).tolist()
        warnings = []
        for vehicle, first, ids, parts, path_kind in zip(
            vehicles, first_cpoi, curve_ids, part_indices, path_kinds, strict=False
        ):
            level = _LEVELS[vehicle_levels[vehicle]]
            if level is Level.NONE:  # nothing triggered
                warnings.append(_NO_WARNINGS[path_kind])
                continue
            triggers = {
                k: Trigger(
                    ids[k - first],
                    int(parts[k - first]),
                    distances[k],
                    radii[k],
                    _LEVELS[levels[k]],
                    speeds[k],
                    warning_distances[k],
                    held[k],
                )
                for k in range(first, first + len(ids))
                if levels[k]
            }
            warnings.append(
                CurveWarning(
                    level=level,
                    target=triggers.get(targets[vehicle]),
                    triggers=tuple(sorted(triggers.values(), key=by_distance)),
                    path_kind=path_kind,
                    hmi=_HMI_HINTS[level],
                )
            )
        return warnings


#: A category's column; its name finds it too (a StrEnum member is equal to its name, and hashes as it).
_COLUMN_INDEX: dict[str, int] = {category: list(Column).index(category.column) for category in Category}
_LEVELS = (Level.NONE, Level.LEVEL_1, Level.LEVEL_2)
#: Orders triggers nearest first (a warning lists its triggers so).
by_distance = attrgetter("distance_m")


def column_index(category: str | Category) -> int:
    """Index into ``list(Column)`` of a category's column of Tables 1-2."""
    index = _COLUMN_INDEX.get(category)
    return index if index is not None else _COLUMN_INDEX[Category.parse(category)]


def column_indices(categories: Sequence[str | Category]) -> np.ndarray:
    """Index into ``list(Column)`` of each category's column of Tables 1-2."""
    return np.array([column_index(c) for c in categories], dtype=np.intp)


def evaluate_batch(
    speed_kmh: np.ndarray,
    column_index: np.ndarray,
    cpoi_vehicle: np.ndarray,
    cpoi_distance_m: np.ndarray,
    cpoi_radius_m: np.ndarray,
    settings: WarningSettings = WarningSettings(),
    *,
    cpoi_latched: np.ndarray | None = None,
    cpoi_hold: np.ndarray | None = None,
    cpoi_passed: np.ndarray | None = None,
    update_period_s: np.ndarray | None = None,
    age_s: np.ndarray | None = None,
) -> BatchWarnings:
    """Evaluate clause 6 for many vehicles and their CPOIs at once.

    Parameters
    ----------
    speed_kmh
        ``(n_vehicles,)`` vehicle speeds V, km/h.
    column_index
        ``(n_vehicles,)`` column of Tables 1-2 per vehicle (see :func:`column_indices`).
    cpoi_vehicle
        ``(n_cpois,)`` index of the vehicle each CPOI belongs to.
    cpoi_distance_m
        ``(n_cpois,)`` distance S from the vehicle to the CPOI, m (>= 0).
    cpoi_radius_m
        ``(n_cpois,)`` radius at the CPOI, m.
    settings
        Policy, latency and release rule.
    cpoi_latched, cpoi_hold
        ``(2, n_cpois)``: which CPOIs kept level 1 (row 0) and level 2 (row 1) on at the
        last update, and which of those the hold may keep on
        (:func:`csws.warning.release.memory_masks`); None for vehicles without a memory (6.1 alone).
    cpoi_passed
        ``(n_cpois,)``: CPOIs the vehicle has just passed (:data:`csws.ahead.horizon.END_MARGIN_M`):
        6.1 requires nothing there, only the release rule may keep a level on.
    update_period_s, age_s
        ``(n_vehicles,)``: each vehicle's update period (learnt, :func:`csws.warning.latency.update_period_s`)
        and its fix's age when answered, s; None for the configured period and fresh fixes. Both
        lengthen the latency allowance (:meth:`WarningSettings.allowance_m`).

    Returns
    -------
    BatchWarnings
        Per-vehicle level and target, per-CPOI triggered level, V_w, S_w and what keeps it on.
    """
    speed_kmh = np.asarray(speed_kmh, dtype=float)
    cpoi_vehicle = np.asarray(cpoi_vehicle, dtype=np.intp)
    distance = np.asarray(cpoi_distance_m, dtype=float)
    radius = np.asarray(cpoi_radius_m, dtype=float)
    cpoi_speed_kmh = speed_kmh[cpoi_vehicle]
    cpoi_speed_mps = kmh_to_mps(cpoi_speed_kmh)
    # Row 0: level 1, row 1: level 2 (Tables 1 and 2).
    threshold_kmh = settings.policy.warning_speeds_kmh(radius, np.asarray(column_index)[cpoi_vehicle])
    sw_m = warning_distance_m(cpoi_speed_mps, kmh_to_mps(threshold_kmh), settings.g_mps2)
    allowance_m = settings.allowance_m(
        cpoi_speed_mps,
        None if update_period_s is None else np.asarray(update_period_s, dtype=float)[cpoi_vehicle],
        0.0 if age_s is None else np.asarray(age_s, dtype=float)[cpoi_vehicle],
    )
    required = meets_clause_6_1(cpoi_speed_kmh, threshold_kmh, distance, sw_m, allowance_m)
    if cpoi_passed is not None:
        required &= ~np.asarray(cpoi_passed, dtype=bool)
    rule = np.where(required, Rule.REQUIRED, Rule.OFF).astype(np.int8)
    if cpoi_latched is not None and cpoi_latched.any():
        _apply_margin(rule, cpoi_latched, cpoi_speed_kmh, threshold_kmh, distance, allowance_m, settings)
    if cpoi_hold is not None and cpoi_hold.any():
        _apply_hold(rule, cpoi_hold, cpoi_vehicle, len(speed_kmh))
    cpoi_level, shown = _levels_shown(rule)
    columns = np.arange(distance.size)
    level, target = _targets(len(speed_kmh), cpoi_vehicle, cpoi_level, distance)
    return BatchWarnings(
        level, target, cpoi_level, threshold_kmh[shown, columns], sw_m[shown, columns], distance, radius, rule
    )


def meets_clause_6_1(speed_kmh, warning_speed_kmh, distance_m, warning_distance_m, allowance_m):
    """6.1: V >= V_w and S <= S_w, plus the distance driven during the latency (floats or arrays)."""
    return (speed_kmh >= warning_speed_kmh) & (distance_m <= warning_distance_m + allowance_m)


def meets_margin(speed_kmh, warning_speed_kmh, distance_m, allowance_m, settings: WarningSettings):
    """Release rule 1: 6.1's condition with V_w lowered by the release margin (floats or arrays).

    A CPOI that kept a level on keeps it while this holds (:mod:`csws.warning.release`).
    ``allowance_m`` is the vehicle's latency allowance (:meth:`WarningSettings.allowance_m`):
    the margin's distance grows with the vehicle's update period as 6.1's does.
    """
    speed_mps = kmh_to_mps(speed_kmh)
    lowered_kmh = lowered_warning_speed_kmh(warning_speed_kmh, settings.release_margin_kmh)
    lowered_sw_m = warning_distance_m(speed_mps, kmh_to_mps(lowered_kmh), settings.g_mps2)
    return meets_clause_6_1(speed_kmh, lowered_kmh, distance_m, lowered_sw_m, allowance_m)


def _apply_margin(
    rule: np.ndarray,
    cpoi_latched: np.ndarray,
    speed_kmh: np.ndarray,
    warning_speed_kmh: np.ndarray,
    distance_m: np.ndarray,
    allowance_m: np.ndarray,
    settings: WarningSettings,
) -> None:
    """Release rule 1 on ``rule``, in place: a CPOI that kept a level on keeps it while
    :func:`meets_margin` holds."""
    margin = cpoi_latched & meets_margin(speed_kmh, warning_speed_kmh, distance_m, allowance_m, settings)
    rule[(rule == Rule.OFF) & margin] = Rule.MARGIN


def _apply_hold(rule: np.ndarray, cpoi_hold: np.ndarray, cpoi_vehicle: np.ndarray, n_vehicles: int) -> None:
    """Release rule 2 on ``rule``, in place: the hold keeps a level on only for a vehicle that
    nothing else keeps warned."""
    warned = np.bincount(cpoi_vehicle, np.any(rule != Rule.OFF, axis=0), n_vehicles) > 0
    rule[(rule == Rule.OFF) & cpoi_hold & ~warned[cpoi_vehicle]] = Rule.HOLD


def _levels_shown(rule: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each CPOI's highest level kept on (0 where none), and the row of ``rule`` whose V_w and
    S_w it shows (level 2's where level 2 is on, else level 1's)."""
    kept = rule != Rule.OFF
    shown = kept[1].astype(np.intp)
    return (kept[0] | kept[1]).astype(np.int8) + shown.astype(np.int8), shown


#: The warning of a vehicle for which nothing triggers, per path kind.
_NO_WARNINGS = {kind: CurveWarning(Level.NONE, None, (), kind, _HMI_HINTS[Level.NONE]) for kind in PathKind}


def no_warning(path_kind: PathKind = PathKind.PREDICTED) -> CurveWarning:
    """The (shared) warning of level 0: nothing triggers, or the system does not warn."""
    return _NO_WARNINGS[path_kind]


def _targets(
    n_vehicles: int, cpoi_vehicle: np.ndarray, cpoi_level: np.ndarray, distance: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Per vehicle the highest triggered level and its nearest CPOI (3.12, 6.2.1).

    CPOIs sorted by vehicle, then level descending, then distance: the first of each
    vehicle is its target, if its level is not 0. Most steps trigger nothing: no sort then.
    """
    level = np.zeros(n_vehicles, dtype=np.int8)
    target = np.full(n_vehicles, -1, dtype=np.intp)
    if not cpoi_level.any():
        return level, target
    order = np.lexsort((distance, -cpoi_level, cpoi_vehicle))
    vehicles = cpoi_vehicle[order]
    first = np.empty(order.size, dtype=bool)
    first[0] = True
    np.not_equal(vehicles[1:], vehicles[:-1], out=first[1:])
    best = order[first]
    triggered = cpoi_level[best] > 0
    level[vehicles[first][triggered]] = cpoi_level[best[triggered]]
    target[vehicles[first][triggered]] = best[triggered]
    return level, target
