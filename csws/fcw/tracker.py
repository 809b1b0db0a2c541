"""The forward collision warning of a vehicle from its sensor's object list, frame by frame (GB/T 33577-2017).

:class:`ForwardCollisionWarning` is one vehicle's system: one :meth:`~ForwardCollisionWarning.update`
a frame with the subject's motion and the objects (:mod:`csws.fcw.objects`), in plain floats.
:func:`update_fleet` is the same for many vehicles at once in numpy arrays, giving the same answers
to the bit; both go through the same formulas (:mod:`csws.fcw.physics`, :mod:`csws.fcw.path`,
:mod:`csws.fcw.objects`). Each frame:

1. the state (4.3, Figure 2 with its delta); only an active system assesses objects;
2. the path's curvature: the map's profile where given (and no turn signal), else the curvature
   given, else yaw rate / speed;
3. every object in the path (the sensor's lane, else within the corridor of the predicted path),
   except a faster cut-in (4.5.5 c), is assessed: a_req of formula (4) for each; the target is the
   most demanding (the highest level its thresholds require after 4.5.5, so an object whose warning
   4.5.5 e suppresses does not hide one that needs it, then the highest a_req, ties the nearest;
   every a_req below the preliminary threshold
   ties, so without a threat the target is the nearest, 3.7), so the vehicle a cut-out reveals is
   the target in the frame the lead leaves the path (4.4.3, 4.7.3);
4. the level the target requires (:func:`csws.fcw.physics.warning_level`: 4.5.5 a and e);
5. the level shown, with a short hold (:func:`csws.fcw.objects.hold_level`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from csws.fcw.objects import EgoMotion, FcwFrame, SensorObject, cut_in, hold_level, in_path
from csws.fcw.path import (
    CurvatureTable,
    PathCurvature,
    equivalent_curvature_1pm,
    offset_from_circle_m,
    path_table,
    yaw_path_curvature_1pm,
)
from csws.fcw.physics import a_req_core, ettc_core, ttc_core, warning_level
from csws.fcw.settings import FcwSettings
from csws.fcw.state import ACTIVE, FCW_STATES, STANDBY, fcw_state_code

__all__ = ["ForwardCollisionWarning", "ego_curvature_1pm"]

#: The chosen object of a frame: the object, the level it requires, its offset from the path, TTC, ETTC, a_req.
Assessed = tuple[SensorObject, int, float, float, float, float]


def ego_curvature_1pm(speed_mps: float, yaw_rate_rps: float | None, curvature_1pm: float | None) -> float:
    """The predicted path's curvature without a map: the one given, else yaw rate / speed, else 0 (straight)."""
    if curvature_1pm is not None:
        return curvature_1pm
    return 0.0 if yaw_rate_rps is None else yaw_path_curvature_1pm(speed_mps, yaw_rate_rps)


class ForwardCollisionWarning:
    """One vehicle's forward collision warning, kept between frames (state, level hold, objects in the path).

    Parameters
    ----------
    settings
        Its thresholds (e.g. ``FcwSettings.for_category("M1")``).
    """

    def __init__(self, settings: FcwSettings = FcwSettings()) -> None:
        self.settings = settings
        self.state_code = STANDBY
        self.held_level = 0
        self.hold_until_s = -math.inf
        self.in_path_ids: frozenset[int] = frozenset()
        self.cut_in_ids: frozenset[int] = frozenset()
        self.last_time_s = -math.inf
        self._table: tuple[PathCurvature, CurvatureTable] | None = None

    def update(self, time_s: float, ego: EgoMotion, objects: Sequence[SensorObject]) -> FcwFrame:
        """The answer for one frame at ``time_s`` (s, increasing) with the subject ``ego`` and the ``objects``."""
        number = type(time_s) is float or isinstance(time_s, float | int)
        if not (number and math.isfinite(time_s) and time_s > self.last_time_s):
            raise ValueError(f"time_s must be finite and increase from frame to frame, got {time_s!r}")
        if len({obj.id for obj in objects}) != len(objects):
            ids = [obj.id for obj in objects]
            raise ValueError(f"objects: duplicate object ids {sorted({i for i in ids if ids.count(i) > 1})}")
        self.last_time_s = time_s
        s = self.settings
        state = fcw_state_code(self.state_code, ego.speed_mps, ego.switched_on, ego.sensor_ok, ego.forward_gear, s)
        self.state_code = state
        if state != ACTIVE:
            self.held_level, self.hold_until_s = 0, -math.inf
            self.in_path_ids = self.cut_in_ids = frozenset()
            return FcwFrame(float(time_s), FCW_STATES[state], 0, 0, None)
        best, in_path_ids, cut_in_ids = self._assess(ego, objects)
        required, target = 0, None
        if best is not None:
            obj, required, offset_m, ttc, ettc, a_req = best
            target = (obj.id, obj.x_m, obj.relative_speed_mps, ttc, ettc, a_req, offset_m)
        holdable = -ego.accel_mps2 < s.collision_a_req_mps2
        level, self.held_level, self.hold_until_s = hold_level(
            required, self.held_level, self.hold_until_s, time_s, holdable, s.level_hold_s
        )
        self.in_path_ids, self.cut_in_ids = in_path_ids, cut_in_ids
        if target is None:
            return FcwFrame(float(time_s), FCW_STATES[state], level, required, None)
        return FcwFrame(float(time_s), FCW_STATES[state], level, required, *target)

    def _assess(
        self, ego: EgoMotion, objects: Sequence[SensorObject]
    ) -> tuple[Assessed | None, frozenset[int], frozenset[int]]:
        """The most demanding object in the path: the highest level its thresholds require, then the highest
        a_req, then the nearest (with its level, offset, TTC, ETTC and a_req); the ids in the path, and cutting in.

        The settings and the subject's motion are read once a frame, and an object's a_req, TTC and ETTC are
        computed only once it is in the path and not a cut-in (4.5.5 b, c), the only objects that can be chosen.
        """
        s = self.settings
        table = self._path_table(ego)
        kappa = ego_curvature_1pm(ego.speed_mps, ego.yaw_rate_rps, ego.curvature_1pm)
        a_sv, v_sv = ego.accel_mps2, ego.speed_mps
        lost_s = 0.0 if ego.braking else s.reaction_time_s + s.brake_response_s
        preliminary = s.preliminary_a_req_mps2
        best: Assessed | None = None
        best_rank: tuple[int, float] = (-1, -math.inf)
        inside_ids, cut_in_ids = [], []
        half_length_m, half_width_m, range_m = s.object_half_length_m, s.path_half_width_m, s.range_m
        was_in_path, was_cut_in = self.in_path_ids, self.cut_in_ids
        for obj in objects:
            x_m, y_m, v_r, lane = obj.x_m, obj.y_m, obj.relative_speed_mps, obj.lane
            centre_x_m = x_m + half_length_m
            if table is not None:
                kappa = equivalent_curvature_1pm(table, centre_x_m, y_m)
            offset_m = offset_from_circle_m(centre_x_m, y_m, kappa)
            if not in_path(x_m, offset_m, 0 if lane is None else lane, lane is not None, half_width_m, range_m):
                continue
            inside_ids.append(obj.id)
            was_in = obj.id in was_in_path
            if cut_in(True, v_r, was_in, was_in and obj.id in was_cut_in):
                cut_in_ids.append(obj.id)
                continue
            a_tv = obj.accel_mps2 + a_sv if obj.accel_is_relative else obj.accel_mps2
            a_req = a_req_core(x_m, v_r, a_tv, a_sv, lost_s, v_sv)
            ttc, ettc = ttc_core(x_m, v_r), ettc_core(x_m, v_r, a_tv - a_sv)
            level = warning_level(a_sv, ttc, ettc, a_req, s)
            rank = (level, preliminary if preliminary > a_req else a_req)
            if best is None or rank > best_rank or (rank == best_rank and x_m < best[0].x_m):
                best, best_rank = (obj, level, offset_m, ttc, ettc, a_req), rank
        return best, frozenset(inside_ids), frozenset(cut_in_ids)

    def _path_table(self, ego: EgoMotion) -> CurvatureTable | None:
        """The map path's table (kept while the same path comes again); None without one or with a turn signal."""
        if ego.map_path is None or ego.turn_signal != 0:
            return None
        if self._table is None or self._table[0] is not ego.map_path:
            self._table = (ego.map_path, path_table(ego.map_path))
        return self._table[1]
