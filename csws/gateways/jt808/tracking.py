"""Temporary location tracking (``0x8202``): 1 s reports from a slow terminal while it nears a curve.

A terminal reports every T seconds (JT/T 808 parameter ``0x0029``, often 10-30 s). The warning
comes on at the last report before formula (1)'s point S_w plus the latency allowance
(:mod:`csws.warning.latency`); the allowance is capped at
:attr:`~csws.warning.rules.WarningSettings.max_update_period_s`, so a terminal slower than that
can be warned up to v (T - cap - the system's own delay) after S_w, and any terminal slower than
1 s is warned early by up to v T and misses a speed change between two reports. The platform can
ask a terminal for reports every ``interval`` seconds for ``validity`` seconds with ``0x8202``
(JT/T 808-2013 and 2019, "temporary location tracking control": WORD interval in s, 0 to stop;
DWORD validity in s). So:

* :class:`ReportPace` learns a terminal's regular interval from the times of its reports outside
  the tracking windows it was asked for, and knows whether a window is running;
* :func:`tracking_window_s` decides, from the curves on the path ahead, whether the next regular
  report could pass a curve's warning point, and if so for how long to track: until the vehicle
  has left the curve at the curve's level-1 warning speed, plus a margin.

One window at a time: while one runs, nothing is asked.
"""

from __future__ import annotations

import math
import statistics
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

from csws.standard import Category, kmh_to_mps, warning_distance_m
from csws.warning.latency import KEPT_INTERVALS, MIN_INTERVALS, update_period_s
from csws.warning.rules import column_index
from csws.warning.settings import WarningSettings

__all__ = ["CurveAhead", "ReportPace", "TrackingSettings", "tracking_window_s"]


@dataclass(frozen=True)
class TrackingSettings:
    """When and how the gateway asks a terminal for temporary tracking.

    Attributes
    ----------
    slow_interval_s
        Terminals whose regular interval is longer than this are asked, s (a 1 s terminal with
        some jitter is not).
    interval_s
        The interval asked for, s (the shortest JT/T 808 can ask for).
    margin_s
        The window lasts this long beyond the time to leave the curve at its warning speed, s.
    max_window_s
        The longest window asked for, s: a vehicle that stops in a curve is not tracked for ever.
    """

    slow_interval_s: float = 1.5
    interval_s: int = 1
    margin_s: float = 10.0
    max_window_s: int = 300


@dataclass(frozen=True)
class CurveAhead:
    """A CPOI on the path ahead and how far away its curve ends.

    Attributes
    ----------
    distance_m
        Distance S to the CPOI, m (0 inside its part).
    radius_m
        The CPOI's radius, m.
    end_distance_m
        Distance to the end of the CPOI's curve (its last part), m.
    """

    distance_m: float
    radius_m: float
    end_distance_m: float


class ReportPace:
    """A terminal's regular report interval and its running tracking window, from its reports' times.

    An interval between two reports counts only when neither report lies inside a tracking
    window (after the report that asked for it, up to its end): the 1 s reports of a window and
    the first interval after it say nothing of the terminal's own rate. The regular interval is
    the median of the last :data:`~csws.warning.latency.KEPT_INTERVALS` intervals, once
    :data:`~csws.warning.latency.MIN_INTERVALS` are known, as the engine learns a period.
    """

    def __init__(self) -> None:
        self.intervals_s: deque[float] = deque(maxlen=KEPT_INTERVALS)
        self._last_s: float | None = None
        self._last_tracked = False
        self.window: tuple[float, float] | None = None
        #: Whether the terminal refused a tracking request (it is not asked again on this connection).
        self.refused = False

    def observe(self, time_s: float) -> None:
        """Note a report taken at ``time_s`` (POSIX seconds, the terminal's clock), in time order."""
        tracked = self.tracking(time_s)
        if self._last_s is not None and not tracked and not self._last_tracked:
            interval_s = time_s - self._last_s
            if interval_s > 0 and math.isfinite(interval_s):
                self.intervals_s.append(interval_s)
        self._last_s, self._last_tracked = time_s, tracked

    def tracking(self, time_s: float) -> bool:
        """Whether a window asked for runs at ``time_s``: after the report that asked, until its end."""
        return self.window is not None and self.window[0] < time_s <= self.window[1]

    def regular_interval_s(self) -> float | None:
        """The terminal's own interval, s; None until enough intervals are known."""
        return statistics.median(self.intervals_s) if len(self.intervals_s) >= MIN_INTERVALS else None

    def start(self, time_s: float, window_s: float) -> bool:
        """Start a window of ``window_s`` after the report taken at ``time_s``; False (nothing started) while one
        asked for runs then or later, or once the terminal refused."""
        if self.refused or (self.window is not None and self.window[1] >= time_s):
            return False
        self.window = (time_s, time_s + window_s)
        return True

    def refuse(self) -> None:
        """Note that the terminal refused tracking: no window runs, and none is asked for again."""
        self.window, self.refused = None, True

    def due(self, time_s: float, settings: TrackingSettings) -> tuple[float, ...] | None:
        """The regular intervals to decide with, if the report at ``time_s`` should be checked for a curve ahead:
        the terminal is slow, has not refused, and no window runs; else None."""
        interval_s = self.regular_interval_s()
        if self.refused or interval_s is None or interval_s <= settings.slow_interval_s or self.tracking(time_s):
            return None
        return tuple(self.intervals_s)


def tracking_window_s(
    curves: Sequence[CurveAhead],
    speed_kmh: float,
    category: str | Category,
    intervals_s: Sequence[float],
    age_s: float,
    warning: WarningSettings,
    settings: TrackingSettings,
) -> int | None:
    """How long to ask for temporary tracking (s), or None: whether the next regular report could pass a curve's
    warning point.

    A curve's warning point lies S_w of formula (1) (6.1) for its level-1 V_w at the vehicle's speed, plus the
    latency allowance at the period the engine learns from the terminal's regular intervals, before its CPOI. Only
    curves that warn at this speed (V >= V_w) have one. If the vehicle, at its speed, could reach it within one
    regular interval T (S - v T <= S_w + allowance), it is tracked until it has left the last such curve at that
    curve's V_w, plus :attr:`TrackingSettings.margin_s`, at most :attr:`TrackingSettings.max_window_s`.
    """
    speed_mps = kmh_to_mps(float(speed_kmh))
    column = column_index(category)
    reach_m = speed_mps * statistics.median(intervals_s)
    allowance_m = warning.allowance_m(speed_mps, update_period_s(intervals_s, warning), age_s)
    leave_s = []
    for curve in curves:
        level_1_kmh, _ = warning.policy.warning_speeds_one_kmh(curve.radius_m, column)
        if speed_kmh < level_1_kmh or curve.end_distance_m <= 0.0:
            continue
        point_m = warning_distance_m(speed_mps, kmh_to_mps(level_1_kmh), warning.g_mps2) + allowance_m
        if curve.distance_m - reach_m <= point_m:
            leave_s.append(curve.end_distance_m / kmh_to_mps(level_1_kmh))
    if not leave_s:
        return None
    return min(settings.max_window_s, math.ceil(max(leave_s) + settings.margin_s))
