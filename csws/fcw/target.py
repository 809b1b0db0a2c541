"""The FCW's system classes by curve (GB/T 33577-2017 4.6, Table 1) and the curve test's speed (5.5.3.2, formula (6)).

A system of class I, II or III detects a forward vehicle down to a curve radius of 500, 250 or
125 m; the curve test drives at formula (6)'s speed on a curve of the class's radius
(:mod:`csws.conformance.fcw`). Which vehicle is the target is the object FCW's (:mod:`csws.fcw.tracker`,
:mod:`csws.fcw.fleet`: the most demanding object in the predicted path).
"""

from __future__ import annotations

import math
from enum import Enum

__all__ = ["CurveClass", "curve_start_speed_mps"]


class CurveClass(Enum):
    """The system classes of Table 1 (4.6): the smallest radius on which a forward vehicle is
    detected, m, and the largest lateral acceleration of the curve test (formula (6)), m/s^2."""

    I = (500.0, 2.0)  # noqa: E741 (the standard's name)
    II = (250.0, 2.3)
    III = (125.0, 2.3)

    @property
    def min_radius_m(self) -> float:
        return self.value[0]

    @property
    def lateral_accel_mps2(self) -> float:
        return self.value[1]


def curve_start_speed_mps(curve_class: CurveClass, radius_m: float, max_speed_mps: float) -> float:
    """V_circle_start of the curve test (5.5.3.2, formula (6)): min(sqrt(a_lateral_max R), V_max)."""
    return min(math.sqrt(curve_class.lateral_accel_mps2 * radius_m), max_speed_mps)
