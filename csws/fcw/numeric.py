"""Operations that take Python floats or numpy arrays and give the same value to the bit either way.

The forward collision warning of one vehicle runs on plain floats (numpy's cost per call would be
most of a frame), that of a fleet on arrays. Every formula is written once against these few
operations, so both forms compute the same IEEE operations in the same order: ``sqrt`` is correctly
rounded in both ``math`` and numpy, and no transcendental function (whose numpy and libm versions
may differ in the last bit) is used.

One vehicle's frame calls these some hundred times, so each tests first for the plain ``float``,
``int`` and ``bool`` it gets there (an exact type test, the cheapest dispatch) before the general case.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["where", "sqrt", "fmax", "fmin", "isfinite", "is_scalar"]


def is_scalar(value: Any) -> bool:
    """Whether ``value`` is a plain number or bool (not an array)."""
    return type(value) is float or isinstance(value, float | int | bool | np.bool_)


def where(condition: Any, if_true: Any, if_false: Any) -> Any:
    """``if_true`` where ``condition`` holds, else ``if_false`` (a bool picks one value; arrays as ``np.where``)."""
    if condition is True:
        return if_true
    if condition is False:
        return if_false
    if isinstance(condition, np.bool_):
        return if_true if condition else if_false
    return np.where(condition, if_true, if_false)


def sqrt(value: Any) -> Any:
    """The square root, correctly rounded (``math.sqrt`` for a float, ``np.sqrt`` for an array)."""
    return math.sqrt(value) if type(value) is float or isinstance(value, float | int) else np.sqrt(value)


def fmax(a: Any, b: Any) -> Any:
    """The larger of two values (elementwise for arrays); of two numbers the first unless the second is larger,
    as ``max``."""
    kind = type(a)
    if kind is type(b) and (kind is float or kind is int):
        return b if b > a else a
    return max(a, b) if is_scalar(a) and is_scalar(b) else np.fmax(a, b)


def fmin(a: Any, b: Any) -> Any:
    """The smaller of two values (elementwise for arrays); of two numbers the first unless the second is smaller,
    as ``min``."""
    kind = type(a)
    if kind is type(b) and (kind is float or kind is int):
        return b if b < a else a
    return min(a, b) if is_scalar(a) and is_scalar(b) else np.fmin(a, b)


def isfinite(value: Any) -> Any:
    """Whether a value is finite (elementwise for arrays)."""
    if type(value) is float:
        return math.isfinite(value)
    return math.isfinite(value) if isinstance(value, float | int) else np.isfinite(value)
