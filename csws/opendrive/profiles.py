"""The exact profile is the profile: road chains whose lanes have an exact κ(σ) read it instead of the fit.

A road chain (:mod:`csws.road.chains`) is the lanes a road continues on, stitched into one
polyline. Where a network has an exact-curvature file (:mod:`csws.opendrive.exact`), each lane
of a chain that has an exact κ(σ) gives the chain its parts, placed at the lane's stretch of the
chain (σ scaled to the shape's length, which netconvert's sampling makes shorter by parts per
million); the lanes without one (internal lanes netconvert made at junctions and section
joints) keep the fitted parts of their stretch. The chain then reads only its own profile: the
curve index, paths, the look-ahead and the warning all follow from it unchanged.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from csws.curvature import RadiusProfile, profile_from_parts
from csws.road.chains import LaneCurve, RoadChains
from csws.road.sharing import Run

from .exact import ExactLane, exact_path, read_exact

if TYPE_CHECKING:
    from csws.road.roadmap import RoadMap

__all__ = ["exact_lanes_beside", "with_exact_profiles", "curve_slopes", "slopes_by_curve_id"]


def exact_lanes_beside(net_path: str | Path) -> dict[str, ExactLane] | None:
    """The exact curvature kept beside network ``net_path`` (``NAME.kappa.json``), None where there is none."""
    path = exact_path(net_path)
    return read_exact(path) if path.is_file() else None


def _lane_parts(chains: RoadChains, chain: int, lane: int, exact: ExactLane | None) -> list[tuple[float, float, float]]:
    """(end s, κ at start, κ at end) of the parts of one lane's stretch of its chain, in chain arc length."""
    start_s = float(chains.lane_start_s[lane])
    length_m = float(chains.lane_road_length_m[lane])
    if exact is not None and exact.length_m > 0:
        scale = length_m / exact.length_m
        ends = start_s + exact.bounds[1:] * scale
        return list(zip(ends.tolist(), exact.start_curvature.tolist(), exact.end_curvature.tolist(), strict=True))
    parts = []
    for part in chains.profiles[chain].parts:
        low, high = max(part.start_s, start_s), min(part.end_s, start_s + length_m)
        if high > low:
            k0, k1 = part.curvature_at_one(low), part.curvature_at_one(high)
            parts.append((high, k0, k1))
    return parts


def _chain_profile(
    chains: RoadChains, chain: int, lane_ids: Sequence[str], exact: Mapping[str, ExactLane]
) -> RadiusProfile:
    """One chain's profile from its lanes' exact parts, fitted parts where a lane has none."""
    bounds, start_k, end_k = [0.0], [], []
    for lane in chains.lanes[chain].tolist():
        for end_s, k0, k1 in _lane_parts(chains, chain, lane, exact.get(lane_ids[lane])):
            if end_s > bounds[-1]:
                bounds.append(end_s)
                start_k.append(k0)
                end_k.append(k1)
    xy = chains.xy[chain]
    vertex_s = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))))
    bounds[-1] = max(bounds[-1], float(vertex_s[-1]))
    return profile_from_parts(vertex_s, np.array(bounds), np.array(start_k), np.array(end_k))


def with_exact_profiles(chains: RoadChains, lane_ids: Sequence[str], exact: Mapping[str, ExactLane]) -> RoadChains:
    """``chains`` with every chain that has a lane of exact curvature reading its exact profile (see the module)."""
    profiles, fitted, runs = list(chains.profiles), list(chains.fitted), list(chains.runs)
    for chain, members in enumerate(chains.lanes):
        if not any(lane_ids[lane] in exact for lane in members.tolist()):
            continue
        profile = _chain_profile(chains, chain, lane_ids, exact)
        profiles[chain] = fitted[chain] = profile
        ends = np.array([0.0, float(profile.s[-1])])
        runs[chain] = (Run(chain, ends, ends, np.zeros(1), is_own=True),)
    return dataclasses.replace(chains, profiles=tuple(profiles), fitted=tuple(fitted), runs=tuple(runs), _curves={})


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
