"""Curves (3.3-3.8) of a radius profile."""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from ..standard import DEFAULT_WARNING_RADIUS_M
from .profile import ConstantRadiusPart, Curve, ProfilePart, RadiusProfile

# --------------------------------------------------------------------------- curves


def _curve(parts: Sequence[ProfilePart]) -> Curve:
    """A curve made of consecutive parts that turn the same way."""
    angle_rad = sum(abs(p.curvature) * p.length_m for p in parts)
    return Curve(
        start_s=parts[0].start_s,
        end_s=parts[-1].end_s,
        angle_deg=math.degrees(angle_rad),
        direction="left" if parts[0].curvature > 0 else "right",
        min_radius_m=min(p.radius_m for p in parts),
        parts=tuple(ConstantRadiusPart(p.start_s, p.end_s, p.radius_m) for p in parts),
    )


def curves_from_profile(profile: RadiusProfile, warning_radius_m: float = DEFAULT_WARNING_RADIUS_M) -> list[Curve]:
    """The curves of a radius profile: maximal runs of parts turning the same way with a
    radius no larger than the warning curvature radius R_c.

    The curve start (3.4) is where the radius becomes <= R_c and the curve end (3.5) where
    it becomes > R_c again; a change of direction ends one curve and starts the next, so
    an S-bend is two curves. A run of several radii is a multi curve (3.8).

    Parameters
    ----------
    profile
        A profile from :func:`radius_profile` or :func:`radius_profiles`.
    warning_radius_m
        R_c (3.2), m, > 0.

    Returns
    -------
    list[Curve]
        In order along the polyline.
    """
    if not (math.isfinite(warning_radius_m) and warning_radius_m > 0):
        raise ValueError(f"warning radius must be a positive number of metres, got {warning_radius_m!r}")
    curves: list[Curve] = []
    run: list[ProfilePart] = []
    for part in profile.parts:
        in_curve = part.radius_m <= warning_radius_m and part.length_m > 0
        if run and not (in_curve and np.sign(part.curvature) == np.sign(run[0].curvature)):
            curves.append(_curve(run))
            run = []
        if in_curve:
            run.append(part)
    if run:
        curves.append(_curve(run))
    return curves
