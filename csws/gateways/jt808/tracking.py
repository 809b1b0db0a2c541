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

One window at a time: while one runs, nothing is asked. The terminal starts the window when the
``0x8202`` reaches it, on its own clock, so the gateway reads the window's end off the reports
(:class:`ReportPace`, :class:`TrackingWindow`) rather than off its clock: neither a late start
(transit, queue, downlink) nor clock skew lets tracked reports pass for the regular interval.
"""

from __future__ import annotations

import math
import statistics
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, replace

from csws.standard import Category, kmh_to_mps, warning_distance_m
from csws.warning.latency import KEPT_INTERVALS, MIN_INTERVALS, update_period_s
from csws.warning.rules import column_index
from csws.warning.settings import WarningSettings

__all__ = ["CurveAhead", "ReportPace", "TrackingSettings", "TrackingWindow", "tracking_window_s"]


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
    overrun_s
        How long past its end as the gateway sees it a window may run on while the reports keep the tracked
        pace, s (:class:`ReportPace`): the downlink and a terminal clock behind the gateway's, bounded so
        that a terminal that stays at the tracked pace for good is seen fast in the end.
    """

    slow_interval_s: float = 1.5
    interval_s: int = 1
    margin_s: float = 10.0
    max_window_s: int = 300
    overrun_s: float = 60.0


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


@dataclass(frozen=True)
class TrackingWindow:
    """A tracking window asked for, in the terminal's report times (its clock).

    Attributes
    ----------
    asked_s
        Time of the report whose answer asked for it; the reports after it are tracked.
    validity_s
        The validity asked for, s.
    end_s
        Where the terminal's validity ends at the latest as the gateway sees it. Until the tracked pace is
        seen, the asking report's time plus its age when the request was sent plus the validity; from the
        first report at the tracked pace (``tracked_from_s``), that report's time plus the validity: the
        terminal got the request before it sent that report, and both times are on its own clock.
    closing_interval_s
        Past ``end_s``, once the tracked pace was seen, the first interval between reports at least this long
        ends the window: the terminal is back at its regular pace. An interval shorter than this after the
        asking report is one at the tracked pace. Halfway between the tracked interval and the regular one (or
        :attr:`TrackingSettings.slow_interval_s` while none is known).
    overrun_s
        The window ends ``overrun_s`` past ``end_s`` whatever the pace (:attr:`TrackingSettings.overrun_s`).
    tracked_from_s
        The first report at the tracked pace; None until one is seen.
    """

    asked_s: float
    validity_s: float
    end_s: float
    closing_interval_s: float
    overrun_s: float
    tracked_from_s: float | None = None

    @property
    def last_s(self) -> float:
        """The window's last moment whatever the pace."""
        return self.end_s + self.overrun_s


class ReportPace:
    """A terminal's regular report interval and its running tracking window, from its reports' times.

    An interval between two reports counts only when neither report lies inside a tracking
    window (after the report that asked for it, up to its end): the tracked reports of a window and
    the first interval after it say nothing of the terminal's own rate. The regular interval is
    the median of the last :data:`~csws.warning.latency.KEPT_INTERVALS` intervals, once
    :data:`~csws.warning.latency.MIN_INTERVALS` are known, as the engine learns a period.

    The terminal starts its validity when the ``0x8202`` reaches it, after the report's transit, the
    gateway's queue and the downlink, and on its own clock; the gateway sees neither. So a window's
    end is read off the reports themselves (:class:`TrackingWindow`): the first report at the tracked
    pace fixes it on the terminal's clock, and past it the window still runs on until an interval at
    the regular pace comes. Before the tracked pace is seen, reports at the regular pace are ones sent
    before the request arrived, so they do not end it; a terminal that never takes up the pace (it
    answered but did not honour the request) is let go at :attr:`TrackingWindow.last_s`.
    """

    def __init__(self) -> None:
        self.intervals_s: deque[float] = deque(maxlen=KEPT_INTERVALS)
        self._regular_s: float | None = None  # the median of intervals_s, kept as they change
        self._last_s: float | None = None
        self._last_tracked = False
        self.window: TrackingWindow | None = None
        #: Whether the terminal refused a tracking request (it is not asked again on this connection).
        self.refused = False

    def observe(self, time_s: float) -> None:
        """Note a report taken at ``time_s`` (POSIX seconds, the terminal's clock), in time order."""
        if self.window is not None and self._last_s is not None:
            self.window = _window_after(self.window, time_s, time_s - self._last_s)
        tracked = self.tracking(time_s)
        if self._last_s is not None and not tracked and not self._last_tracked:
            interval_s = time_s - self._last_s
            if interval_s > 0 and math.isfinite(interval_s):
                self.intervals_s.append(interval_s)
                if len(self.intervals_s) >= MIN_INTERVALS:
                    self._regular_s = statistics.median(self.intervals_s)
        self._last_s, self._last_tracked = time_s, tracked

    def tracking(self, time_s: float) -> bool:
        """Whether a window asked for runs at ``time_s``: after the report that asked, until it has ended."""
        return self.window is not None and self.window.asked_s < time_s <= self.window.last_s

    def regular_interval_s(self) -> float | None:
        """The terminal's own interval, s; None until enough intervals are known."""
        return self._regular_s

    def start(self, time_s: float, window_s: float, age_s: float, settings: TrackingSettings) -> bool:
        """Start a window of ``window_s`` asked for by the report taken at ``time_s`` and ``age_s`` old when the
        request is sent (the gateway's clock now less ``time_s``, clock skew included); False (nothing started)
        while one asked for runs then or later, or once the terminal refused.

        The age is taken between 0 and :attr:`TrackingSettings.overrun_s`: a terminal clock ahead of the
        gateway's would make it negative, one far behind would hold the window open for nothing. It only
        places the end until the terminal is seen at the tracked pace (:class:`TrackingWindow`).
        """
        if self.refused or (self.window is not None and self.window.last_s >= time_s):
            return False
        end_s = time_s + min(max(age_s, 0.0), settings.overrun_s) + window_s
        regular_s = self.regular_interval_s() or settings.slow_interval_s  # slower than that, or not asked
        closing_s = (settings.interval_s + regular_s) / 2.0
        self.window = TrackingWindow(time_s, window_s, end_s, closing_s, settings.overrun_s)
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


def _window_after(window: TrackingWindow, time_s: float, interval_s: float) -> TrackingWindow | None:
    """``window`` after a report taken at ``time_s``, ``interval_s`` after the one before: its end fixed by the
    first report at the tracked pace, or None once it has ended (back at the regular pace past its end, or past
    its last moment)."""
    if time_s <= window.asked_s:
        return window
    at_tracked_pace = 0.0 < interval_s < window.closing_interval_s
    if window.tracked_from_s is None and at_tracked_pace and time_s <= window.last_s:
        return replace(window, tracked_from_s=time_s, end_s=time_s + window.validity_s)
    back_at_pace = (
        window.tracked_from_s is not None and time_s > window.end_s and interval_s >= window.closing_interval_s
    )
    return None if back_at_pace or time_s > window.last_s else window


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
