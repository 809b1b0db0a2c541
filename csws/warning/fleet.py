"""Clause 6 with the release rule for a fleet: the CPOIs recalled from memory, the judgement, the memories kept.

:class:`csws.engine.Engine` hands each update's active vehicles here, with the roads ahead the
look-ahead found for them (:class:`csws.ahead.horizon.BatchAhead`) and what each vehicle's
warning left in memory (:class:`csws.warning.release.HeldWarning`): the CPOIs the release rule
recalls (rule 4) are put back on the road ahead, clause 6 is judged for every vehicle in one
vectorised step, and each vehicle's memory is kept while one of its levels is on.
"""

from __future__ import annotations

from collections.abc import MutableMapping, Sequence
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from csws.warning.release import NOT_HELD, HeldWarning, memory_masks, next_memories, recalled_points, rows_of_vehicles
from csws.warning.rules import BatchWarnings, evaluate_batch
from csws.warning.settings import WarningSettings

if TYPE_CHECKING:
    from csws.ahead.horizon import BatchAhead

__all__ = ["judged", "keep_memories", "keep_memory", "with_recalled"]


def judged(
    ahead: BatchAhead,
    first: Sequence[int],
    held: Sequence[HeldWarning],
    now_s: Sequence[float | None],
    periods_s: np.ndarray,
    age_s: np.ndarray,
    speed_kmh: np.ndarray,
    columns: np.ndarray,
    recalled: np.ndarray | None,
    settings: WarningSettings,
) -> tuple[BatchWarnings, list[HeldWarning]]:
    """Clause 6 with the release rule for vehicles and their CPOIs, and each vehicle's next warning memory.

    Vehicle ``i``'s CPOIs are ``ahead``'s rows ``first[i]:first[i + 1]``, ``recalled`` those recalled from
    its memory ``held[i]`` (:func:`with_recalled`); ``periods_s`` is each vehicle's update period.
    """
    latched, hold = memory_masks(
        held, now_s, first, ahead.cpoi_curve_id, ahead.cpoi_part_index, settings.hold_s(periods_s), recalled
    )
    batch = evaluate_batch(
        speed_kmh,
        columns,
        ahead.cpoi_vehicle,
        ahead.cpoi_distance_m,
        ahead.cpoi_radius_m,
        settings,
        cpoi_latched=latched,
        cpoi_hold=hold,
        cpoi_passed=ahead.cpoi_passed,
        update_period_s=periods_s,
        age_s=age_s,
    )
    places = (ahead.cpoi_distance_m, ahead.cpoi_radius_m, speed_kmh)
    memories = next_memories(held, now_s, first, ahead.cpoi_curve_id, ahead.cpoi_part_index, batch.cpoi_rule, places)
    return batch, memories


def with_recalled(
    held: Sequence[HeldWarning],
    now_s: Sequence[float | None],
    speed_kmh: np.ndarray,
    hold_s: np.ndarray,
    ahead: BatchAhead,
) -> tuple[BatchAhead, np.ndarray | None]:
    """The roads ahead with the CPOIs the release rule recalls from each vehicle's memory (rule 4,
    :func:`csws.warning.release.recalled_points`) after the vehicle's own, marked passed; and which
    CPOIs are recalled (None where none is). ``hold_s`` is each vehicle's hold time, s."""
    remembered = [(vehicle, memory) for vehicle, memory in enumerate(held) if memory.places]
    if not remembered:
        return ahead, None
    first = np.searchsorted(ahead.cpoi_vehicle, np.arange(len(held) + 1))
    vehicles = [vehicle for vehicle, _ in remembered]
    path_rows, _ = rows_of_vehicles(first, vehicles)
    keys = list(zip(ahead.cpoi_curve_id[path_rows].tolist(), ahead.cpoi_part_index[path_rows].tolist(), strict=True))
    bounds = np.cumsum(np.diff(first)[vehicles]).tolist()
    # Python floats and ints once for the fleet, not a numpy scalar per vehicle.
    speeds_kmh, holds_s, firsts = speed_kmh.tolist(), hold_s.tolist(), first.tolist()
    rows: list[int] = []
    found: list[tuple[int, str, int, float, float]] = []
    for (vehicle, memory), start, stop in zip(remembered, [0, *bounds[:-1]], bounds, strict=True):
        for place in recalled_points(memory, keys[start:stop], now_s[vehicle], speeds_kmh[vehicle], holds_s[vehicle]):
            rows.append(firsts[vehicle + 1])
            found.append((vehicle, *place))
    if not rows:
        return ahead, None
    owner, curve_id, part_index, distance_m, radius_m = (list(column) for column in zip(*found, strict=True))
    recalled_ahead = replace(
        ahead,
        cpoi_vehicle=np.insert(ahead.cpoi_vehicle, rows, owner),
        cpoi_distance_m=np.insert(ahead.cpoi_distance_m, rows, distance_m),
        cpoi_radius_m=np.insert(ahead.cpoi_radius_m, rows, radius_m),
        cpoi_part_index=np.insert(ahead.cpoi_part_index, rows, part_index),
        cpoi_curve_id=np.insert(ahead.cpoi_curve_id, rows, np.array(curve_id, dtype=object)),
        cpoi_passed=np.insert(ahead.cpoi_passed, rows, True),
    )
    return recalled_ahead, np.insert(np.zeros(ahead.cpoi_vehicle.size, dtype=bool), rows, True)


def keep_memories(
    kept: MutableMapping[str, HeldWarning],
    vehicle_ids: Sequence[str],
    memories: Sequence[HeldWarning],
    before: Sequence[HeldWarning] | None = None,
) -> None:
    """Keep each vehicle's warning memory in ``kept`` while a level is on; drop it when none is (where
    ``before``, each vehicle's memory before this update, is given, only where it had one)."""
    for vehicle, (vehicle_id, memory) in enumerate(zip(vehicle_ids, memories, strict=False)):
        if memory is not NOT_HELD or before is None or before[vehicle] is not NOT_HELD:
            keep_memory(kept, vehicle_id, memory)


def keep_memory(kept: MutableMapping[str, HeldWarning], vehicle_id: str, memory: HeldWarning) -> None:
    """Keep a vehicle's warning memory in ``kept`` while a level is on; drop any it had when none is."""
    if memory is not NOT_HELD and memory.is_on:
        kept[vehicle_id] = memory
    elif kept:
        kept.pop(vehicle_id, None)
