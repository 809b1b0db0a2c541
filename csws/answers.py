"""Holds what the system answers: one vehicle's :class:`Answer`, and a fleet's answers as columns.

:class:`csws.engine.Engine` gives them; the co-simulation, the HTTP service and library users
read them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Any, NamedTuple

import numpy as np

from csws.ahead.horizon import BatchAhead, PathAhead
from csws.standard import Level
from csws.state import Fault, SystemState
from csws.warning.rules import BatchWarnings, CurveWarning, no_warning

__all__ = ["Answer", "FleetAnswers", "TargetColumns"]


@dataclass(frozen=True)
class Answer:
    """The system's answer for one vehicle at one instant.

    Attributes
    ----------
    vehicle_id
        The vehicle.
    state
        The system state (5.2-5.4); warnings come only in ``active``.
    fault
        Why the state is ``fault``, else None.
    warning
        The warning (level 0 when there is none; always level 0 unless active).
    path
        The path ahead, when one was found.
    """

    vehicle_id: str
    state: SystemState
    fault: Fault | None
    warning: CurveWarning
    path: PathAhead | None

    @property
    def level(self) -> Level:
        """The warning level, 0 to 2."""
        return self.warning.level


@dataclass(frozen=True)
class FleetAnswers:
    """The system's answers for many vehicles at one instant, as parallel columns in their order.

    Columns rather than one :class:`Answer` per vehicle, so that a large fleet is answered
    without per-vehicle objects: the warnings as objects (:attr:`warning`) are built only when
    asked for; :meth:`targets` and :meth:`entries` read the same answers from the arrays.

    Attributes
    ----------
    vehicle_id, state, fault
        Per vehicle, as in :class:`Answer`.
    active
        The vehicles whose path ahead was looked at (active ones), ascending.
    ahead
        Their roads ahead, in the order of ``active``; None when no vehicle is active.
    judged
        Clause 6 and the release rule on the CPOIs of ``ahead`` (vehicle ``k`` of it is
        ``active[k]``); None when no vehicle is active.
    """

    vehicle_id: Sequence[str]
    state: list[SystemState]
    fault: list[Fault | None]
    active: list[int]
    ahead: BatchAhead | None
    judged: BatchWarnings | None

    def _looked_at(self) -> tuple[BatchAhead, BatchWarnings] | None:
        """The roads ahead and their judgement, None when no vehicle is active."""
        if self.ahead is None or self.judged is None:
            return None
        return self.ahead, self.judged

    @cached_property
    def _first_cpoi(self) -> list[int]:
        """Offset of each active vehicle's first CPOI in the flat CPOI arrays, and their count at the end."""
        cpoi_vehicle = self.ahead.cpoi_vehicle if self.ahead is not None else np.zeros(0, dtype=np.intp)
        return np.searchsorted(cpoi_vehicle, np.arange(len(self.active) + 1)).tolist()

    @cached_property
    def level(self) -> list[int]:
        """Each vehicle's warning level, 0 to 2."""
        levels = [0] * len(self.state)
        if self.judged is not None:
            for i, level in zip(self.active, self.judged.level.tolist(), strict=True):
                levels[i] = level
        return levels

    @cached_property
    def warning(self) -> list[CurveWarning]:
        """Each vehicle's :class:`CurveWarning` (vehicles with no warning share theirs)."""
        warnings = [no_warning()] * len(self.state)
        looked_at = self._looked_at()
        if looked_at is None:
            return warnings
        (ahead, judged), first = looked_at, self._first_cpoi
        for i, horizon in zip(self.active, ahead.horizons, strict=True):
            warnings[i] = no_warning(horizon.kind)
        warned = np.flatnonzero(judged.level).tolist()
        if warned:  # most vehicles: nothing to look at
            curve_ids, part_indices = ahead.cpoi_curve_id.tolist(), ahead.cpoi_part_index.tolist()
            found = judged.vehicle_warnings(
                warned,
                [first[k] for k in warned],
                [curve_ids[first[k] : first[k + 1]] for k in warned],
                [part_indices[first[k] : first[k + 1]] for k in warned],
                [ahead.horizons[k].kind for k in warned],
            )
            for k, warning in zip(warned, found, strict=True):
                warnings[self.active[k]] = warning
        return warnings

    def targets(self) -> TargetColumns:
        """Each vehicle's target CPOI (3.12) as columns, None where it has no warning: the values of
        ``warning[i].target`` without the objects."""
        count = len(self.state)
        columns = TargetColumns([None] * count, [None] * count, [None] * count, [None] * count, [None] * count)
        looked_at = self._looked_at()
        if looked_at is None:
            return columns
        ahead, judged = looked_at
        warned = np.flatnonzero(judged.level)
        rows = judged.target[warned]
        vehicles = np.asarray(self.active, dtype=np.intp)[warned].tolist()
        values = (
            ahead.cpoi_curve_id[rows].tolist(),
            ahead.cpoi_part_index[rows].tolist(),
            judged.cpoi_distance_m[rows].tolist(),
            judged.cpoi_radius_m[rows].tolist(),
            judged.warning_speed_kmh[rows].tolist(),
        )
        fields: list[list[Any]] = list(columns)
        for column, column_values in zip(fields, values, strict=True):
            for i, value in zip(vehicles, column_values, strict=True):
                column[i] = value
        return columns

    def entries(self) -> list[tuple[int, str, int, float, int]]:
        """The triggering CPOIs each vehicle is inside (distance 0), in order: vehicle, curve id, part
        index, radius (m) and level; the triggers of ``warning[i]`` at distance 0, without the objects."""
        looked_at = self._looked_at()
        if looked_at is None:
            return []
        ahead, judged = looked_at
        rows = np.flatnonzero((judged.cpoi_level > 0) & (judged.cpoi_distance_m <= 0.0))
        vehicles = np.asarray(self.active, dtype=np.intp)[ahead.cpoi_vehicle[rows]].tolist()
        return list(
            zip(
                vehicles,
                ahead.cpoi_curve_id[rows].tolist(),
                ahead.cpoi_part_index[rows].tolist(),
                judged.cpoi_radius_m[rows].tolist(),
                judged.cpoi_level[rows].tolist(),
                strict=True,
            )
        )


class TargetColumns(NamedTuple):
    """The target CPOI of each vehicle of a fleet, one list per field, None without a warning."""

    curve_id: list[str | None]
    part_index: list[int | None]
    distance_m: list[float | None]
    radius_m: list[float | None]
    warning_speed_kmh: list[float | None]
