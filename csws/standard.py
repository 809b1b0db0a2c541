"""Holds what T/ITS 0091-2018 fixes in numbers: vehicle categories, the warning speeds and formula (1).

Everything the standard fixes numerically lives here: the vehicle categories of
GB/T 15089 and the column each falls in (Tables 1-2 merge M3, N and O), the warning
speeds V_w of Tables 1 (level 1) and 2 (level 2), and the warning distance S_w of
formula (1) in clause 6.1.

The warning speeds are kept in one policy object, :class:`WarningSpeedPolicy`, so a
fleet can tighten or loosen them without touching the rest of the system. Between
and beyond the table radii the policy follows the lateral acceleration
``a = v_w**2 / R`` that the tables imply: interpolated linearly in R between the
table radii and held constant outside them.

The core functions take and return numpy arrays (used by batch evaluation); the
public scalar functions validate their input and raise ``ValueError`` with a clear
message for negative, NaN or infinite values.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from enum import IntEnum, StrEnum
from functools import cached_property

import numpy as np

__all__ = [
    "G_MPS2",
    "DEFAULT_WARNING_RADIUS_M",
    "REACTION_TIME_S",
    "Category",
    "Column",
    "Level",
    "WarningSpeedPolicy",
    "DEFAULT_POLICY",
    "warning_distance",
    "warning_distance_m",
    "formula_1_m",
    "interp_one",
    "warning_speed",
    "kmh_to_mps",
    "mps_to_kmh",
]

#: Gravitational acceleration g of formula (1), m/s^2.
G_MPS2 = 9.8
#: The 0.8 s term of formula (1): the driver's reaction time, s.
REACTION_TIME_S = 0.8
#: Default warning curvature radius R_c (3.2), m. The standard leaves R_c to the system;
#: 300 m covers every warning speed the tables' test speeds can need (the level-1 warning
#: speed of M1, the highest, reaches 130 km/h at R = 295 m).
DEFAULT_WARNING_RADIUS_M = 300.0


class Category(StrEnum):
    """Vehicle category per GB/T 15089 (clause 1: M, N and O commercial vehicles)."""

    M1 = "M1"
    M2 = "M2"
    M3 = "M3"
    N = "N"
    O = "O"  # noqa: E741 - the standard's name

    @property
    def column(self) -> Column:
        """The column of Tables 1-2 (and 5-9) that applies to this category."""
        return _CATEGORY_COLUMN[self]

    @classmethod
    def parse(cls, value: str | Category) -> Category:
        """Category from its name (``"M1"``, ``"n"``, ...); ValueError names the valid ones.

        ``"M3_N_O"`` (the merged column of the tables) is read as M3, the first of its members.
        """
        if isinstance(value, Category):
            return value
        text = str(value).strip().upper()
        if text == Column.M3_N_O.value:
            return cls.M3
        try:
            return cls(text)
        except ValueError:
            valid = ", ".join(c.value for c in cls)
            raise ValueError(f"unknown vehicle category {value!r}; expected one of {valid}") from None


class Column(StrEnum):
    """A column of Tables 1-2: M1, M2, or M3, N and O merged."""

    M1 = "M1"
    M2 = "M2"
    M3_N_O = "M3_N_O"


_CATEGORY_COLUMN = {
    Category.M1: Column.M1,
    Category.M2: Column.M2,
    Category.M3: Column.M3_N_O,
    Category.N: Column.M3_N_O,
    Category.O: Column.M3_N_O,
}


class Level(IntEnum):
    """Warning level (5.1.2: the system warns at two levels; 0 means no warning)."""

    NONE = 0
    LEVEL_1 = 1
    LEVEL_2 = 2

    @classmethod
    def parse(cls, value: int | Level) -> Level:
        """A warning level 1 or 2; ValueError otherwise."""
        if value in (1, 2):
            return cls(int(value))
        raise ValueError(f"warning level must be 1 or 2, got {value!r}")


def kmh_to_mps(speed_kmh):
    """km/h to m/s (works on scalars and numpy arrays)."""
    return speed_kmh / 3.6


def mps_to_kmh(speed_mps):
    """m/s to km/h (works on scalars and numpy arrays)."""
    return speed_mps * 3.6


#: Table radii R of Tables 1 and 2, m.
TABLE_RADII_M: tuple[float, ...] = (40.0, 120.0, 200.0)
#: Table 1 (level 1) and Table 2 (level 2): V_w in km/h at TABLE_RADII_M, per column.
TABLE_WARNING_SPEEDS_KMH: Mapping[tuple[Column, Level], tuple[float, ...]] = {
    (Column.M1, Level.LEVEL_1): (48.0, 83.0, 107.0),
    (Column.M2, Level.LEVEL_1): (45.0, 78.0, 101.0),
    (Column.M3_N_O, Level.LEVEL_1): (39.0, 68.0, 87.0),
    (Column.M1, Level.LEVEL_2): (55.0, 96.0, 123.0),
    (Column.M2, Level.LEVEL_2): (50.0, 87.0, 113.0),
    (Column.M3_N_O, Level.LEVEL_2): (45.0, 78.0, 101.0),
}


@dataclass(frozen=True)
class WarningSpeedPolicy:
    """Warning speeds V_w per column and level, given at a set of radii.

    The defaults are Tables 1 and 2 of the standard. A fleet may override them (for
    example lower speeds for tankers) by passing its own ``speeds_kmh``; every entry
    must give one speed per radius in ``radii_m``.

    Attributes
    ----------
    radii_m
        Increasing radii R (m) at which the speeds are given.
    speeds_kmh
        ``(column, level) -> speeds`` in km/h, one per radius.
    """

    radii_m: tuple[float, ...] = TABLE_RADII_M
    speeds_kmh: Mapping[tuple[Column, Level], tuple[float, ...]] = field(
        default_factory=lambda: dict(TABLE_WARNING_SPEEDS_KMH)
    )

    def __post_init__(self) -> None:
        radii = np.asarray(self.radii_m, dtype=float)
        if radii.ndim != 1 or radii.size < 2 or np.any(~np.isfinite(radii)) or np.any(radii <= 0):
            raise ValueError("policy radii must be two or more finite positive numbers")
        if np.any(np.diff(radii) <= 0):
            raise ValueError("policy radii must be strictly increasing")
        missing = [
            f"{column.value} level {int(level)}"
            for level in _LEVELS
            for column in _COLUMNS
            if (column, level) not in self.speeds_kmh
        ]
        if missing:
            raise ValueError(f"policy has no warning speeds for {', '.join(missing)}: every column needs both levels")
        for key, speeds in self.speeds_kmh.items():
            if len(speeds) != radii.size:
                raise ValueError(f"policy entry {key} has {len(speeds)} speeds for {radii.size} radii")
            if not all(math.isfinite(v) and v > 0 for v in speeds):
                raise ValueError(f"policy entry {key} has a speed that is not a positive number")

    @cached_property
    def _interpolation_axis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One axis for all (level, column) rows: each row's radii shifted by its own offset.

        Returns the offset per (level, column), the shifted radii and the lateral
        accelerations a = v_w^2 / R at them, so that a single ``np.interp`` interpolates
        every CPOI of every column and level at once (6.1, Tables 1-2).
        """
        radii = np.asarray(self.radii_m, dtype=float)
        spacing = 10.0 ** np.ceil(np.log10(radii[-1] + 1.0))  # rows never overlap
        offsets = np.arange(len(_LEVELS) * len(_COLUMNS), dtype=float).reshape(len(_LEVELS), len(_COLUMNS)) * spacing
        accelerations = np.full(offsets.shape + radii.shape, np.nan)
        for (column, level), speeds in self.speeds_kmh.items():
            speeds_mps = kmh_to_mps(np.asarray(speeds, dtype=float))
            accelerations[_LEVELS.index(Level(level)), _COLUMNS.index(Column(column))] = speeds_mps**2 / radii
        return offsets, (offsets[..., None] + radii).ravel(), accelerations.ravel()

    def lateral_acceleration_mps2(self, column: Column, level: Level) -> np.ndarray:
        """The lateral acceleration a = v_w^2 / R (m/s^2) at each policy radius."""
        _, _, accelerations = self._interpolation_axis
        row = _LEVELS.index(level) * len(_COLUMNS) + _COLUMNS.index(column)
        return accelerations[row * len(self.radii_m) : (row + 1) * len(self.radii_m)]

    def warning_speeds_kmh(self, radius_m: np.ndarray, column_index: np.ndarray) -> np.ndarray:
        """V_w (km/h) of both levels for arrays of radii and column indices (into ``list(Column)``).

        Returns an array of shape ``(2, n)``: row 0 level 1, row 1 level 2; ``inf`` where
        the radius is infinite (a straight). The lateral acceleration of the policy is
        interpolated linearly in R between the policy radii and held constant outside
        them; at a policy radius the result is the policy's speed (rounded to 1e-9 km/h
        to absorb floating-point error).
        """
        radius = np.asarray(radius_m, dtype=float)
        offsets, axis, accelerations = self._interpolation_axis
        clipped = np.minimum(np.maximum(radius, self.radii_m[0]), self.radii_m[-1])
        accel = np.interp(offsets[:, column_index] + clipped, axis, accelerations)
        return _speed_from_acceleration_kmh(accel, radius)

    def warning_speeds_one_kmh(self, radius_m: float, column_index: int) -> tuple[float, float]:
        """V_w (km/h) of both levels at one radius, in plain floats: :meth:`warning_speeds_kmh`'s
        table look-up and formula on one value, so the result is the same to the bit at a fraction
        of numpy's cost per call."""
        if math.isinf(radius_m):
            return math.inf, math.inf
        offsets, axis, accelerations = self._interpolation_lists
        clipped = min(max(radius_m, self.radii_m[0]), self.radii_m[-1])
        level_1, level_2 = (interp_one(offset[column_index] + clipped, axis, accelerations) for offset in offsets)
        return _speed_from_acceleration_kmh(level_1, radius_m), _speed_from_acceleration_kmh(level_2, radius_m)

    @cached_property
    def _interpolation_lists(self) -> tuple[list[list[float]], list[float], list[float]]:
        """:attr:`_interpolation_axis` as Python lists, for :meth:`warning_speeds_one_kmh`."""
        offsets, axis, accelerations = self._interpolation_axis
        return offsets.tolist(), axis.tolist(), accelerations.tolist()

    def warning_speed_kmh(self, radius_m: np.ndarray, column: Column, level: Level) -> np.ndarray:
        """V_w (km/h) of one column and level for an array of radii (see :meth:`warning_speeds_kmh`)."""
        radius = np.asarray(radius_m, dtype=float)
        column_index = np.full(radius.shape, _COLUMNS.index(column))
        speeds = self.warning_speeds_kmh(radius.ravel(), column_index.ravel())[_LEVELS.index(level)]
        return speeds.reshape(radius.shape)


_LEVELS = (Level.LEVEL_1, Level.LEVEL_2)
_COLUMNS = tuple(Column)


#: V_w is rounded to this many decimals of a km/h, to absorb floating-point error at the table radii.
_SPEED_DECIMALS = 9


def _speed_from_acceleration_kmh(acceleration_mps2, radius_m):
    """V_w = sqrt(a R) in km/h, rounded to :data:`_SPEED_DECIMALS` (floats or arrays, the same to the bit).

    ``np.round`` scales, rounds half to even and scales back; a float takes the same steps.
    """
    if isinstance(acceleration_mps2, float) and isinstance(radius_m, float):
        scale = 10.0**_SPEED_DECIMALS
        return round(mps_to_kmh(math.sqrt(acceleration_mps2 * radius_m)) * scale) / scale
    return np.round(mps_to_kmh(np.sqrt(acceleration_mps2 * radius_m)), _SPEED_DECIMALS)


def interp_one(x: float, xp: Sequence[float], fp: Sequence[float]) -> float:
    """``np.interp`` of one float, with its arithmetic: ends held, a knot's own value at a knot.

    The one plain-float interpolation, for the one-vehicle path: ``np.interp`` costs more per
    call than the whole look-up, and this gives its result to the bit.
    """
    j = bisect.bisect_right(xp, x) - 1
    if j < 0:
        return fp[0]
    if j >= len(xp) - 1 or xp[j] == x:
        return fp[j]
    return (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j]) * (x - xp[j]) + fp[j]


#: The standard's own warning speeds (Tables 1 and 2).
DEFAULT_POLICY = WarningSpeedPolicy()


def _require_finite_non_negative(name: str, value: float) -> float:
    """``value`` as a float, or ValueError naming ``name`` when it is NaN, infinite or negative."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(number):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    if number < 0:
        raise ValueError(f"{name} must not be negative, got {value!r}")
    return number


def warning_speed(
    radius_m: float,
    category: str | Category,
    level: int | Level,
    policy: WarningSpeedPolicy = DEFAULT_POLICY,
) -> float:
    """Warning speed V_w in km/h for a curvature point of radius ``radius_m`` (6.1, Tables 1-2).

    Parameters
    ----------
    radius_m
        Radius of curvature R in metres, > 0; ``inf`` (a straight) gives ``inf``.
    category
        Vehicle category, M1, M2, M3, N or O (M3, N and O share a column).
    level
        Warning level, 1 (Table 1) or 2 (Table 2).
    policy
        The thresholds; by default the standard's tables.

    Returns
    -------
    float
        V_w in km/h: the table value at R = 40, 120 and 200 m, and between and beyond
        them the speed of the table's lateral acceleration at that radius.
    """
    try:
        radius = float(radius_m)
    except (TypeError, ValueError):
        raise ValueError(f"radius_m must be a number, got {radius_m!r}") from None
    if math.isnan(radius) or radius <= 0:
        raise ValueError(f"radius_m must be a positive number of metres, got {radius_m!r}")
    column = Category.parse(category).column
    return float(policy.warning_speed_kmh(np.asarray(radius), column, Level.parse(level)))


def formula_1_m(speed_mps, warning_speed_mps, g: float = G_MPS2):
    """Formula (1) as written, in SI: 0.8 v + (v^2 - v_w^2) / g, m (floats or arrays, any v)."""
    return REACTION_TIME_S * speed_mps + (speed_mps * speed_mps - warning_speed_mps * warning_speed_mps) / g


def warning_distance_m(speed_mps, warning_speed_mps, g: float = G_MPS2):
    """Formula (1) in SI: S_w = 0.8 v + (v^2 - v_w^2) / g, 0 where v < v_w (floats or arrays).

    A vehicle below the warning speed is not to be warned (6.1 warns when V >= V_w), so
    it has no warning area: its warning distance is 0 m. Two floats give a float, the
    array's value to the bit; anything else gives an array.
    """
    if isinstance(speed_mps, float) and isinstance(warning_speed_mps, float):
        return formula_1_m(speed_mps, warning_speed_mps, g) if speed_mps >= warning_speed_mps else 0.0
    speed = np.asarray(speed_mps, dtype=float)
    threshold = np.asarray(warning_speed_mps, dtype=float)
    return np.where(speed >= threshold, formula_1_m(speed, threshold, g), 0.0)


def warning_distance(speed_kmh: float, warning_speed_kmh: float, g: float = G_MPS2) -> float:
    """Warning distance S_w in metres, formula (1) of clause 6.1.

    ``S_w = V/3.6 * [0.8 + ((V/3.6)^2 - (V_w/3.6)^2) / ((V/3.6) * g)]``, that is
    ``0.8 v + (v^2 - v_w^2) / g`` with v in m/s: 0.8 s of reaction, then the distance to
    slow from v to v_w.

    Parameters
    ----------
    speed_kmh
        Vehicle speed V in km/h, >= 0.
    warning_speed_kmh
        Warning speed V_w in km/h, >= 0 (``inf`` for a straight).
    g
        Gravitational acceleration, m/s^2, > 0.

    Returns
    -------
    float
        S_w in metres; 0.0 when V < V_w, where no warning is due (6.1).

    Raises
    ------
    ValueError
        When a speed is negative or NaN, or ``g`` is not a positive finite number.
    """
    speed = _require_finite_non_negative("speed_kmh", speed_kmh)
    try:
        threshold = float(warning_speed_kmh)
    except (TypeError, ValueError):
        raise ValueError(f"warning_speed_kmh must be a number, got {warning_speed_kmh!r}") from None
    if math.isnan(threshold) or threshold < 0:
        raise ValueError(f"warning_speed_kmh must be a non-negative number, got {warning_speed_kmh!r}")
    gravity = _require_finite_non_negative("g", g)
    if gravity == 0:
        raise ValueError("g must be positive")
    return float(warning_distance_m(kmh_to_mps(speed), kmh_to_mps(threshold), gravity))
