"""The exact profile is the profile: road chains whose lanes have an exact κ(σ) read it instead of the fit.

A road chain (:mod:`csws.road.chains`) is the lanes a road continues on, stitched into one
polyline. Where a network has an exact-curvature file (:mod:`csws.opendrive.exact`), each lane
of a chain that has an exact κ(σ) gives the chain its parts, placed at the lane's stretch of the
chain (σ scaled to the shape's length, which netconvert's sampling makes shorter by parts per
million); the lanes without one (internal lanes of a few metres netconvert made at junctions and
section joints) are bridged by one linear part between the curvatures either side. Such a chain
is not fitted at all (:func:`given_exact_profiles`, given to :func:`csws.road.chains.fit_road_chains`):
it reads only its own profile, and names its curves after its road's reference lane's, as the
lanes of a fitted road share one curve id. The curve index, paths, the look-ahead and the warning
all follow from it unchanged.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from csws.curvature import RadiusProfile, profile_along
from csws.road.chains import GivenProfile, LaneCurve

from .exact import ExactLane, exact_path, read_exact

if TYPE_CHECKING:
    from csws.road.roadmap import RoadMap

__all__ = ["BRIDGE_M", "exact_lanes_beside", "given_exact_profiles", "curve_slopes", "slopes_by_curve_id"]


def exact_lanes_beside(net_path: str | Path) -> dict[str, ExactLane] | None:
    """The exact curvature kept beside network ``net_path`` (``NAME.kappa.json``), None where there is none."""
    path = exact_path(net_path)
    return read_exact(path) if path.is_file() else None


#: The longest stretch of a chain without exact curvature its exact profile bridges, m: the internal lanes
#: netconvert makes where lane sections or roads join are a few metres. A chain with a longer one (a lane the
#: import left to the fit) is fitted whole.
BRIDGE_M = 20.0

#: A chain's parts as (end s, κ at start, κ at end); None for a lane's stretch still to bridge.
_Parts = list[tuple[float, float, float] | None]


def _exact_parts(lane: ExactLane, start_s: float, length_m: float) -> list[tuple[float, float, float]]:
    """(end s, κ at start, κ at end) of a lane's exact parts on its stretch of a chain, σ scaled to the stretch."""
    scale = length_m / lane.length_m
    ends = start_s + lane.bounds[1:] * scale
    return list(zip(ends.tolist(), lane.start_curvature.tolist(), lane.end_curvature.tolist(), strict=True))


def _bridged(parts: _Parts, gap_ends: list[float]) -> list[tuple[float, float, float]]:
    """The parts with each stretch without exact curvature (None, ending at the next of ``gap_ends``) one linear
    part from the curvature where the part before ends to where the one after starts (a lone neighbour's on
    either side: constant)."""
    filled: list[tuple[float, float, float]] = []
    ends = iter(gap_ends)
    for index, part in enumerate(parts):
        if part is not None:
            filled.append(part)
            continue
        after = next((p for p in parts[index + 1 :] if p is not None), None)
        k0 = filled[-1][2] if filled else (after[1] if after else 0.0)
        filled.append((next(ends), k0, after[1] if after else k0))
    return filled


def given_exact_profiles(lane_ids: Sequence[str], exact: Mapping[str, ExactLane]) -> GivenProfile:
    """The exact profile of every road chain with a lane of exact curvature (see the module), for
    :func:`csws.road.chains.fit_road_chains` to take instead of fitting it; None for the others and for
    chains with a stretch without exact curvature longer than :data:`BRIDGE_M`."""

    def profile(
        members: np.ndarray, xy: np.ndarray, lane_start_s: np.ndarray, lane_length_m: np.ndarray
    ) -> RadiusProfile | None:
        lanes = [exact.get(lane_ids[lane]) for lane in members.tolist()]
        if all(lane is None for lane in lanes):
            return None
        parts: _Parts = []
        gap_ends: list[float] = []
        for lane, start_s, length_m in zip(lanes, lane_start_s.tolist(), lane_length_m.tolist(), strict=True):
            if lane is not None and lane.length_m > 0:
                parts.extend(_exact_parts(lane, start_s, length_m))
            elif length_m > BRIDGE_M:
                return None
            else:
                parts.append(None)
                gap_ends.append(start_s + length_m)
        filled = _bridged(parts, gap_ends)
        return profile_along(xy, filled)

    return profile


def _lane_samples(lane: ExactLane, sumo_length_m: float, from_pos_m: float, to_pos_m: float) -> np.ndarray:
    """Indices of a lane's grade and superelevation samples between two SUMO lane positions."""
    scale = lane.length_m / sumo_length_m if sumo_length_m > 0 else 1.0
    inside = (lane.profile_s >= from_pos_m * scale - 1e-9) & (lane.profile_s <= to_pos_m * scale + 1e-9)
    if not inside.any():  # a curve shorter than the sample spacing: the nearest sample
        middle = 0.5 * (from_pos_m + to_pos_m) * scale
        inside[int(np.argmin(np.abs(lane.profile_s - middle)))] = True
    return np.flatnonzero(inside)


def curve_slopes(
    exact: Mapping[str, ExactLane], lane_lengths_m: Mapping[str, float], lane_curve: LaneCurve
) -> dict[str, float] | None:
    """The mean grade along a curve and its mean superelevation toward the inside of the curve, per cent.

    Information next to the standard's figures (docs/road-model.md): grade positive uphill in the
    driving direction; superelevation positive where the road falls toward the inside of the turn
    (the banking that helps). None where the curve's lanes have no exact data.
    """
    if lane_curve.end_lane_id == lane_curve.lane_id:
        ends = [(lane_curve.lane_id, lane_curve.start_pos_m, lane_curve.end_pos_m)]
    else:
        ends = [
            (lane_curve.lane_id, lane_curve.start_pos_m, math.inf),
            (lane_curve.end_lane_id, 0.0, lane_curve.end_pos_m),
        ]
    grades, rolls = [], []
    for lane_id, from_pos_m, to_pos_m in ends:
        lane = exact.get(lane_id)
        if lane is None:
            continue
        rows = _lane_samples(lane, lane_lengths_m[lane_id], from_pos_m, to_pos_m)
        grades.extend(lane.grade_pct[rows].tolist())
        rolls.extend(lane.superelevation_pct[rows].tolist())
    if not grades:
        return None
    toward_inside = 1.0 if lane_curve.curve.direction == "right" else -1.0
    return {"grade_pct": float(np.mean(grades)), "superelevation_pct": toward_inside * float(np.mean(rolls))}


def slopes_by_curve_id(road_map: RoadMap) -> dict[str, dict[str, float]]:
    """The grade and superelevation of every curve of the road map by its id (the curve index's, junction curves
    included), for the answers that name curves by id; empty on a network without exact data.

    A road's curve has one id on all its lanes (:func:`csws.road.chains.road_curve_id`); its figures are those
    of the lane it is listed at, whose road shares the same elevation and cross slope.
    """
    found: dict[str, dict[str, float]] = {}
    if not road_map.exact_lanes:
        return found
    for lane_curve in road_map.curves(include_junctions=True):
        if lane_curve.curve_id not in found and (slopes := road_map.curve_slopes(lane_curve)) is not None:
            found[lane_curve.curve_id] = slopes
    return found
