"""Tracks the system state of each vehicle's CSWS after clauses 5.2 to 5.4 of T/ITS 0091-2018.

A small pure state machine: every update takes the previous :class:`VehicleStatus`
and what is known now, and returns the next one. The co-simulation and the HTTP
service keep one status per vehicle and use the same functions.

States
------
off
    The driver switched CSWS off (5.2); the off indication is shown (5.5.2).
standby
    Switched on but not activated: below the activation speed (5.3.2 b).
active
    Activated: warnings are given (5.3.1). By default the system activates on start (5.3.2 a),
    so a vehicle at speed 0 is active; it gets no warning, since 6.1 warns only at speeds of at
    least the warning speed V_w.
fault
    The system cannot warn: no map, no map match, stale or invalid input. 5.4 asks that
    a failing system indicate the fault and switch itself off: in this state warnings
    are off and the fault is indicated with its reason (5.5.3). The faults a map-based
    system meets are conditions of its input rather than broken parts, so the state
    clears by itself with the next good update instead of waiting for the driver; the
    activation latch is kept, so a short loss of the map match does not send an active
    system back to standby.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from enum import StrEnum

import numpy as np

__all__ = [
    "SystemState",
    "Fault",
    "ACTIVATION_ON_START_KMH",
    "STALE_AFTER_S",
    "ActivationSettings",
    "VehicleStatus",
    "switch",
    "next_status",
    "next_statuses",
]


class SystemState(StrEnum):
    """The state of a vehicle's CSWS."""

    OFF = "off"
    STANDBY = "standby"
    ACTIVE = "active"
    FAULT = "fault"


class Fault(StrEnum):
    """Why the system is in fault (5.4): its value a text for people, its :attr:`code` stable for programs."""

    NO_MAP = "no map is loaded"
    NO_MAP_MATCH = "the position matches no lane of the map"
    STALE_INPUT = "the input is stale"
    INVALID_INPUT = "the input is invalid"

    @property
    def code(self) -> str:
        """The fault's stable code (5.5.3: the fault indicated), its name in lower case: ``no_map``,
        ``no_map_match``, ``stale_input``, ``invalid_input``; the text may be reworded, the code is not."""
        return self.name.lower()


#: 5.3.2 a): activation on start. The system activates with the first update after the vehicle starts,
#: whatever its speed: a vehicle standing at speed 0 is active (no warning comes of it, 6.1 asks V >= V_w).
ACTIVATION_ON_START_KMH = 0.0
#: How old a position may be when it is evaluated before it is stale (5.4: the system then indicates a
#: fault instead of warning on where the vehicle was), s. The standard gives no figure: two update
#: periods of a 1 Hz GNSS receiver.
STALE_AFTER_S = 2.0
#: A position older than the last accepted one by more than this is a new start of the vehicle's clock, s
#: (:attr:`ActivationSettings.clock_jump_s`; the sequence matcher takes it likewise, :mod:`csws.road.hmm`).
CLOCK_JUMP_S = 60.0


@dataclass(frozen=True)
class ActivationSettings:
    """When CSWS activates (5.3.2) and when input counts as stale.

    Attributes
    ----------
    activation_speed_kmh
        0 (:data:`ACTIVATION_ON_START_KMH`, the default) activates on start (5.3.2 a), at any
        speed, 0 included; a positive speed activates when the vehicle reaches it (5.3.2 b),
        and a vehicle standing at speed 0 is then in standby (where the activation speed
        exceeds the hysteresis).
    hysteresis_kmh
        Once active, the system returns to standby only below
        ``activation_speed_kmh - hysteresis_kmh``, so it does not flicker.
    stale_after_s
        A position older than this when it is evaluated is stale.
    clock_jump_s
        A position older than the last accepted one by more than this is not stale: the
        vehicle's clock started again (a restart, a new trip) or the last timestamp was
        wrong, and the position is accepted as a new start. One fix with a timestamp far
        in the future therefore silences no fix after it; a fix overtaken by a newer one
        (late by less than this) is still stale.
    """

    activation_speed_kmh: float = ACTIVATION_ON_START_KMH
    hysteresis_kmh: float = 5.0
    stale_after_s: float = STALE_AFTER_S
    clock_jump_s: float = CLOCK_JUMP_S

    def __post_init__(self) -> None:
        for name in ("activation_speed_kmh", "hysteresis_kmh", "stale_after_s", "clock_jump_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be a non-negative number, got {value!r}")


@dataclass(frozen=True)
class VehicleStatus:
    """What the system knows of one vehicle between updates.

    Attributes
    ----------
    state
        The current state.
    switched_on
        The driver's switch (5.2).
    activated
        The activation latch (5.3), kept through faults so that a short fault does not
        send an active system back to standby.
    last_timestamp_s
        Timestamp of the last accepted position, s; None before the first.
    fault
        The reason of a fault state, else None.
    """

    state: SystemState = SystemState.STANDBY
    switched_on: bool = True
    activated: bool = False
    last_timestamp_s: float | None = None
    fault: Fault | None = None

    @property
    def warns(self) -> bool:
        """Whether warnings may be given (5.3.1: only when active)."""
        return self.state is SystemState.ACTIVE


def switch(status: VehicleStatus, on: bool) -> VehicleStatus:
    """The driver switches CSWS on or off (5.2). Switching on starts in standby."""
    if on == status.switched_on:
        return status
    if not on:
        return replace(status, state=SystemState.OFF, switched_on=False, activated=False, fault=None)
    return replace(status, state=SystemState.STANDBY, switched_on=True, activated=False, fault=None)


def _is_activated(was_activated, speed_kmh, settings: ActivationSettings):
    """The activation latch with hysteresis (5.3.2): once activated, the threshold drops by the hysteresis.

    Works on one vehicle (bool, float) and on arrays alike.
    """
    return speed_kmh >= settings.activation_speed_kmh - settings.hysteresis_kmh * was_activated


def _is_number(value):
    """Whether ``value`` is a finite number (floats or arrays; NaN and infinities are not)."""
    return (value == value) & (abs(value) < math.inf)


#: Fault codes of :func:`_next_fields` (0: no fault).
_FAULTS = (None, Fault.NO_MAP, Fault.NO_MAP_MATCH, Fault.STALE_INPUT, Fault.INVALID_INPUT)
_FAULT_CODE = {fault: code for code, fault in enumerate(_FAULTS)}
_STALE, _INVALID = _FAULT_CODE[Fault.STALE_INPUT], _FAULT_CODE[Fault.INVALID_INPUT]


def _next_fields(
    was_activated,
    last_timestamp_s,
    has_last,
    speed_kmh,
    timestamp_s,
    has_timestamp,
    age_s,
    has_age,
    found_fault_code,
    settings: ActivationSettings,
):
    """The rules of one update of a switched-on system (5.3, 5.4), on one vehicle or on arrays of them.

    An absent timestamp, last timestamp or age is flagged by ``has_*`` False (its value
    is then ignored). The input's own faults come first: a speed or a timestamp that is
    not a number is invalid; a timestamp older than the last accepted one (by at most
    ``clock_jump_s``: further back, the clock started again), or an age beyond
    ``stale_after_s``, is stale; else the fault found outside (map side), if any.

    Returns
    -------
    fault_code, activated, last_timestamp_s
        The fault (an index into ``_FAULTS``, 0 for none), the activation latch (kept
        as it was in fault) and the last accepted timestamp.
    """
    invalid = ((speed_kmh >= 0) & (speed_kmh < math.inf)) ^ True
    invalid = invalid | (has_timestamp & (_is_number(timestamp_s) ^ True))
    stale = has_timestamp & has_last & overtaken(last_timestamp_s, timestamp_s, settings.clock_jump_s)
    stale = stale | (has_age & ((_is_number(age_s) & (age_s <= settings.stale_after_s)) ^ True))
    fault_code = _select(invalid, _INVALID, _select(stale, _STALE, found_fault_code))
    in_fault = fault_code > 0
    activated = _select(in_fault, was_activated, _is_activated(was_activated, speed_kmh, settings))
    return fault_code, activated, _select((in_fault ^ True) & has_timestamp, timestamp_s, last_timestamp_s)


def overtaken(newest_s, time_s, clock_jump_s: float = CLOCK_JUMP_S):
    """Whether a time comes before the newest one by at most ``clock_jump_s`` (further back, the clock started again):
    a position that came late (floats or arrays; NaN is never overtaken). The engine answers such a position stale;
    the map matcher (:mod:`csws.road.hmm`) and the service's live map keep the newest one."""
    behind_s = newest_s - time_s
    return (behind_s > 0) & (behind_s <= clock_jump_s)


def _select(condition, if_true, if_false):
    """``if_true`` where ``condition`` holds, else ``if_false`` (one vehicle, or arrays of them)."""
    if isinstance(condition, np.ndarray):
        return np.where(condition, if_true, if_false)
    return if_true if condition else if_false


def next_status(
    status: VehicleStatus,
    speed_kmh: float,
    *,
    timestamp_s: float | None = None,
    age_s: float | None = None,
    found_fault: Fault | None = None,
    settings: ActivationSettings = ActivationSettings(),
) -> VehicleStatus:
    """The status after one update of the vehicle's speed and position.

    Parameters
    ----------
    status
        The status before the update.
    speed_kmh
        The vehicle's speed, km/h.
    timestamp_s
        When the position was taken, s; an update older than the last accepted one is stale,
        unless it is older by more than ``settings.clock_jump_s`` (a new start of the clock).
    age_s
        How old the position is now, s, where known; older than ``stale_after_s`` is stale.
    found_fault
        A fault found outside the state machine: ``Fault.NO_MAP`` or ``Fault.NO_MAP_MATCH``
        when the map side failed, ``Fault.INVALID_INPUT`` for a position that is not a number.
    settings
        Activation speed, hysteresis and staleness limit.
    """
    if not status.switched_on:
        return status
    fault_code, activated, last_timestamp_s = _next_fields(
        status.activated,
        _or_nan(status.last_timestamp_s),
        status.last_timestamp_s is not None,
        speed_kmh,
        _or_nan(timestamp_s),
        timestamp_s is not None,
        _or_nan(age_s),
        age_s is not None,
        _FAULT_CODE[found_fault],
        settings,
    )
    return _switched_on_status(
        fault_code, activated, None if last_timestamp_s != last_timestamp_s else last_timestamp_s
    )


def next_statuses(
    statuses: Sequence[VehicleStatus],
    speed_kmh: Sequence[float] | np.ndarray,
    *,
    timestamp_s: Sequence[float | None] | None = None,
    age_s: Sequence[float | None] | None = None,
    found_fault: Sequence[Fault | None] | None = None,
    settings: ActivationSettings = ActivationSettings(),
) -> list[VehicleStatus]:
    """:func:`next_status` of many vehicles in one vectorised step: the same status each would get alone.

    Parameters are those of :func:`next_status`, one entry per vehicle (None for a whole
    column that is absent). Vehicles whose statuses come out equal share one (immutable)
    status object, so that a fleet updated at one timestamp costs a handful of objects.
    """
    count = len(statuses)
    last_s, has_last = _optional_array([status.last_timestamp_s for status in statuses], count)
    time_s, has_time = _optional_array(timestamp_s, count)
    age, has_age = _optional_array(age_s, count)
    found_codes = (
        np.zeros(count, dtype=np.intp)
        if found_fault is None
        else np.array([_FAULT_CODE[fault] for fault in found_fault], dtype=np.intp)
    )
    was_activated = np.array([status.activated for status in statuses], dtype=bool)
    fault_code, activated, last_s = _next_fields(
        was_activated,
        last_s,
        has_last,
        np.asarray(speed_kmh, dtype=float),
        time_s,
        has_time,
        age,
        has_age,
        found_codes,
        settings,
    )
    last_list = last_s.tolist()
    if np.isnan(last_s).any():
        last_list = [None if value != value else value for value in last_list]
    made: dict[tuple, VehicleStatus] = {}
    updated = []
    for status, key in zip(
        statuses, zip(fault_code.tolist(), activated.tolist(), last_list, strict=False), strict=False
    ):
        if status.switched_on:
            status = made.get(key) or made.setdefault(key, _switched_on_status(*key))
        updated.append(status)
    return updated


def _switched_on_status(fault_code: int, activated: bool, last_timestamp_s: float | None) -> VehicleStatus:
    """The status of a switched-on system from the outcome of :func:`_next_fields`."""
    fault = _FAULTS[fault_code]
    state = SystemState.FAULT if fault is not None else SystemState.ACTIVE if activated else SystemState.STANDBY
    return VehicleStatus(state, True, activated, last_timestamp_s, fault)


def _or_nan(value: float | None) -> float:
    """``value``, or NaN when it is absent (with a separate flag, for :func:`_next_fields`)."""
    return math.nan if value is None else value


def _optional_array(values: Sequence[float | None] | None, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Values as floats (NaN where absent) and whether each is present."""
    if values is None:
        return np.full(count, math.nan), np.zeros(count, dtype=bool)
    present = np.array([value is not None for value in values], dtype=bool)
    if present.all():
        return np.asarray(values, dtype=float), present
    return np.array([_or_nan(value) for value in values], dtype=float), present
