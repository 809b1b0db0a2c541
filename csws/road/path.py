"""Profiles the road along consecutive lanes (a path) from the fitted road chains.

A path runs along stretches of chains (:mod:`csws.road.chains`). Where it leaves a chain
(a turn into another road at a junction), the turn's internal lane is a chain of its own,
a junction manoeuvre, as is every lane of a roundabout: their curves are offered only on
request (:meth:`PathProfile.curves` against :meth:`PathProfile.road_curves`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial

import numpy as np

from csws.curvature import Curve, RadiusProfile, profile_from_parts, straight_profile
from csws.road.chains import RoadChains, clip_curve
from csws.road.stitching import stitch_vertices
from csws.standard import DEFAULT_WARNING_RADIUS_M, WarningSpeedPolicy

__all__ = ["PathProfile", "path_profile", "path_profile_parts", "path_runs"]


@dataclass(frozen=True)
class PathProfile:
    """The road along consecutive lanes: one polyline, and the fitted profiles of the roads it runs on.

    The path arc length ``s`` starts at 0 at the first vertex of the first lane. The
    look-ahead distance (3.9) to a curve start or to a CPOI (3.11) is a difference of
    two path arc lengths. The path is cut into runs, each a stretch of one road chain;
    its profile and curves are those of the chains, cut to the runs.

    Attributes
    ----------
    lane_ids
        The lanes in driving order, internal via lanes included.
    xy
        The stitched polyline, ``(n, 2)``.
    profile
        Its radius profile: the chains' profiles on the runs.
    lane_start_s
        Path arc length at the first shape point of each lane, ``(len(lane_ids),)``, m.
    lane_shape_length_m, lane_position_factor
        Length of each lane's shape on the path and SUMO's position factor for it (see
        :class:`csws.road.roadmap.Lane`; an internal lane that continues the road is one chord here).
    lane_is_junction
        Whether each lane is a junction manoeuvre (:attr:`csws.road.roadmap.Lane.is_junction`).
    run_chain, run_chain_start_s, run_chain_end_s, run_path_start_s, run_is_junction
        Per run: its chain, where it starts and ends in the chain's arc length, where it
        starts on the path, and whether it is a junction manoeuvre.
    """

    lane_ids: tuple[str, ...]
    xy: np.ndarray
    profile: RadiusProfile
    lane_start_s: np.ndarray
    lane_shape_length_m: np.ndarray
    lane_position_factor: np.ndarray
    lane_is_junction: np.ndarray
    run_chain: np.ndarray
    run_chain_start_s: np.ndarray
    run_chain_end_s: np.ndarray
    run_path_start_s: np.ndarray
    run_is_junction: np.ndarray
    chain_curves: Callable[[int, float], list[Curve]] = field(repr=False, compare=False)

    @property
    def length_m(self) -> float:
        """Arc length of the whole path, m."""
        return float(self.profile.s[-1])

    def curves(self, warning_radius_m: float = DEFAULT_WARNING_RADIUS_M) -> list[Curve]:
        """The curves (radius <= ``warning_radius_m``, 3.2-3.8) along the path, junction manoeuvres included."""
        return [curve for curve, _, _ in self.curve_sources(warning_radius_m, junctions=True)]

    def road_curves(self, warning_radius_m: float = DEFAULT_WARNING_RADIUS_M) -> list[Curve]:
        """The curves of the road along the path: :meth:`curves` without junction manoeuvres.

        A turn from one road into another (the path leaves a road chain at a junction)
        and a drive round a roundabout are junction manoeuvres; a curve of a road with a
        node inside it is a curve of the road, whole.
        """
        return [curve for curve, _, _ in self.curve_sources(warning_radius_m, junctions=False)]

    def curve_sources(self, warning_radius_m: float, junctions: bool) -> list[tuple[Curve, int, Curve]]:
        """The curves along the path with where they come from: ``(curve in path arc length,
        chain, the chain's whole curve)``; junction manoeuvres only with ``junctions``.

        The chain's curve says which curve of the index it is (where it starts, 3.4),
        also when the path starts inside it or turns off the road before its end.
        """
        found = []
        for chain, start_s, end_s, path_start_s, is_junction in zip(
            self.run_chain.tolist(),
            self.run_chain_start_s.tolist(),
            self.run_chain_end_s.tolist(),
            self.run_path_start_s.tolist(),
            self.run_is_junction.tolist(),
            strict=True,
        ):
            if is_junction and not junctions:
                continue
            offset_m = path_start_s - start_s
            for curve in self.chain_curves(chain, warning_radius_m):
                clipped = clip_curve(curve, start_s, end_s, offset_m)
                if clipped is not None:
                    found.append((clipped, chain, curve))
        return found

    def lane_positions(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Map path arc lengths to lanes: for each ``s``, the index into :attr:`lane_ids` and the lane position.

        An ``s`` on a joint belongs to the lane that starts there; ``s`` outside the
        path is clamped to its ends.
        """
        s = np.asarray(s, dtype=float)
        lane = np.clip(np.searchsorted(self.lane_start_s, s, side="right") - 1, 0, len(self.lane_ids) - 1)
        along_shape_m = np.clip(s - self.lane_start_s[lane], 0.0, self.lane_shape_length_m[lane])
        return lane, along_shape_m * self.lane_position_factor[lane]

    def lane_position(self, s: float) -> tuple[str, float]:
        """The lane id and lane position at path arc length ``s`` (see :meth:`lane_positions`)."""
        lane, pos_m = self.lane_positions(np.array([s]))
        return self.lane_ids[int(lane[0])], float(pos_m[0])

    def path_s(self, lane_id: str, lane_pos_m: float) -> float:
        """Path arc length of a lane position on the first occurrence of ``lane_id`` in the path.

        Raises
        ------
        KeyError
            If the lane is not on the path.
        """
        try:
            lane = self.lane_ids.index(lane_id)
        except ValueError:
            raise KeyError(f"lane {lane_id!r} is not on the path") from None
        along_shape_m = np.clip(lane_pos_m / self.lane_position_factor[lane], 0.0, self.lane_shape_length_m[lane])
        return float(self.lane_start_s[lane] + along_shape_m)


def path_runs(chains: RoadChains, lanes: Sequence[int]) -> list[tuple[int, int]]:
    """The path's lanes cut into runs along one chain each: ``(first, last)`` indices into ``lanes``."""
    runs: list[tuple[int, int]] = []
    first = 0
    lane_chain, lane_start_s = chains.lane_chain_and_start
    for position in range(1, len(lanes) + 1):
        if position == len(lanes):
            runs.append((first, position - 1))
            break
        previous, lane = lanes[position - 1], lanes[position]
        same_chain = lane_chain[lane] == lane_chain[previous]
        if not (same_chain and lane_start_s[lane] > lane_start_s[previous]):
            runs.append((first, position - 1))
            first = position
    return runs


def path_profile_parts(
    chains: RoadChains,
    chain_of_run: np.ndarray,
    chain_start_s: np.ndarray,
    chain_end_s: np.ndarray,
    path_start_s: np.ndarray,
    vertex_s: np.ndarray,
) -> RadiusProfile:
    """The radius profile of a path: each run's stretch of its chain's profile, shifted onto
    the path; a gap between runs (lanes that do not meet) is straight."""
    bounds: list[float] = [0.0]
    start_k: list[float] = []
    end_k: list[float] = []

    def add(end_s: float, k0: float, k1: float) -> None:
        if end_s > bounds[-1] + 1e-9:
            bounds.append(end_s)
            start_k.append(k0)
            end_k.append(k1)

    for chain, start_s, end_s, offset_s in zip(
        chain_of_run.tolist(),
        chain_start_s.tolist(),
        chain_end_s.tolist(),
        (path_start_s - chain_start_s).tolist(),
        strict=False,
    ):
        add(start_s + offset_s, 0.0, 0.0)
        for part in chains.profile_parts_between(chain, start_s, end_s):
            a, b = max(part.start_s, start_s), min(part.end_s, end_s)
            add(b + offset_s, part.curvature_at_one(a), part.curvature_at_one(b))
    add(float(vertex_s[-1]), 0.0, 0.0)
    if len(bounds) < 2:
        return straight_profile(vertex_s)
    return profile_from_parts(vertex_s, np.array(bounds), np.array(start_k), np.array(end_k))


def path_profile(
    chains: RoadChains,
    lanes: Sequence[int],
    lane_ids: Sequence[str],
    road_shapes: Sequence[np.ndarray],
    lane_length_m: np.ndarray,
    lane_is_junction: np.ndarray,
    warning_policy: WarningSpeedPolicy,
) -> PathProfile:
    """The profile of a path of consecutive lanes (internal lanes included) read from the road chains.

    Parameters
    ----------
    chains
        The network's fitted road chains.
    lanes, lane_ids
        The path's lane indices and ids.
    road_shapes
        The shape each lane of the path gives its road, ``(n, 2)``, m.
    lane_length_m
        The SUMO length of each lane of the path, m.
    lane_is_junction
        Whether each lane of the path is a junction manoeuvre.
    warning_policy
        The warning speeds its curves' clothoids are cut by (:func:`csws.curvature.curves_from_profile`).
    """
    xy, vertex_s, lane_first_vertex = stitch_vertices(road_shapes)
    lane_start_s = vertex_s[lane_first_vertex]
    shape_length_m = chains.lane_road_length_m[list(lanes)]
    runs = path_runs(chains, lanes)
    first = np.array([lanes[a] for a, _ in runs], dtype=np.int64)
    last = np.array([lanes[b] for _, b in runs], dtype=np.int64)
    run_chain = chains.lane_chain[first]
    run_chain_start_s = chains.lane_start_s[first]
    run_chain_end_s = chains.lane_start_s[last] + chains.lane_road_length_m[last]
    run_path_start_s = lane_start_s[[a for a, _ in runs]]
    return PathProfile(
        lane_ids=tuple(lane_ids),
        xy=xy,
        profile=path_profile_parts(chains, run_chain, run_chain_start_s, run_chain_end_s, run_path_start_s, vertex_s),
        lane_start_s=lane_start_s,
        lane_shape_length_m=shape_length_m,
        lane_position_factor=np.divide(
            lane_length_m, shape_length_m, out=np.ones(len(lanes)), where=shape_length_m > 0
        ),
        lane_is_junction=np.asarray(lane_is_junction, dtype=bool),
        run_chain=run_chain,
        run_chain_start_s=run_chain_start_s,
        run_chain_end_s=run_chain_end_s,
        run_path_start_s=run_path_start_s,
        run_is_junction=chains.is_junction[run_chain],
        chain_curves=partial(chains.curves, policy=warning_policy),
    )
