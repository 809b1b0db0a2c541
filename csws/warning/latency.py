"""Learns each vehicle's update period from its own timestamps, for the latency allowance of 6.1.

The warning must be on when the distance S to a CPOI falls below S_w of formula (1) (6.1).
The system sees a vehicle only when a fix of it arrives: after the fix answered now, the
next comes one update period T later, and each is answered when it is already ``age`` old
and after the system's own delay. So 6.1 is met only if the level comes on at the last fix
before S <= S_w, that is at S <= S_w + v (T + age + delay)
(:meth:`csws.warning.rules.WarningSettings.allowance_m`). A fleet sending a fix a second
needs ten times the allowance of a vehicle on a 10 Hz bus, so T is learnt per vehicle:

* each accepted fix with a timestamp later than the last accepted one adds the interval
  between them to the vehicle's last :data:`KEPT_INTERVALS` intervals (kept in its memory,
  :class:`csws.engine.VehicleMemory`);
* its period is their median once :data:`MIN_INTERVALS` are known, so one long gap (a
  tunnel, a dropped fix) or one fix sent twice does not move it; never more than
  :attr:`~csws.warning.rules.WarningSettings.max_update_period_s`;
* until then, and always where the fleet pins it
  (:attr:`~csws.warning.rules.WarningSettings.learn_update_period` False), the configured
  :attr:`~csws.warning.rules.WarningSettings.update_period_s` is taken.

The release rule's hold lasts at least
:attr:`~csws.warning.rules.WarningSettings.release_hold_intervals` periods
(:meth:`~csws.warning.rules.WarningSettings.hold_s`), so one noisy fix between two good ones
does not switch a level off and on.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, MutableMapping, Sequence

from csws.warning.settings import WarningSettings

__all__ = [
    "KEPT_INTERVALS",
    "MIN_INTERVALS",
    "fix_age_s",
    "learn_intervals",
    "next_intervals",
    "update_period_s",
    "update_periods_s",
]

#: How many of its last intervals between fixes a vehicle's memory keeps.
KEPT_INTERVALS = 5
#: How many intervals must be known before the learnt period replaces the configured one.
MIN_INTERVALS = 3


def next_intervals(
    intervals_s: tuple[float, ...], last_timestamp_s: float | None, accepted_timestamp_s: float | None
) -> tuple[float, ...]:
    """A vehicle's last intervals after an update, s.

    Parameters
    ----------
    intervals_s
        Its last intervals before the update, oldest first.
    last_timestamp_s, accepted_timestamp_s
        The last accepted timestamp before the update, and after it
        (:attr:`csws.state.VehicleStatus.last_timestamp_s`): a fix that was not accepted (a
        fault) or carried no timestamp leaves it, and adds nothing; a clock that started
        again (an earlier timestamp accepted) adds nothing either.
    """
    if last_timestamp_s is None or accepted_timestamp_s is None:
        return intervals_s
    interval_s = accepted_timestamp_s - last_timestamp_s
    if not (interval_s > 0 and math.isfinite(interval_s)):
        return intervals_s
    return (*intervals_s[-(KEPT_INTERVALS - 1) :], interval_s)


def update_period_s(intervals_s: Sequence[float], settings: WarningSettings) -> float:
    """The vehicle's update period, s: the median of its last intervals, at most
    ``settings.max_update_period_s``, once :data:`MIN_INTERVALS` are known and the period
    is learnt; else the configured one."""
    count = len(intervals_s)
    if count < MIN_INTERVALS or not settings.learn_update_period:
        return settings.update_period_s
    ordered = sorted(intervals_s)
    middle = count // 2
    median_s = ordered[middle] if count % 2 else (ordered[middle - 1] + ordered[middle]) / 2
    return min(median_s, settings.max_update_period_s)


def learn_intervals(
    intervals: MutableMapping[str, tuple[float, ...]],
    vehicle_ids: Sequence[str],
    last_timestamp_s: Sequence[float | None],
    accepted_timestamp_s: Sequence[float | None],
) -> None:
    """:func:`next_intervals` of many vehicles, kept in ``intervals`` (by vehicle id) where they change.

    Each distinct (intervals, last timestamp, accepted timestamp) is worked out once: a fleet updated
    at one clock shares them, and so its intervals.
    """
    no_intervals: tuple[float, ...] = ()
    learnt: dict[tuple, tuple[float, ...]] = {}
    for vehicle_id, last_s, accepted_s in zip(vehicle_ids, last_timestamp_s, accepted_timestamp_s, strict=True):
        # Only a fix accepted after an earlier accepted one adds an interval.
        if accepted_s is None or last_s is None:
            continue
        intervals_s = intervals.get(vehicle_id, no_intervals)
        key = (intervals_s, last_s, accepted_s)
        after = learnt.get(key)
        if after is None:
            after = learnt[key] = next_intervals(intervals_s, last_s, accepted_s)
        if after != intervals_s:
            intervals[vehicle_id] = after


def update_periods_s(
    intervals: Mapping[str, tuple[float, ...]], vehicle_ids: Sequence[str], settings: WarningSettings
) -> list[float]:
    """:func:`update_period_s` of many vehicles from their intervals (by vehicle id; none where absent), s.

    The period is a function of the intervals alone, so it is found once per distinct intervals: a fleet
    updated at one clock shares a few of them.
    """
    if not (intervals and settings.learn_update_period):
        return [settings.update_period_s] * len(vehicle_ids)
    no_intervals: tuple[float, ...] = ()
    of_intervals: dict[tuple[float, ...], float] = {}
    periods_s = []
    for vehicle_id in vehicle_ids:
        intervals_s = intervals.get(vehicle_id, no_intervals)
        period_s = of_intervals.get(intervals_s)
        if period_s is None:
            period_s = of_intervals[intervals_s] = update_period_s(intervals_s, settings)
        periods_s.append(period_s)
    return periods_s


def fix_age_s(age_s: float | None) -> float:
    """How old the fix is when it is answered, s: the age the client gives (its clock is then
    known), negative ages (clocks apart) taken as 0, and 0 where none is given."""
    if age_s is None or not math.isfinite(age_s):
        return 0.0
    return max(age_s, 0.0)
