"""The forward collision warning of queries that carry the forward sensor's objects, kept between queries.

The vehicles of a round (each at most once, :mod:`service.answers`) that sent ``objects`` are
answered by the library's fleet FCW (:func:`csws.fcw.fleet.update_fleet`, the same answers as one
:class:`csws.fcw.tracker.ForwardCollisionWarning` per vehicle), once per group of vehicles with the
same settings (:mod:`service.fcw_settings`). What each vehicle's FCW keeps between frames (the
state of Figure 2, the level's hold, the objects in the path and cutting in, the last target) comes
from its session and goes back into it (:class:`service.sessions.FcwMemory`), so the hysteresis
holds across queries whichever worker answers them.

The path is predicted from the curvature of the road ahead where the curve warning looked ahead
for the vehicle (its horizon's curvature profile, from the knots where its slope changes), else from the
yaw rate.
A frame's time is the query's ``timestamp_s``, else the time the round is answered; a query not
after the vehicle's last frame is answered from the kept memory and changes nothing of it.
"""

from __future__ import annotations

import itertools
import math
import operator
from collections.abc import Sequence
from typing import Any, cast

import numpy as np

from csws.ahead.horizon import PathAhead
from csws.fcw.fleet import UNKNOWN_LANE, FleetEgo, FleetFrame, FleetMemory, FleetObjects, FleetPaths, update_fleet
from csws.fcw.settings import FcwSettings
from csws.fcw.state import FCW_STATES, STANDBY
from csws.standard import kmh_to_mps

from .decoding import DecodedQuery
from .sessions import FcwMemory

__all__ = ["object_fcw"]

#: A new vehicle's memory: standby, nothing held, no frame yet.
NEW_MEMORY = FcwMemory(STANDBY, 0, -math.inf, -math.inf)
_ID_BITS = 32
#: The contract's text of each FCW state code.
_STATE_VALUES = [state.value for state in FCW_STATES]
#: The fields of an object that may be left out (None).
_OPTIONAL_FIELDS = frozenset({"accel_mps2", "relative_accel_mps2", "lane"})
#: A knot of the map path's curvature profile is dropped where the slope changes by less than this, 1/m^2:
#: over the 200 m of the range that moves the path across by at most 200^3 / 6 times it (about 1 mm).
SLOPE_TOLERANCE_1PM2 = 1e-9


def object_fcw(
    queries: Sequence[DecodedQuery],
    settings: Sequence[FcwSettings],
    memories: Sequence[FcwMemory | None],
    paths: Sequence[PathAhead | None],
    now_s: float,
) -> tuple[list[dict[str, Any]], list[FcwMemory]]:
    """The contract's FcwAnswer of each query (of distinct vehicles, each with objects), and each vehicle's memory.

    Parameters
    ----------
    queries
        The queries, each with ``objects``.
    settings
        Each vehicle's FCW settings (its fleet's for its category).
    memories
        What each vehicle's FCW kept, None for one never queried with objects.
    paths
        The curve warning's path ahead of each vehicle, None where it did not look ahead.
    now_s
        The time of the frames of queries without a ``timestamp_s``, s.
    """
    answers: list[dict[str, Any]] = [{}] * len(queries)
    kept: list[FcwMemory] = [NEW_MEMORY] * len(queries)
    groups: dict[int, list[int]] = {}
    for row, own in enumerate(settings):
        groups.setdefault(id(own), []).append(row)
    for rows in groups.values():
        group_answers, group_kept = _group(
            [queries[r] for r in rows],
            settings[rows[0]],
            [memories[r] or NEW_MEMORY for r in rows],
            [paths[r] for r in rows],
            now_s,
        )
        for row, answer, memory in zip(rows, group_answers, group_kept, strict=True):
            answers[row], kept[row] = answer, memory
    return answers, kept


def _ego(queries: Sequence[DecodedQuery]) -> FleetEgo:
    """The subjects as columns: speed, acceleration, yaw rate (rad/s, NaN where not given), brake, turn signal."""
    yaw_dps = [math.nan if q.yaw_rate_dps is None else q.yaw_rate_dps for q in queries]
    return FleetEgo.of(
        kmh_to_mps(np.array([q.speed_kmh for q in queries])),
        [q.accel_mps2 for q in queries],
        np.radians(yaw_dps),
        braking=[q.braking for q in queries],
        turn_signal=[q.turn_signal for q in queries],
    )


def _column(objects: Sequence[Any], name: str) -> np.ndarray:
    """One field of all objects as floats (None, where not given, as NaN)."""
    values = map(operator.attrgetter(name), objects)
    if name in _OPTIONAL_FIELDS:  # NaN for None in Python: numpy converts a list holding None twice as slowly
        return np.fromiter([math.nan if value is None else value for value in values], dtype=float, count=len(objects))
    return np.fromiter(values, dtype=float, count=len(objects))


def _objects(queries: Sequence[DecodedQuery]) -> FleetObjects:
    """The objects of all queries as flat columns, each with its query's row (an object's own acceleration
    is 0 where neither it nor the relative one is given)."""
    listed = [query.objects or () for query in queries]
    flat = list(itertools.chain.from_iterable(listed))
    own_accel, relative_accel = _column(flat, "accel_mps2"), _column(flat, "relative_accel_mps2")
    relative = ~np.isnan(relative_accel)
    lane = _column(flat, "lane")
    return FleetObjects.of(
        np.repeat(np.arange(len(queries)), [len(objects) for objects in listed]),
        _column(flat, "id").astype(np.int64),
        _column(flat, "x_m"),
        _column(flat, "y_m"),
        _column(flat, "relative_speed_mps"),
        np.where(relative, relative_accel, np.nan_to_num(own_accel)),
        relative,
        _column(flat, "width_m"),
        np.where(np.isnan(lane), UNKNOWN_LANE, lane).astype(np.int64),
    )


def _knots(path: PathAhead) -> tuple[np.ndarray, np.ndarray]:
    """The knots of a horizon's curvature profile where its slope changes (the first of repeated arc lengths
    kept, as :func:`csws.fcw.path.path_curvature_ahead` does): the same piecewise linear curvature."""
    profile = path.path.profile
    s_m, kappa = np.asarray(profile.s, dtype=float), np.asarray(profile.curvature, dtype=float)
    distinct = np.concatenate(([True], np.diff(s_m) > 0.0))
    s_m, kappa = s_m[distinct], kappa[distinct]
    slope = np.diff(kappa) / np.diff(s_m)
    bend = np.abs(np.diff(slope)) > SLOPE_TOLERANCE_1PM2
    keep = np.concatenate(([True], bend, [True])) if s_m.size > 1 else np.ones(1, dtype=bool)
    return s_m[keep], kappa[keep]


def _paths(paths: Sequence[PathAhead | None], range_m: float) -> FleetPaths | None:
    """The map paths of the vehicles that have one, as flat knots grouped by row; None without any.

    Each is the curvature of the road ahead from the vehicle's front over ``range_m``, as
    :func:`csws.fcw.path.path_curvature_ahead` gives it, from the knots where its slope changes
    (:func:`_knots`) and a last knot at ``range_m``; the vehicles on one horizon in one pass.
    """
    by_horizon: dict[int, list[int]] = {}
    for row, ahead in enumerate(paths):
        if ahead is not None:
            by_horizon.setdefault(id(ahead.horizon), []).append(row)
    if not by_horizon:
        return None
    owners, s_parts, kappa_parts = [], [], []
    for rows in by_horizon.values():
        knot_s, knot_kappa = _knots(cast(PathAhead, paths[rows[0]]))
        front = np.array([cast(PathAhead, paths[row]).vehicle_s for row in rows])
        first = np.searchsorted(knot_s, front, side="right")
        counts = np.searchsorted(knot_s, front + range_m, side="left") - first
        inner = np.repeat(first - np.cumsum(counts) + counts, counts) + np.arange(counts.sum())
        ends = np.stack([front, front + range_m], axis=1)
        end_kappa = np.interp(ends, knot_s, knot_kappa)
        owner = np.concatenate([np.arange(len(rows)), np.repeat(np.arange(len(rows)), counts), np.arange(len(rows))])
        s_all = np.concatenate([ends[:, 0], knot_s[inner], ends[:, 1]]) - front[owner]
        kappa_all = np.concatenate([end_kappa[:, 0], knot_kappa[inner], end_kappa[:, 1]])
        order = np.lexsort((s_all, owner))
        owners.append(np.asarray(rows, dtype=np.int64)[owner[order]])
        s_parts.append(s_all[order])
        kappa_parts.append(kappa_all[order])
    owner_all = np.concatenate(owners)
    order = np.argsort(owner_all, kind="stable")
    return FleetPaths(owner_all[order], np.concatenate(s_parts)[order], np.concatenate(kappa_parts)[order])


def _keys(id_lists: Sequence[tuple[int, ...]]) -> np.ndarray:
    """The sorted keys (row, id) of each row's ids, as :class:`csws.fcw.fleet.FleetMemory` holds them."""
    counts = np.fromiter(map(len, id_lists), dtype=np.int64, count=len(id_lists))
    ids = np.fromiter(itertools.chain.from_iterable(id_lists), dtype=np.int64, count=int(counts.sum()))
    return np.sort((np.repeat(np.arange(len(id_lists), dtype=np.int64), counts) << _ID_BITS) | ids)


def _ids_by_row(keys: np.ndarray, rows: int) -> list[tuple[int, ...]]:
    """Each row's ids of sorted keys (row, id)."""
    bounds = np.searchsorted(keys >> _ID_BITS, np.arange(rows + 1)).tolist()
    ids = (keys & ((1 << _ID_BITS) - 1)).tolist()
    return [tuple(ids[start:end]) for start, end in itertools.pairwise(bounds)]


def _memory(memories: Sequence[FcwMemory], time_s: np.ndarray) -> tuple[FleetMemory, np.ndarray]:
    """The fleet memory of the vehicles, and which frames are not after the last one (stale: they
    are evaluated from the memory as if it had no last time, and change nothing of it)."""
    last = np.array([m.last_time_s for m in memories])
    stale = time_s <= last
    memory = FleetMemory(
        np.array([m.state for m in memories], dtype=np.int8),
        np.array([m.held_level for m in memories], dtype=np.int8),
        np.array([m.hold_until_s for m in memories]),
        np.where(stale, -math.inf, last),
        _keys([m.in_path_ids for m in memories]),
        _keys([m.cut_in_ids for m in memories]),
    )
    return memory, stale


def _group(
    queries: Sequence[DecodedQuery],
    settings: FcwSettings,
    memories: Sequence[FcwMemory],
    paths: Sequence[PathAhead | None],
    now_s: float,
) -> tuple[list[dict[str, Any]], list[FcwMemory]]:
    """:func:`object_fcw` of vehicles with the same settings."""
    time_s = np.array([now_s if q.timestamp_s is None else q.timestamp_s for q in queries])
    memory, stale = _memory(memories, time_s)
    frame, kept = update_fleet(
        settings, memory, time_s, _ego(queries), _objects(queries), _paths(paths, settings.range_m)
    )
    answers = _answers(frame)
    in_path, cut_in = _ids_by_row(kept.in_path_keys, len(queries)), _ids_by_row(kept.cut_in_keys, len(queries))
    columns = zip(
        kept.state.tolist(),
        kept.held_level.tolist(),
        kept.hold_until_s.tolist(),
        kept.last_time_s.tolist(),
        in_path,
        cut_in,
        (answer["target_id"] for answer in answers),
        stale.tolist(),
        memories,
        strict=True,
    )
    new = [old if was_stale else FcwMemory(*values) for *values, was_stale, old in columns]
    return answers, new


def _json_values(values: np.ndarray) -> list[Any]:
    """Numbers for JSON, as Python floats or ints: None where NaN, infinite or (ids) negative."""
    absent = ~np.isfinite(values) if values.dtype.kind == "f" else values < 0
    listed = values.astype(object)
    listed[absent] = None
    return cast(list[Any], listed.tolist())


def _answers(frame: FleetFrame) -> list[dict[str, Any]]:
    """The contract's FcwAnswer of each vehicle of a frame."""
    columns = zip(
        frame.state.tolist(),
        frame.level.tolist(),
        _json_values(frame.ttc_s),
        _json_values(frame.ettc_s),
        _json_values(frame.a_req_mps2),
        _json_values(frame.target_id),
        _json_values(frame.clearance_m),
        strict=True,
    )
    return [
        {
            "state": _STATE_VALUES[state],
            "level": level,
            "ttc_s": ttc,
            "ettc_s": ettc,
            "a_req_mps2": a_req,
            "target_id": target,
            "clearance_m": clearance,
        }
        for state, level, ttc, ettc, a_req, target, clearance in columns
    ]
