"""Target selection of the forward collision warning (GB/T 33577-2017 3.7, 4.4.3, 4.6, 4.7.3).

The target vehicle is the vehicle ahead on the subject's path that the subject reaches first
(3.7, 4.4.3, 4.7.3.1): of the vehicles in its path, the nearest along the path, since no
vehicle in the path can pass through the one ahead of it. A vehicle in an adjacent lane is
never the target (4.5.5, 4.7.3.2), also on a curve, where a straight sensor beam would see it
in front of the subject.

Candidates are therefore given in the subject's path coordinates: the distance along the
path to the candidate's rear and the candidate's lateral offset from the path's centre line
(in SUMO, lane position and lane, so a curve bends both with the road). A candidate is in
the path when its offset is within half a lane width; beyond the detection range, or on a
curve tighter than the system's class allows (4.6, Table 1: class I R >= 500 m, II >= 250 m,
III >= 125 m), it is not seen.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

import numpy as np

#: The path's radius may come out this much under the class's radius, as a share: an estimate
#: from two vehicles' headings (:mod:`csws.cosim.fcw`) on a curve of exactly the class's radius
#: (the curve test of 5.5.3.2) scatters by a few per cent.
RADIUS_TOLERANCE = 0.05

__all__ = ["RADIUS_TOLERANCE", "CurveClass", "TargetSettings", "curve_start_speed_mps", "select_targets"]


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


@dataclass(frozen=True)
class TargetSettings:
    """How far and how wide the system looks.

    Attributes
    ----------
    curve_class
        The class of Table 1: no target on a curve tighter than its radius.
    lane_width_m
        W_L: a candidate is in the path when its lateral offset is at most half of it
        (Table 3: the detection width at d_max is the lane width).
    range_m
        d_max, the detection range along the path, m (Table 2: V_max_rel T_max + V_max_rel^2 / (2 a_min)
        is 85.6 m with Annex A.5's values and 20 m/s; 200 m covers TTC 4 s at 50 m/s).
    """

    curve_class: CurveClass = CurveClass.III
    lane_width_m: float = 3.5
    range_m: float = 200.0

    def __post_init__(self) -> None:
        if not (self.lane_width_m > 0.0 and self.range_m > 0.0):
            raise ValueError("the lane width and the range must be positive")


def select_targets(
    subject_index: np.ndarray,
    path_distance_m: np.ndarray,
    lateral_offset_m: np.ndarray,
    path_radius_m: np.ndarray,
    subjects: int,
    settings: TargetSettings = TargetSettings(),
) -> np.ndarray:
    """The target of each subject among the candidates: per subject the candidate's index, or -1.

    Parameters
    ----------
    subject_index
        Whose candidate each one is, ``(m,)``: indices into ``range(subjects)``.
    path_distance_m
        Distance along the subject's path from its front to the candidate's rear, m ``(m,)``.
    lateral_offset_m
        The candidate's centre from the path's centre line, m ``(m,)`` (either sign).
    path_radius_m
        The radius of the path up to the candidate, m ``(m,)`` (``inf`` on a straight); a candidate
        is seen down to the class's radius less :data:`RADIUS_TOLERANCE`.
    subjects
        How many subjects.
    settings
        Range, lane width, class.
    """
    owner = np.asarray(subject_index, dtype=np.intp)
    distance = np.asarray(path_distance_m, dtype=float)
    seen = (
        (np.abs(np.asarray(lateral_offset_m, dtype=float)) <= settings.lane_width_m / 2.0)
        & (distance >= 0.0)
        & (distance <= settings.range_m)
        & (np.asarray(path_radius_m, dtype=float) >= settings.curve_class.min_radius_m * (1.0 - RADIUS_TOLERANCE))
    )
    targets = np.full(subjects, -1, dtype=np.intp)
    candidates = np.flatnonzero(seen)
    if candidates.size:
        # Nearest first; of each subject's candidates the first one in that order wins.
        ordered = candidates[np.lexsort((distance[candidates], owner[candidates]))]
        first = np.concatenate(([True], owner[ordered][1:] != owner[ordered][:-1]))
        targets[owner[ordered][first]] = ordered[first]
    return targets
