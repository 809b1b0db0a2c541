"""Decides when a warning that is on goes off (the release rule), and what a vehicle's warning keeps for it.

Clause 6.1 says when a level is due; the standard says nothing of when it ends beyond
6.2.1's "持续发出" (the warning continues while curves keep requiring it). Taken at
every update on its own, 6.1's condition switches a level on and off as the measured
speed wanders round V_w by a few tenths of a km/h, or as a braking driver's S_w shrinks
towards the distance left. The rule here keeps a level on that is on:

1. **Margin.** A CPOI (3.11) that kept level L on at the last update keeps it on while
   6.1's condition holds for it with V_w lowered by :attr:`WarningSettings.release_margin_kmh`
   (1 km/h): V >= V_w - 1 km/h and S <= S_w(V, V_w - 1 km/h) + the latency allowance.
   A level goes on at V_w and off only 1 km/h below it, so speed noise smaller than the
   margin cannot switch it back and forth.
2. **Hold.** When nothing keeps any level on any more but a CPOI that kept one on is
   still ahead or under the vehicle, that level stays on until
   :attr:`WarningSettings.release_hold_s` (1 s), and at least
   :attr:`WarningSettings.release_hold_intervals` (1.5) of the vehicle's update periods
   (:mod:`csws.warning.latency`), has passed since it was last kept on. The
   warning is so never switched off and on again by the same curve within that time. A
   level 2 that gives way to a level 1 still required is not held: the driver then sees
   at once the lower warning speed that is due. The hold needs the vehicle's timestamps;
   without them only the margin applies.
3. **Passed.** A CPOI behind the vehicle requires nothing; for the first
   :data:`csws.ahead.horizon.END_MARGIN_M` (1 m) past its part only rules 1 and 2 may keep a
   level on there, so that position noise at the curve's end cannot switch the warning
   off and on again; beyond that it keeps nothing on, and the level goes off at once.
4. **Lost.** A CPOI that kept a level on and is missing from the path ahead at the next
   update (a fix matched onto another connection at a junction, or onto a neighbouring lane
   leading elsewhere) is recalled from the memory while the vehicle cannot have reached it:
   its distance then, less the time since times the larger of the vehicle's speeds then and
   now, is still positive. Recalled at that distance, it is marked passed, so that neither
   6.1 nor the margin applies to it and only rule 2 may keep its level on: the level stays
   on until the hold has run out since it was last kept on otherwise, and goes off at once
   when the vehicle may have reached the CPOI. One fix matched away from the curve so does
   not switch the warning off and on again; a vehicle that really turned away keeps it for
   no longer than the hold, and never once it may be in or behind the curve.

Why the rule never hides a warning the standard requires: it only ever adds to 6.1. A
level that 6.1 requires at some CPOI at this update is on, whatever was before; the rule
decides only how long a level stays on after 6.1 stopped requiring it. Level 2 keeps its
priority (6.2.1): the levels are held separately and the higher one on is shown, and as
any CPOI that triggers level 2 triggers level 1 (V_w and S_w of the two levels nest), a
held level 2 never stands where level 1 was not due first.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import compress

import numpy as np

from csws.standard import kmh_to_mps

__all__ = [
    "HeldWarning",
    "NOT_HELD",
    "Rule",
    "lowered_warning_speed_kmh",
    "memory_masks",
    "named_points",
    "next_memories",
    "recalled_points",
    "rows_of_vehicles",
    "vehicle_memory",
    "within_hold",
]

#: A CPOI as the release rule remembers it: (curve id, part index).
PointKey = tuple[str, int]

#: Where a CPOI was at an update: curve id, part index, distance S (m) and radius (m).
PointPlace = tuple[str, int, float, float]

#: Numbers, as a list or an array.
Floats = Sequence[float] | np.ndarray


class Rule:
    """What keeps a level on at a CPOI: codes of the ``(2, n_cpois)`` array
    :func:`csws.warning.rules.evaluate_batch` returns (row 0 level 1, row 1 level 2)."""

    OFF = 0
    #: 6.1's condition holds now.
    REQUIRED = 1
    #: Rule 1: the margin.
    MARGIN = 2
    #: Rule 2: the hold.
    HOLD = 3


@dataclass(frozen=True)
class HeldWarning:
    """What a vehicle's warning keeps between updates for the release rule.

    Attributes
    ----------
    points
        For level 1 and level 2 (in that order), the CPOIs that kept the level on at the
        last update; empty where the level is off.
    kept_at_s
        For each level, the timestamp of the last update at which 6.1 or the margin kept
        it on (not the hold); None where it is off or the vehicle sends no timestamps.
    places
        Where each CPOI of ``points`` was at the last update (rule 4), nearest first.
    seen
        The last update's timestamp, s, and the vehicle's speed then, km/h (rule 4); None
        without a timestamp.
    """

    points: tuple[frozenset[PointKey], frozenset[PointKey]] = (frozenset(), frozenset())
    kept_at_s: tuple[float | None, float | None] = (None, None)
    places: tuple[PointPlace, ...] = ()
    seen: tuple[float, float] | None = None

    @property
    def is_on(self) -> bool:
        """Whether any level was on at the last update."""
        return bool(self.points[0] or self.points[1])


#: The memory of a vehicle whose warning is off (shared: memories are immutable).
NOT_HELD = HeldWarning()


def memory_masks(
    held: Sequence[HeldWarning],
    now_s: Sequence[float | None],
    first_cpoi: Sequence[int],
    curve_ids: Sequence[str] | np.ndarray,
    part_indices: Sequence[int] | np.ndarray,
    hold_s: float | Sequence[float] | np.ndarray,
    recalled: Sequence[bool] | np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Which CPOIs each level's memory names (rule 1), and which of those the hold may keep
    on (rule 2: less than ``hold_s`` since the level was last kept on otherwise; it does
    only where nothing else keeps the vehicle warned), each
    ``(2, n_cpois)`` bool. A CPOI behind the vehicle is not among the CPOIs (rule 3).

    Parameters
    ----------
    held, now_s
        Each vehicle's memory and the timestamp of this update (None where unknown).
    first_cpoi
        Offset of each vehicle's first CPOI in the flat CPOI arrays, and their count at the end.
    curve_ids, part_indices
        The flat CPOIs.
    hold_s
        The hold (:meth:`csws.warning.rules.WarningSettings.hold_s`): one for all vehicles, or
        each vehicle's (it lasts at least some of its update periods).
    recalled
        Which of the CPOIs are recalled from the memory (rule 4, :func:`recalled_points`): only the
        hold may keep them on, never the margin. None where none is.
    """
    latched = np.zeros((2, len(curve_ids)), dtype=bool)
    hold = np.zeros((2, len(curve_ids)), dtype=bool)
    vehicles = _vehicles_held(held)
    if not vehicles:  # most updates of most fleets: no warning to keep
        return latched, hold
    rows, owner = rows_of_vehicles(first_cpoi, vehicles)
    keys = list(
        zip(
            np.asarray(curve_ids, dtype=object)[rows].tolist(),
            np.asarray(part_indices, dtype=np.int64)[rows].tolist(),
            strict=True,
        )
    )
    holds_s = np.broadcast_to(np.asarray(hold_s, dtype=float), (len(held),)).tolist()
    points = [held[vehicle].points for vehicle in vehicles]
    owners = owner.tolist()
    for level in (0, 1):
        # Rule 1 as :func:`named_points` asks it of one vehicle, for the rows of every vehicle at once.
        named = np.array([key in points[place][level] for place, key in zip(owners, keys, strict=True)], dtype=bool)
        kept_at_s = [held[vehicle].kept_at_s[level] for vehicle in vehicles]
        within = [within_hold(kept_s, now_s[v], holds_s[v]) for kept_s, v in zip(kept_at_s, vehicles, strict=True)]
        latched[level, rows] = named
        hold[level, rows] = named & np.array(within, dtype=bool)[owner]
    if recalled is not None:
        latched &= ~np.asarray(recalled, dtype=bool)
    return latched, hold


def _vehicles_held(held: Sequence[HeldWarning]) -> list[int]:
    """The vehicles whose memory keeps a level on (most of a fleet's keep none: :data:`NOT_HELD`)."""
    return [vehicle for vehicle, memory in enumerate(held) if memory is not NOT_HELD and memory.is_on]


def rows_of_vehicles(first_cpoi: Sequence[int] | np.ndarray, vehicles: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    """The rows of the flat CPOI arrays that belong to ``vehicles``, and to which of them (its place in
    ``vehicles``) each row belongs."""
    first = np.asarray(first_cpoi, dtype=np.intp)
    chosen = np.asarray(vehicles, dtype=np.intp)
    starts = first[chosen]
    counts = first[chosen + 1] - starts
    owner = np.repeat(np.arange(chosen.size), counts)
    rows = np.arange(int(counts.sum())) + np.repeat(starts - (np.cumsum(counts) - counts), counts)
    return rows, owner


def recalled_points(
    held: HeldWarning, keys: Sequence[PointKey], now_s: float | None, speed_kmh: float, hold_s: float
) -> list[PointPlace]:
    """Rule 4: the CPOIs that kept a level on, are missing from the path ahead (``keys``) and that the
    vehicle cannot have reached since the last update, each at its distance less the most the vehicle
    can have driven; only those whose level the hold may still keep on (rule 2), nearest first.

    Parameters
    ----------
    held
        The vehicle's memory from the last update.
    keys
        The CPOIs on its path ahead now.
    now_s, speed_kmh
        This update's timestamp, s (None where unknown), and the vehicle's speed now, km/h.
    hold_s
        Its hold (:meth:`csws.warning.rules.WarningSettings.hold_s`), s.
    """
    if not held.places or held.seen is None or now_s is None:
        return []
    on_path = set(keys)
    missing = [place for place in held.places if (place[0], place[1]) not in on_path]
    if not missing:  # most updates: every CPOI that kept a level on is still ahead
        return []
    seen_at_s, seen_speed_kmh = held.seen
    driven_m = kmh_to_mps(max(seen_speed_kmh, speed_kmh)) * (now_s - seen_at_s)
    if not math.isfinite(driven_m) or now_s < seen_at_s:
        return []
    holding = [level for level in (0, 1) if within_hold(held.kept_at_s[level], now_s, hold_s)]
    recalled = []
    for curve_id, part_index, distance_m, radius_m in missing:
        key = (curve_id, part_index)
        if not any(key in held.points[level] for level in holding):
            continue
        if distance_m - driven_m > 0.0:
            recalled.append((curve_id, part_index, distance_m - driven_m, radius_m))
    return recalled


def next_memories(
    held: Sequence[HeldWarning],
    now_s: Sequence[float | None],
    first_cpoi: Sequence[int],
    curve_ids: Sequence[str] | np.ndarray,
    part_indices: Sequence[int] | np.ndarray,
    cpoi_rule: np.ndarray,
    places: tuple[Floats, Floats, Floats] | None = None,
) -> list[HeldWarning]:
    """Each vehicle's memory after this update, from what kept each level on at each of its
    CPOIs (``cpoi_rule``, ``(2, n_cpois)`` :class:`Rule` codes).

    ``places`` are the flat CPOIs' distances S and radii, m, and each vehicle's speed, km/h, for
    rule 4; without them the memories keep no places, and rule 4 recalls nothing from them.

    The CPOIs that keep a level on are found once for all vehicles; each vehicle's memory is built
    from those rows only (a CPOI that keeps nothing on adds nothing to it), by the same helper as
    :func:`vehicle_memory`.
    """
    memories = [NOT_HELD] * len(held)
    on_rows = np.flatnonzero(np.any(cpoi_rule != Rule.OFF, axis=0))
    if not on_rows.size:
        return memories
    vehicle_of_row = np.searchsorted(np.asarray(first_cpoi), on_rows, side="right") - 1
    vehicles, starts = np.unique(vehicle_of_row, return_index=True)
    bounds = [*starts.tolist(), int(on_rows.size)]
    rules_on = cpoi_rule[:, on_rows]
    level_1, level_2 = rules_on.tolist()
    kept_1, kept_2 = np.maximum.reduceat(_KEPT[rules_on], starts, axis=1).tolist()
    ids = np.asarray(curve_ids, dtype=object)[on_rows].tolist()
    parts = np.asarray(part_indices, dtype=np.int64)[on_rows].tolist()
    keys = list(zip(ids, parts, strict=True))
    if places is not None:
        # Every row here keeps a level on, so each vehicle keeps the places of all its rows.
        distances_m = np.asarray(places[0], dtype=float)[on_rows].tolist()
        radii_m = np.asarray(places[1], dtype=float)[on_rows].tolist()
        kept_places = list(zip(ids, parts, distances_m, radii_m, strict=True))
        speeds_kmh = np.asarray(places[2], dtype=float)[vehicles].tolist()
    for k, (vehicle, start, stop) in enumerate(zip(vehicles.tolist(), bounds, bounds[1:], strict=False)):
        here = (level_1[start:stop], level_2[start:stop])
        where = None if places is None else (tuple(kept_places[start:stop]), speeds_kmh[k])
        memories[vehicle] = _memory(
            keys[start:stop], here, (kept_1[k], kept_2[k]), held[vehicle], now_s[vehicle], where
        )
    return memories


def vehicle_memory(
    rules: tuple[Sequence[int], Sequence[int]],
    keys: Sequence[PointKey],
    held: HeldWarning,
    now_s: float | None,
    places: tuple[Floats, Floats, float] | None = None,
) -> HeldWarning:
    """One vehicle's memory after this update, from what kept level 1 and level 2 on at each of its
    CPOIs (``rules``, :class:`Rule` codes in the order of ``keys``) and its memory ``held`` before.

    A level keeps the CPOIs that kept it on; its time is now where 6.1 or the margin kept it on,
    the time it had where only the hold did (rule 2 counts from the last time it was kept on
    otherwise), and none where it is off. With ``places`` (the CPOIs' distances S and radii, m,
    and the vehicle's speed, km/h) it keeps where those CPOIs are now, for rule 4.
    """
    rules_1, rules_2 = rules
    if not any(rules_1) and not any(rules_2):
        return NOT_HELD
    kept = (max(map(_KEPT_OF.__getitem__, rules_1), default=0), max(map(_KEPT_OF.__getitem__, rules_2), default=0))
    where = None
    if places is not None:
        distances_m, radii_m, speed_kmh = places
        kept_places = tuple(
            (key[0], key[1], float(distance_m), float(radius_m))
            for key, level_1, level_2, distance_m, radius_m in zip(
                keys, rules_1, rules_2, distances_m, radii_m, strict=True
            )
            if level_1 or level_2
        )
        where = (kept_places, float(speed_kmh))
    return _memory(keys, rules, kept, held, now_s, where)


#: What each :class:`Rule` code says of when its level was last kept on (rule 2): 2 now (6.1 or the
#: margin keeps it on), 1 when it was before (only the hold keeps it on), 0 never (off); a level's
#: time follows the largest of its CPOIs'.
_KEPT = np.array([0, 2, 2, 1], dtype=np.int8)
_KEPT_OF = tuple(_KEPT.tolist())


def _memory(
    keys: Sequence[PointKey],
    rules: tuple[Sequence[int], Sequence[int]],
    kept: tuple[int, int],
    held: HeldWarning,
    now_s: float | None,
    where: tuple[tuple[PointPlace, ...], float] | None,
) -> HeldWarning:
    """A vehicle's memory from its CPOIs' rules and each level's ``kept`` code (:data:`_KEPT`), with where
    (``where``: the places of the CPOIs that keep a level on, and the speed, km/h) for rule 4."""
    points = (frozenset(compress(keys, rules[0])), frozenset(compress(keys, rules[1])))
    kept_at_s = (_kept_at_s(kept[0], held.kept_at_s[0], now_s), _kept_at_s(kept[1], held.kept_at_s[1], now_s))
    if where is None or now_s is None or not math.isfinite(now_s):
        return HeldWarning(points, kept_at_s)
    return HeldWarning(points, kept_at_s, where[0], (now_s, where[1]))


def _kept_at_s(kept: int, kept_before_s: float | None, now_s: float | None) -> float | None:
    """When a level was last kept on by 6.1 or the margin (its ``kept`` code, :data:`_KEPT`): now where one
    of them keeps it on, the time it had where only the hold does (rule 2), none where it is off."""
    if kept == 2:
        return now_s
    return kept_before_s if kept == 1 else None


def named_points(held: HeldWarning, keys: Sequence[PointKey]) -> tuple[list[bool], list[bool]]:
    """For level 1 and level 2, which of a vehicle's CPOIs (``keys``, in order) its memory names (rule 1)."""
    return [key in held.points[0] for key in keys], [key in held.points[1] for key in keys]


def lowered_warning_speed_kmh(warning_speed_kmh, margin_kmh: float):
    """Rule 1: V_w lowered by the release margin, never below 0, km/h (floats or arrays, the same to the bit)."""
    if isinstance(warning_speed_kmh, float):
        return max(warning_speed_kmh - margin_kmh, 0.0)
    return np.fmax(warning_speed_kmh - margin_kmh, 0.0)


def within_hold(kept_at_s: float | None, now_s: float | None, hold_s: float) -> bool:
    """Whether less than ``hold_s`` has passed since ``kept_at_s`` (both known)."""
    if kept_at_s is None or now_s is None or not math.isfinite(now_s):
        return False
    return now_s - kept_at_s < hold_s
