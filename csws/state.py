"""The system state of one vehicle's CSWS: clauses 5.2 to 5.4 of T/ITS 0091-2018.

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
    Activated: warnings are given (5.3.1).
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
from dataclasses import dataclass, replace
from enum import StrEnum

__all__ = ["SystemState", "Fault", "ActivationSettings", "VehicleStatus", "switch", "next_status"]


class SystemState(StrEnum):
    """The state of a vehicle's CSWS."""

    OFF = "off"
    STANDBY = "standby"
    ACTIVE = "active"
    FAULT = "fault"


class Fault(StrEnum):
    """Why the system is in fault (5.4)."""

    NO_MAP = "no map is loaded"
    NO_MAP_MATCH = "the position matches no lane of the map"
    STALE_INPUT = "the input is stale"
    INVALID_INPUT = "the input is invalid"


@dataclass(frozen=True)
class ActivationSettings:
    """When CSWS activates (5.3.2) and when input counts as stale.

    Attributes
    ----------
    activation_speed_kmh
        0 activates on start (5.3.2 a); a positive speed activates when the vehicle
        reaches it (5.3.2 b).
    hysteresis_kmh
        Once active, the system returns to standby only below
        ``activation_speed_kmh - hysteresis_kmh``, so it does not flicker.
    stale_after_s
        A position older than this when it is evaluated is stale.
    """

    activation_speed_kmh: float = 0.0
    hysteresis_kmh: float = 5.0
    stale_after_s: float = 2.0

    def __post_init__(self) -> None:
        for name in ("activation_speed_kmh", "hysteresis_kmh", "stale_after_s"):
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


def _is_activated(was_activated: bool, speed_kmh: float, settings: ActivationSettings) -> bool:
    """The activation latch with hysteresis (5.3.2)."""
    if was_activated:
        return speed_kmh >= settings.activation_speed_kmh - settings.hysteresis_kmh
    return speed_kmh >= settings.activation_speed_kmh


def _input_fault(speed_kmh: float, timestamp_s: float | None, age_s: float | None, last_timestamp_s, settings):
    """The fault the input itself shows, or None."""
    if not (math.isfinite(speed_kmh) and speed_kmh >= 0):
        return Fault.INVALID_INPUT
    if timestamp_s is not None and not math.isfinite(timestamp_s):
        return Fault.INVALID_INPUT
    if timestamp_s is not None and last_timestamp_s is not None and timestamp_s < last_timestamp_s:
        return Fault.STALE_INPUT
    if age_s is not None and (not math.isfinite(age_s) or age_s > settings.stale_after_s):
        return Fault.STALE_INPUT
    return None


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
        When the position was taken, s; an update older than the last accepted one is stale.
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
    fault = _input_fault(speed_kmh, timestamp_s, age_s, status.last_timestamp_s, settings) or found_fault
    if fault is not None:
        return replace(status, state=SystemState.FAULT, fault=fault)
    activated = _is_activated(status.activated, speed_kmh, settings)
    return VehicleStatus(
        state=SystemState.ACTIVE if activated else SystemState.STANDBY,
        switched_on=True,
        activated=activated,
        last_timestamp_s=timestamp_s if timestamp_s is not None else status.last_timestamp_s,
        fault=None,
    )
