"""Defines the road model's types: the radius profile of a polyline and its parts (T/ITS 0091-2018, 3.2-3.8)."""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np


class ProfilePart(NamedTuple):
    """A stretch of a polyline whose curvature is constant (a straight or an arc) or
    changes linearly with arc length (a clothoid, the transition curve of road design).

    A named tuple rather than a dataclass: every path a vehicle meets is made of them, and a
    tuple is built in a fraction of the time.

    Attributes
    ----------
    start_s, end_s
        Arc length of its ends along the polyline, m.
    curvature
        Signed curvature at its start, 1/m, positive turning left.
    end_curvature
        Signed curvature at its end, 1/m; None where it is constant.
    """

    start_s: float
    end_s: float
    curvature: float
    end_curvature: float | None = None

    @property
    def final_curvature(self) -> float:
        """Signed curvature at the end of the part, 1/m."""
        return self.curvature if self.end_curvature is None else self.end_curvature

    @property
    def is_spiral(self) -> bool:
        """Whether the curvature changes along the part (a clothoid)."""
        return self.end_curvature is not None and self.end_curvature != self.curvature

    @property
    def radius_m(self) -> float:
        """Smallest radius on the part, m; ``inf`` on a straight."""
        largest = max(abs(self.curvature), abs(self.final_curvature))
        with np.errstate(over="ignore"):
            return float(np.divide(1.0, largest)) if largest else math.inf

    @property
    def length_m(self) -> float:
        """Arc length of the part, m."""
        return self.end_s - self.start_s

    def curvature_at(self, s: np.ndarray) -> np.ndarray:
        """Signed curvature at arc lengths ``s`` of the part (clipped to it), 1/m."""
        if not self.is_spiral or self.length_m <= 0:
            return np.full(np.shape(s), self.curvature)
        fraction = np.clip((np.asarray(s, dtype=float) - self.start_s) / self.length_m, 0.0, 1.0)
        return self.curvature + (self.final_curvature - self.curvature) * fraction

    def curvature_at_one(self, s: float) -> float:
        """:meth:`curvature_at` of one arc length, in plain floats (the same operations)."""
        if not self.is_spiral or self.length_m <= 0:
            return self.curvature
        fraction = min(max((s - self.start_s) / self.length_m, 0.0), 1.0)
        return self.curvature + (self.final_curvature - self.curvature) * fraction


@dataclass(frozen=True)
class RadiusProfile:
    """Curvature and radius along a polyline.

    Attributes
    ----------
    s
        Arc length along the polyline at each input vertex, m (``s[0] == 0``; a repeated
        vertex has the arc length of the one it repeats).
    curvature
        Signed curvature at each vertex, 1/m, positive turning left: that of the part the
        vertex lies in, or of the part starting at it when it is a knot.
    radius
        ``1 / |curvature|`` at each vertex, m; ``inf`` on straights.
    parts
        The parts (straights, arcs and clothoids: curvature piecewise linear in arc
        length) the vertex values come from, in order, covering ``[0, s[-1]]``; empty
        when the polyline has no length.
    """

    s: np.ndarray
    curvature: np.ndarray
    radius: np.ndarray
    parts: tuple[ProfilePart, ...]


@dataclass(frozen=True)
class ConstantRadiusPart:
    """A part of a curve taken at one radius: a curvature point of interest (3.11) at its
    start, standing for the road up to its end.

    On an arc it is the arc: the whole of a single curve (3.7) or one of the directly
    joined curves of a multi curve (3.8). On a clothoid it is a piece short enough that
    the warning speed V_w of every category and level changes along it by at most
    :data:`csws.curvature.curves.SPIRAL_PIECE_KMH`, taken at the radius of its start
    point: a real point of the road, so a warning it raises is one the road requires.

    Attributes
    ----------
    start_s, end_s
        Arc length of its ends along the polyline, m.
    radius_m
        Its radius, m: the arc's, or the road's radius at the piece's start.
    spiral
        Whether it is a piece of a clothoid (not an arc of its own).
    """

    start_s: float
    end_s: float
    radius_m: float
    spiral: bool = False


@dataclass(frozen=True)
class Curve:
    """A curve: a stretch whose radius is at most the warning curvature radius R_c.

    Attributes
    ----------
    start_s
        Curve start point (3.4): where the radius becomes <= R_c, m along the polyline.
    end_s
        Curve end point (3.5): where the radius becomes > R_c again (or the road turns
        the other way), m.
    angle_deg
        Curve angle (3.6): the central angle between start and end, degrees, unsigned.
    direction
        ``"left"`` or ``"right"``.
    min_radius_m
        The smallest radius in the curve, m.
    parts
        Its parts in order (see :class:`ConstantRadiusPart`): its arcs, one for a single
        curve (3.7), two or more for a multi curve (3.8), and the pieces of the clothoids
        that lead into, between and out of them.
    """

    start_s: float
    end_s: float
    angle_deg: float
    direction: str
    min_radius_m: float
    parts: tuple[ConstantRadiusPart, ...]

    @property
    def is_multi(self) -> bool:
        """Whether this is a multi curve (3.8): two or more joined constant-radius curves (arcs)."""
        return sum(not part.spiral for part in self.parts) >= 2


def straight_profile(vertex_s: np.ndarray) -> RadiusProfile:
    """The profile of a polyline without length: straight at every vertex, no parts."""
    return RadiusProfile(vertex_s.copy(), np.zeros(len(vertex_s)), np.full(len(vertex_s), np.inf), ())


def profile_from_parts(
    vertex_s: np.ndarray, bounds: np.ndarray, curvature_of_part: np.ndarray, end_curvature: np.ndarray | None = None
) -> RadiusProfile:
    """The radius profile of one polyline from its part bounds (``[0, ..., end]``) and the
    curvature at each part's start and end (``end_curvature`` None: constant parts)."""
    end_curvature = curvature_of_part if end_curvature is None else end_curvature
    part = np.searchsorted(bounds[1:-1], vertex_s, side="right")
    length = np.diff(bounds)[part]
    fraction = np.divide(vertex_s - bounds[part], length, out=np.zeros(len(vertex_s)), where=length > 0)
    curvature = curvature_of_part[part] + (end_curvature[part] - curvature_of_part[part]) * np.clip(fraction, 0.0, 1.0)
    magnitude = np.abs(curvature)
    radius = np.divide(1.0, magnitude, out=np.full(len(magnitude), np.inf), where=magnitude > 1.0 / np.finfo(float).max)
    edges = bounds.tolist()
    starts, ends = curvature_of_part.tolist(), end_curvature.tolist()
    parts = tuple(
        ProfilePart(a, b, k0, None if k1 == k0 else k1)
        for a, b, k0, k1 in zip(edges[:-1], edges[1:], starts, ends, strict=False)
    )
    return RadiusProfile(vertex_s.copy(), curvature, radius, parts)


def profile_along(xy: np.ndarray, parts: Iterable[tuple[float, float, float]]) -> RadiusProfile:
    """The radius profile of the polyline ``xy`` from its parts in order, each ``(end_s, start curvature, end
    curvature)`` from where the one before ended (the first from 0): a part that ends no later than the one
    before is left out, and the last is stretched to the polyline's end."""
    bounds, start_k, end_k = [0.0], [], []
    for end_s, k0, k1 in parts:
        if end_s > bounds[-1]:
            bounds.append(end_s)
            start_k.append(k0)
            end_k.append(k1)
    vertex_s = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))))
    bounds[-1] = max(bounds[-1], float(vertex_s[-1]))
    return profile_from_parts(vertex_s, np.array(bounds), np.array(start_k), np.array(end_k))
