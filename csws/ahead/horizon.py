"""Builds the road ahead of a vehicle as the warning reads it (its horizon from a lane) and its CPOIs (3.11).

A :class:`Horizon` is the stitched, profiled path from the start of a lane with the parts
of its curves; :class:`PathAhead` (one vehicle) and :class:`BatchAhead` (many, as flat
arrays) are the CPOIs a vehicle at a position on it has within S_LAD. :mod:`csws.ahead.lookahead`
builds and caches horizons. A CPOI is the first point of a part ahead of the vehicle; inside
a part the point under the vehicle counts (:func:`radius_under`), and a part stays a CPOI,
marked passed, for :data:`END_MARGIN_M` after its end (:mod:`csws.warning.release`).
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from functools import cached_property
from operator import attrgetter

import numpy as np

from csws.curvature import RadiusProfile
from csws.road.path import PathProfile
from csws.warning.rules import CurvaturePointOfInterest, PathKind

__all__ = [
    "END_MARGIN_M",
    "Horizon",
    "PathAhead",
    "BatchAhead",
    "PartPool",
    "is_cpoi",
    "radius_at_end",
    "radius_under",
]


@dataclass(frozen=True)
class Horizon:
    """The road ahead from the start of one lane, with every curve part on it.

    One horizon serves every vehicle whose lanes ahead are its lanes (whatever its route
    beyond them), wherever it is on the first lane, as long as S_LAD fits; horizons are
    cached (:mod:`csws.ahead.lookahead`).

    Attributes
    ----------
    path
        The stitched path, starting at the first lane's start.
    kind
        ``route`` when the path follows the route, else ``predicted``.
    part_start_s, part_end_s, part_radius_m, part_index
        The constant-radius parts of the curves on the path (3.7, 3.8): start and end
        in path arc length, radius, index within the curve.
    part_end_radius_m
        The road's radius where each part ends, m: a spiral piece's radius changes along it
        (:func:`radius_under`); an arc's is its radius.
    part_curve_id
        The curve id of each part (``edge@position`` of the curve's start, the same on every lane of the road).
    """

    path: PathProfile
    kind: PathKind
    part_start_s: np.ndarray
    part_end_s: np.ndarray
    part_radius_m: np.ndarray
    part_index: np.ndarray
    part_curve_id: np.ndarray
    part_end_radius_m: np.ndarray

    @cached_property
    def parts(self) -> list[tuple[float, float, float, float, int, str]]:
        """Each part as plain values: start and end s, radius at start and end, index, curve id."""
        return list(
            zip(
                self.part_start_s.tolist(),
                self.part_end_s.tolist(),
                self.part_radius_m.tolist(),
                self.part_end_radius_m.tolist(),
                self.part_index.tolist(),
                self.part_curve_id.tolist(),
                strict=False,
            )
        )

    @cached_property
    def _first_lane(self) -> tuple[float, float]:
        """Position factor and shape length of the first lane."""
        return float(self.path.lane_position_factor[0]), float(self.path.lane_shape_length_m[0])

    def vehicle_s(self, lane_pos_m: float) -> float:
        """Path arc length of a lane position on the first lane, m."""
        factor, shape_length_m = self._first_lane
        return min(max(lane_pos_m / factor, 0.0), shape_length_m)


@dataclass(frozen=True)
class PathAhead:
    """The road ahead of one vehicle and the CPOIs on it.

    Attributes
    ----------
    horizon
        The cached road ahead from the start of the vehicle's lane.
    vehicle_s
        The vehicle's arc length along the path, m.
    lookahead_m
        S_LAD used, m.
    """

    horizon: Horizon
    vehicle_s: float
    lookahead_m: float

    @property
    def path(self) -> PathProfile:
        """The stitched path (lanes in driving order, polyline, radius profile)."""
        return self.horizon.path

    @property
    def kind(self) -> PathKind:
        """``route`` when the path follows the vehicle's route, else ``predicted``."""
        return self.horizon.kind

    @cached_property
    def _rows(self) -> np.ndarray:
        """The horizon's parts that are CPOIs (3.11)."""
        h = self.horizon
        return np.flatnonzero(is_cpoi(h.part_start_s, h.part_end_s, self.vehicle_s, self.lookahead_m))

    @property
    def cpoi_distance_m(self) -> np.ndarray:
        """Distance S from the vehicle to each CPOI, nearest first, m; 0 inside a part."""
        return np.maximum(self.horizon.part_start_s[self._rows] - self.vehicle_s, 0.0)

    @property
    def cpoi_passed(self) -> np.ndarray:
        """Whether the vehicle is beyond each CPOI's part (by at most :data:`END_MARGIN_M`)."""
        return self.horizon.part_end_s[self._rows] <= self.vehicle_s

    @property
    def cpoi_start_s(self) -> np.ndarray:
        """Path arc length where each CPOI's part starts, m (behind the vehicle when it is inside)."""
        return self.horizon.part_start_s[self._rows]

    @property
    def cpoi_radius_m(self) -> np.ndarray:
        """Radius of each CPOI, m: its part's, or the road's under the vehicle inside a part (:func:`radius_under`)."""
        h, rows = self.horizon, self._rows
        return radius_under(
            h.part_start_s[rows], h.part_end_s[rows], h.part_radius_m[rows], h.part_end_radius_m[rows], self.vehicle_s
        )

    @property
    def cpoi_part_index(self) -> np.ndarray:
        """Index of each CPOI's part within its curve."""
        return self.horizon.part_index[self._rows]

    @property
    def cpoi_curve_id(self) -> tuple[str, ...]:
        """The curve id of each CPOI."""
        return tuple(self.horizon.part_curve_id[self._rows])

    def cpoi_points(self) -> list[tuple[str, int, float, float, bool]]:
        """Each CPOI as plain values, nearest first: curve id, part index, distance S (m), radius
        (m) and whether it is passed, equal to the arrays above (:func:`is_cpoi` and :func:`radius_under` in
        floats: a horizon has a few parts, on which numpy's cost per call would be most of the work)."""
        vehicle_s, lookahead_m = self.vehicle_s, self.lookahead_m
        points = []
        for start_s, end_s, start_radius_m, end_radius_m, part_index, curve_id in self.horizon.parts:
            if not is_cpoi(start_s, end_s, vehicle_s, lookahead_m):
                continue
            length_m = end_s - start_s
            fraction = min(max((vehicle_s - start_s) / length_m if length_m > 0 else 0.0, 0.0), 1.0)
            radius_m = start_radius_m
            if fraction > 0:
                curvature = 1.0 / start_radius_m + (1.0 / end_radius_m - 1.0 / start_radius_m) * fraction
                radius_m = 1.0 / curvature if curvature else math.inf
            points.append((curve_id, part_index, max(start_s - vehicle_s, 0.0), radius_m, end_s <= vehicle_s))
        return points

    @property
    def cpois(self) -> tuple[CurvaturePointOfInterest, ...]:
        """The CPOIs as objects, nearest first."""
        return tuple(
            CurvaturePointOfInterest(curve_id, int(part), float(distance), float(radius))
            for curve_id, part, distance, radius in zip(
                self.cpoi_curve_id, self.cpoi_part_index, self.cpoi_distance_m, self.cpoi_radius_m, strict=False
            )
        )


@dataclass(frozen=True)
class BatchAhead:
    """The roads ahead of many vehicles, with all their CPOIs as flat arrays.

    Attributes
    ----------
    horizons
        Each vehicle's horizon.
    vehicle_s, lookahead_m
        ``(n,)`` each vehicle's path arc length and S_LAD, m.
    cpoi_vehicle
        ``(k,)`` the vehicle of each CPOI, ascending.
    cpoi_distance_m, cpoi_radius_m, cpoi_part_index, cpoi_curve_id, cpoi_passed
        ``(k,)`` as in :class:`PathAhead`.
    """

    horizons: list[Horizon]
    vehicle_s: np.ndarray
    lookahead_m: np.ndarray
    cpoi_vehicle: np.ndarray
    cpoi_distance_m: np.ndarray
    cpoi_radius_m: np.ndarray
    cpoi_part_index: np.ndarray
    cpoi_curve_id: np.ndarray
    cpoi_passed: np.ndarray

    def path_ahead(self, vehicle: int) -> PathAhead:
        """One vehicle's :class:`PathAhead`."""
        return PathAhead(self.horizons[vehicle], float(self.vehicle_s[vehicle]), float(self.lookahead_m[vehicle]))

    def paths_ahead(self) -> list[PathAhead]:
        """Every vehicle's :class:`PathAhead`, in order (:meth:`path_ahead` of each, without per-vehicle indexing)."""
        return list(map(PathAhead, self.horizons, self.vehicle_s.tolist(), self.lookahead_m.tolist()))


class _Column:
    """A flat array that grows by appending, its buffer doubled when full (appending costs what is
    appended, not what is already there)."""

    def __init__(self, dtype: type) -> None:
        self._buffer: np.ndarray = np.zeros(64, dtype=dtype)
        self._size = 0

    def extend(self, values: np.ndarray) -> None:
        """Append ``values``."""
        end = self._size + len(values)
        if end > len(self._buffer):
            grown = np.zeros(max(end, 2 * len(self._buffer)), dtype=self._buffer.dtype)
            grown[: self._size] = self._buffer[: self._size]
            self._buffer = grown
        self._buffer[self._size : end] = values
        self._size = end

    @property
    def values(self) -> np.ndarray:
        """What was appended, in order (a view)."""
        return self._buffer[: self._size]


class PartPool:
    """The curve parts of many horizons in flat arrays, each horizon in a slot: a batch of vehicles
    reads the parts of its horizons with one gather instead of joining each horizon's arrays.

    The pool only grows, and keeps every horizon it holds alive (so that a horizon's ``id``
    names its slot); its owner empties it with :meth:`clear` when it has grown too large.
    """

    _PART_FIELDS = ("part_start_s", "part_end_s", "part_radius_m", "part_index", "part_curve_id", "part_end_radius_m")

    def __init__(self) -> None:
        self.clear()

    def clear(self) -> None:
        """Forget every horizon; slots handed out before are no longer valid."""
        self.horizons: list[Horizon] = []
        self._slot_of: dict[int, int] = {}
        self._joined = 0
        self._first, self._count = _Column(np.intp), _Column(np.intp)
        self._position_factor, self._shape_length_m = _Column(float), _Column(float)
        self._parts = tuple(_Column(object if name == "part_curve_id" else float) for name in self._PART_FIELDS)

    def slot(self, horizon: Horizon) -> int:
        """The slot of ``horizon``, given it on first sight."""
        slot = self._slot_of.get(id(horizon))
        if slot is None:
            slot = self._slot_of[id(horizon)] = len(self.horizons)
            self.horizons.append(horizon)
        return slot

    def join(self) -> None:
        """Append the parts of the horizons given slots since the last call to the flat arrays."""
        new = self.horizons[self._joined :]
        if not new:
            return
        self._joined = len(self.horizons)
        counts = np.array([h.part_start_s.size for h in new], dtype=np.intp)
        self._first.extend(len(self._parts[0].values) + np.cumsum(counts) - counts)
        self._count.extend(counts)
        self._position_factor.extend(np.array([h.path.lane_position_factor[0] for h in new]))
        self._shape_length_m.extend(np.array([h.path.lane_shape_length_m[0] for h in new]))
        for column, name in zip(self._parts, self._PART_FIELDS, strict=False):
            column.extend(np.concatenate([getattr(h, name) for h in new]))

    @property
    def first(self) -> np.ndarray:
        """Each slot's first part in the part arrays."""
        return self._first.values

    @property
    def count(self) -> np.ndarray:
        """Each slot's number of parts."""
        return self._count.values

    @property
    def position_factor(self) -> np.ndarray:
        """Each slot's first lane's lane-position factor (SUMO length over shape length)."""
        return self._position_factor.values

    @property
    def shape_length_m(self) -> np.ndarray:
        """Each slot's first lane's shape length, m."""
        return self._shape_length_m.values

    @property
    def parts(self) -> tuple[np.ndarray, ...]:
        """Start and end s, radius, index in the curve, curve id and end radius of every part, slot after slot."""
        return tuple(column.values for column in self._parts)


def radius_at_end(profile: RadiusProfile, end_s: float) -> float:
    """The road's radius at arc length ``end_s``, approached from before it, m."""
    parts = profile.parts
    part = parts[min(max(bisect.bisect_left(parts, end_s, key=_start_s) - 1, 0), len(parts) - 1)]
    curvature = abs(part.curvature_at_one(end_s))
    return 1.0 / curvature if curvature > 0 else math.inf


#: A profile part's start, m (the key its parts are bisected by).
_start_s = attrgetter("start_s")


def radius_under(
    start_s: np.ndarray, end_s: np.ndarray, start_radius_m: np.ndarray, end_radius_m: np.ndarray, vehicle_s
) -> np.ndarray:
    """The radius of each CPOI for a vehicle at ``vehicle_s`` (a float or one per CPOI), m.

    A CPOI ahead is its part's first point, with its part's radius. Inside a part the point
    under the vehicle counts (6.2.1: the warning lasts while the road under the vehicle
    requires it): on an arc its radius; on a spiral piece the clothoid's radius there, its
    curvature linear between the piece's ends. On an exit spiral the piece's first point is
    behind the vehicle and tighter than the road under it: taken instead, it would keep
    requiring a warning the road no longer does.
    """
    length_m = end_s - start_s
    fraction = np.clip(
        np.divide(vehicle_s - start_s, length_m, out=np.zeros(len(length_m)), where=length_m > 0), 0.0, 1.0
    )
    curvature = 1.0 / start_radius_m + (1.0 / end_radius_m - 1.0 / start_radius_m) * fraction
    with np.errstate(divide="ignore"):
        return np.where(fraction > 0, 1.0 / curvature, start_radius_m)


#: A part stays among a vehicle's CPOIs, at distance 0 and marked passed, until the vehicle
#: is this far beyond its end, m: 6.1 no longer requires a warning there, but a level it
#: kept on may stay on (:mod:`csws.warning.release`), so that position noise at a curve's end
#: cannot switch the warning off and on again.
END_MARGIN_M = 1.0


def is_cpoi(part_start_s, part_end_s, vehicle_s, lookahead_m):
    """Whether each part is a CPOI (3.11) of a vehicle at ``vehicle_s``, or one it passed by at
    most :data:`END_MARGIN_M`: starting closer than the look-ahead distance S_LAD (3.9). Works on
    floats and on arrays alike."""
    return (part_end_s + END_MARGIN_M > vehicle_s) & (part_start_s < vehicle_s + lookahead_m)
