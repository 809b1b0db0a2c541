"""The road model's types: the radius profile of a polyline and its parts (T/ITS 0091-2018, 3.2-3.8)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ProfilePart:
    """A stretch of constant curvature found in a polyline.

    Attributes
    ----------
    start_s, end_s
        Arc length of its ends along the polyline, m.
    curvature
        Signed curvature, 1/m, positive turning left.
    """

    start_s: float
    end_s: float
    curvature: float

    @property
    def radius_m(self) -> float:
        """Radius of the part, m; ``inf`` on a straight."""
        with np.errstate(over="ignore"):
            return float(np.divide(1.0, abs(self.curvature))) if self.curvature else math.inf

    @property
    def length_m(self) -> float:
        """Arc length of the part, m."""
        return self.end_s - self.start_s


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
        The parts of constant curvature the vertex values come from, in order, covering
        ``[0, s[-1]]``; empty when the polyline has no length.
    """

    s: np.ndarray
    curvature: np.ndarray
    radius: np.ndarray
    parts: tuple[ProfilePart, ...]


@dataclass(frozen=True)
class ConstantRadiusPart:
    """A constant-radius part of a curve: the whole of a single curve (3.7) or one of the
    directly joined curves of a multi curve (3.8).

    Attributes
    ----------
    start_s, end_s
        Arc length of its ends along the polyline, m.
    radius_m
        Its radius, m.
    """

    start_s: float
    end_s: float
    radius_m: float


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
        Its constant-radius parts: one for a single curve (3.7), two or more for a multi
        curve (3.8).
    """

    start_s: float
    end_s: float
    angle_deg: float
    direction: str
    min_radius_m: float
    parts: tuple[ConstantRadiusPart, ...]

    @property
    def is_multi(self) -> bool:
        """Whether this is a multi curve (3.8): two or more directly joined constant-radius curves."""
        return len(self.parts) >= 2


def _straight_profile(vertex_s: np.ndarray) -> RadiusProfile:
    """The profile of a polyline without length: straight at every vertex, no parts."""
    return RadiusProfile(vertex_s.copy(), np.zeros(len(vertex_s)), np.full(len(vertex_s), np.inf), ())


def _profile(vertex_s: np.ndarray, bounds: np.ndarray, curvature_of_part: np.ndarray) -> RadiusProfile:
    """The radius profile of one polyline from its part bounds (``[0, ..., end]``) and curvatures."""
    part = np.searchsorted(bounds[1:-1], vertex_s, side="right")
    curvature = curvature_of_part[part]
    magnitude = np.abs(curvature)
    radius = np.divide(1.0, magnitude, out=np.full(len(magnitude), np.inf), where=magnitude > 1.0 / np.finfo(float).max)
    edges = bounds.tolist()
    parts = tuple(map(ProfilePart, edges[:-1], edges[1:], curvature_of_part.tolist()))
    return RadiusProfile(vertex_s.copy(), curvature, radius, parts)
