"""Holds what the warning of clause 6 needs beyond the standard's tables: policy, latency and release rule."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from csws.standard import DEFAULT_POLICY, G_MPS2, WarningSpeedPolicy

__all__ = ["WarningSettings"]

#: How many (radius, column) pairs a settings object remembers the warning speeds of before it starts afresh.
WARNING_SPEEDS_REMEMBERED = 4096


@dataclass(frozen=True)
class WarningSettings:
    """What the warning engine needs beyond the standard's tables.

    Attributes
    ----------
    policy
        Warning speeds (Tables 1 and 2 by default; a fleet may override them).
    update_period_s
        How often the vehicle's position reaches the system, s. Between two updates the
        vehicle moves v * update_period_s unseen, so the warning is raised that much
        earlier to be on when the distance falls below S_w. With ``learn_update_period``
        this is the period of a vehicle until its own is learnt from its timestamps
        (:mod:`csws.warning.latency`); without, it is every vehicle's period (pinned).
    system_delay_s
        Processing and display delay of the system, s.
    g_mps2
        g of formula (1).
    release_margin_kmh
        How far below V_w a level that is on goes off, km/h (:mod:`csws.warning.release`, rule 1).
    release_hold_s
        How long a level stays on after nothing keeps it on any more while a CPOI that
        did is still ahead or under the vehicle, s (:mod:`csws.warning.release`, rule 2);
        at least ``release_hold_intervals`` update periods (:meth:`hold_s`).
    learn_update_period
        Whether each vehicle's update period is learnt from its own timestamps (the median of
        its last intervals, :mod:`csws.warning.latency`); False pins it to ``update_period_s``.
    max_update_period_s
        The largest update period learnt, s: a vehicle heard from less often than this is
        compensated for this long only (a longer silence is a gap, not a rate).
    release_hold_intervals
        The hold lasts at least this many of the vehicle's update periods.

    Notes
    -----
    Latency compensation is what makes the system pass the standard's own test rows:
    Tables 5-9 list several S_w up to 1.64 m larger than formula (1) gives (M3-N-O,
    R=200 m, V=100 km/h), and a system that sees the vehicle only every
    ``update_period_s`` would be late by up to ``v * update_period_s`` otherwise.
    """

    policy: WarningSpeedPolicy = field(default_factory=lambda: DEFAULT_POLICY)
    update_period_s: float = 0.1
    system_delay_s: float = 0.1
    g_mps2: float = G_MPS2
    release_margin_kmh: float = 1.0
    release_hold_s: float = 1.0
    learn_update_period: bool = True
    max_update_period_s: float = 5.0
    release_hold_intervals: float = 1.5

    def __post_init__(self) -> None:
        for name in (
            "update_period_s",
            "system_delay_s",
            "release_margin_kmh",
            "release_hold_s",
            "max_update_period_s",
            "release_hold_intervals",
        ):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                unit = "km/h" if name.endswith("_kmh") else "intervals" if name.endswith("_intervals") else "seconds"
                raise ValueError(f"{name} must be a non-negative number of {unit}, got {value!r}")
        if not (np.isfinite(self.g_mps2) and self.g_mps2 > 0):
            raise ValueError(f"g_mps2 must be a positive number, got {self.g_mps2!r}")

    @property
    def latency_s(self) -> float:
        """Total latency t_latency compensated for with the configured update period and a fresh fix, s."""
        return self.update_period_s + self.system_delay_s

    def allowance_m(self, speed_mps, update_period_s=None, age_s=0.0):
        """The distance driven at ``speed_mps`` during the latency, by which S_w is extended, m (floats or arrays).

        The latency is the vehicle's update period (``update_period_s``: its learnt one,
        :mod:`csws.warning.latency`; the configured one where None), the system delay and the
        fix's age when it is answered (``age_s``): the next fix, one period later, is answered
        that much further on, so 6.1's S <= S_w must already be met at this one. Floats and
        arrays give the same result to the bit.
        """
        period_s = self.update_period_s if update_period_s is None else update_period_s
        return speed_mps * (period_s + self.system_delay_s + age_s)

    def hold_s(self, update_period_s=None):
        """Release rule 2's hold for a vehicle updated every ``update_period_s`` (the configured period
        where None), s: ``release_hold_s``, and at least ``release_hold_intervals`` update periods so that
        one noisy fix between two good ones cannot switch a level off and on (floats or arrays)."""
        period_s = self.update_period_s if update_period_s is None else update_period_s
        if isinstance(period_s, np.ndarray):
            return np.fmax(self.release_hold_s, self.release_hold_intervals * period_s)
        return max(self.release_hold_s, self.release_hold_intervals * period_s)

    def warning_speeds_one_kmh(self, radius_m: float, column_index: int) -> tuple[float, float]:
        """V_w (km/h) of both levels at one radius and column (Tables 1-2), the policy's
        :meth:`~csws.standard.WarningSpeedPolicy.warning_speeds_one_kmh` remembered per radius and column:
        a vehicle meets the same curve parts, at their same radii, update after update."""
        if not (isinstance(radius_m, float) and radius_m > 0):
            return self.policy.warning_speeds_one_kmh(radius_m, column_index)
        remembered = self._warning_speeds_one
        key = (radius_m, column_index)
        speeds_kmh = remembered.get(key)
        if speeds_kmh is None:
            if len(remembered) >= WARNING_SPEEDS_REMEMBERED:
                remembered.clear()
            speeds_kmh = remembered[key] = self.policy.warning_speeds_one_kmh(radius_m, column_index)
        return speeds_kmh

    @cached_property
    def _warning_speeds_one(self) -> dict[tuple[float, int], tuple[float, float]]:
        """The warning speeds :meth:`warning_speeds_one_kmh` found, by (radius, column)."""
        return {}
