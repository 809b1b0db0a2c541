"""What a sparse way's nodes can tell of where its curves start: the Cramér-Rao bound.

A road of known form (its pieces: straights, arcs, clothoids joining their neighbours'
curvatures) is described by a few numbers: its sideways offset and heading at the start,
the length of every piece but the last, and the curvature of every arc. Each node of a
map way tells only its distance from the road across it (where along the road it lies is
unknown), with the per-axis variance of the node noise. The Fisher information of those
distances bounds the variance of any unbiased estimate of each curve start (3.4) — the
point where the curvature reaches 1/R_c, inside a clothoid where there is one — from
below. An extractor, which must also find the road's form, cannot be expected to do
better on average; where the bound itself is above a target, the target is out of reach
of the nodes, not of the extractor.

Where a piece holds too few nodes to tell its length from its curvature the information
is singular; the pseudo-inverse then gives the bound of what the nodes do tell, which is
smaller than the true bound (infinite along what they cannot tell), so a bound above a
target still proves it out of reach.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from csws.geometry import Piece, piece_starts_s, pose_at

#: Relative central-difference step of each parameter (floored at 1e-3 of its unit).
DIFFERENCE_STEP = 1e-6
#: Gauss-Newton iterations of the maximum-likelihood reference, Newton steps projecting
#: the nodes onto its road, and the shortest piece it may make, m.
ML_ITERATIONS = 40
ML_PROJECTION_STEPS = 2
ML_SHORTEST_PIECE_M = 0.1


def _free_parameters(pieces: Sequence[Piece]) -> tuple[np.ndarray, list[int]]:
    """The road's free numbers after offset and heading: every piece's length but the last,
    then the curvature of every arc (directly joined arcs of one curvature, an arc with a
    node inside it, share theirs); and for each piece the index of its curvature among
    those, -1 for none (a straight or a clothoid)."""
    curvature_of: list[int] = []
    curvatures: list[float] = []
    for index, piece in enumerate(pieces):
        if piece.end_curvature is not None or piece.curvature == 0:
            curvature_of.append(-1)
        elif index > 0 and curvature_of[-1] >= 0 and curvatures[curvature_of[-1]] == piece.curvature:
            curvature_of.append(curvature_of[-1])
        else:
            curvatures.append(piece.curvature)
            curvature_of.append(len(curvatures) - 1)
    return np.array([piece.length_m for piece in pieces[:-1]] + curvatures, dtype=float), curvature_of


def parameter_count(pieces: Sequence[Piece]) -> int:
    """How many numbers describe the road of known form: its offset and heading and its
    free numbers. A way with no more nodes than this, each telling one sideways distance,
    leaves the road undetermined: no estimator can place its curves from them alone."""
    return 2 + len(_free_parameters(pieces)[0])


def _pieces(pieces: Sequence[Piece], curvature_of: list[int], values: np.ndarray) -> list[Piece]:
    """The road with its free numbers set to ``values``: clothoids run from the curvature of
    the piece before them to that of the piece after them (0 at a straight)."""
    count = len(pieces)
    lengths = list(values[: count - 1]) + [pieces[-1].length_m]
    curvatures = values[count - 1 :]
    constant = [
        (float(curvatures[curvature_of[i]]) if curvature_of[i] >= 0 else 0.0) if p.end_curvature is None else None
        for i, p in enumerate(pieces)
    ]
    built = []
    for index, piece in enumerate(pieces):
        own = constant[index]
        if own is not None:
            built.append(Piece(lengths[index], own))
            continue
        previous = constant[index - 1] if index > 0 else None
        following = constant[index + 1] if index + 1 < count else None
        before = previous if previous is not None else piece.curvature
        after = following if following is not None else piece.end_curvature
        built.append(Piece(lengths[index], before, after))
    return built


def curve_starts_s(pieces: Sequence[Piece], warning_radius_m: float) -> np.ndarray:
    """Arc lengths where the road's curvature reaches 1/R_c in magnitude from below: the curve
    starts (3.4), exactly (inside a clothoid by its linear curvature, at a piece's start for an arc)."""
    limit = 1.0 / warning_radius_m

    def side(curvature: float) -> float:
        return math.copysign(1.0, curvature) if abs(curvature) >= limit else 0.0

    starts, s, previous = [], 0.0, 0.0
    for piece in pieces:
        k0, k1 = piece.curvature, piece.final_curvature
        if side(k0) != 0.0 and side(k0) != side(previous):
            starts.append(s)
        for level in (limit, -limit):
            crossing = (level - k0) / (k1 - k0) if k1 != k0 else -1.0
            if 0.0 < crossing < 1.0 and (level > 0.0) == (k1 > k0):
                starts.append(s + crossing * piece.length_m)
        s += piece.length_m
        previous = k1
    return np.array(sorted(starts))


def _road_of(pieces: Sequence[Piece], curvature_of: list[int]):
    """The road of the parameters ``[offset, heading, free numbers]`` as a function, and the
    nodes' points on it at arc lengths ``node_s`` as another."""

    def road(values: np.ndarray) -> list[Piece]:
        return _pieces(pieces, curvature_of, values[2:])

    def node_points(values: np.ndarray, node_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x, y, heading = pose_at(road(values), node_s, (0.0, values[0]), values[1])
        return np.column_stack((x, y)), heading

    return road, node_points


def _sideways_jacobian(node_points, values: np.ndarray, node_s: np.ndarray) -> np.ndarray:
    """Derivatives of the nodes' road points across the road at ``node_s`` by each parameter."""
    _, heading = node_points(values, node_s)
    normal = np.column_stack((-np.sin(heading), np.cos(heading)))
    jacobian = np.empty((len(node_s), len(values)))
    for column in range(len(values)):
        step = np.zeros(len(values))
        step[column] = DIFFERENCE_STEP * max(abs(values[column]), 1e-3)
        moved = (node_points(values + step, node_s)[0] - node_points(values - step, node_s)[0]) / (2.0 * step[column])
        jacobian[:, column] = np.einsum("ij,ij->i", moved, normal)
    return jacobian


@dataclass(frozen=True)
class RoadInformation:
    """What the nodes tell of a road of known form: the inverse Fisher information
    ``covariance`` of its parameters (the pseudo-inverse where it is singular), the true
    parameters ``truth`` and, for each piece, the index of its curvature among them
    (``curvature_of``, -1 for none)."""

    pieces: Sequence[Piece]
    covariance: np.ndarray
    truth: np.ndarray
    curvature_of: list[int]


def road_information(pieces: Sequence[Piece], node_s: np.ndarray, noise_rms_m: float) -> RoadInformation:
    """The information of nodes at arc lengths ``node_s`` along the true road ``pieces``,
    with isotropic node noise of ``noise_rms_m`` RMS (both axes together), m."""
    free, curvature_of = _free_parameters(pieces)
    truth = np.concatenate(([0.0, 0.0], free))
    jacobian = _sideways_jacobian(_road_of(pieces, curvature_of)[1], truth, node_s)
    information = jacobian.T @ jacobian / (noise_rms_m**2 / 2.0)
    return RoadInformation(pieces, np.linalg.pinv(information, hermitian=True), truth, curvature_of)


def start_bounds_m(information: RoadInformation, warning_radius_m: float) -> np.ndarray:
    """The Cramér-Rao bound on the standard deviation of each curve start (R_c
    ``warning_radius_m``), m."""
    pieces, truth = information.pieces, information.truth
    road = _road_of(pieces, information.curvature_of)[0]
    gradient = np.empty((len(curve_starts_s(pieces, warning_radius_m)), len(truth)))
    for column in range(len(truth)):
        step = np.zeros(len(truth))
        step[column] = DIFFERENCE_STEP * max(abs(truth[column]), 1e-3)
        gradient[:, column] = (
            curve_starts_s(road(truth + step), warning_radius_m) - curve_starts_s(road(truth - step), warning_radius_m)
        ) / (2.0 * step[column])
    return np.sqrt(np.einsum("ij,jk,ik->i", gradient, information.covariance, gradient))


def radius_bounds(information: RoadInformation, curve_spans_s: Sequence[tuple[float, float]]) -> np.ndarray:
    """The Cramér-Rao bound on the relative standard deviation of each curve's smallest
    radius (that of its sharpest arc, whose curvature is one of the road's parameters),
    for curves spanning ``curve_spans_s``; nan for a curve without an arc."""
    pieces, truth, curvature_of = information.pieces, information.truth, information.curvature_of
    first_curvature = len(pieces) + 1
    starts = piece_starts_s(pieces)
    bounds = []
    for start_s, end_s in curve_spans_s:
        inside = [
            i
            for i, piece in enumerate(pieces)
            if curvature_of[i] >= 0 and starts[i] < end_s and starts[i + 1] > start_s
        ]
        if not inside:
            bounds.append(math.nan)
            continue
        column = first_curvature + curvature_of[max(inside, key=lambda i: abs(pieces[i].curvature))]
        bounds.append(math.sqrt(information.covariance[column, column]) / abs(truth[column]))
    return np.array(bounds)


def ml_start_errors_m(
    pieces: Sequence[Piece], nodes_xy: np.ndarray, node_s: np.ndarray, warning_radius_m: float
) -> np.ndarray:
    """The start error of each curve of the maximum-likelihood road told the true form, m.

    The reference method: the road's form (which pieces, straights, arcs and clothoids, in
    which order) is given, and its numbers are fitted to the nodes by damped Gauss-Newton
    steps from the true ones, each node at its nearest point of the road. An extractor,
    which must find the form as well and starts from nothing, can hardly do better; where
    this reference misses a target, the nodes do not hold what the target asks. ``node_s``
    are the nodes' first places along the road (their projections onto the true road).
    """
    free, curvature_of = _free_parameters(pieces)
    values = np.concatenate(([0.0, 0.0], free))
    road, node_points = _road_of(pieces, curvature_of)
    node_s = np.array(node_s, dtype=float)

    def distances(values: np.ndarray, node_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The nodes' sideways distances from the road, each after Newton steps to its nearest point."""
        for _ in range(ML_PROJECTION_STEPS):
            points, heading = node_points(values, node_s)
            offset = nodes_xy - points
            node_s = node_s + offset[:, 0] * np.cos(heading) + offset[:, 1] * np.sin(heading)
        points, heading = node_points(values, node_s)
        offset = nodes_xy - points
        return offset[:, 1] * np.cos(heading) - offset[:, 0] * np.sin(heading), node_s

    residual, node_s = distances(values, node_s)
    damping = 1e-3
    lengths = slice(2, len(pieces) + 1)
    for _ in range(ML_ITERATIONS):
        jacobian = _sideways_jacobian(node_points, values, node_s)
        normal = jacobian.T @ jacobian
        normal += damping * np.diag(np.diag(normal) + 1e-12)
        trial = values + np.linalg.lstsq(normal, jacobian.T @ residual, rcond=None)[0]
        trial[lengths] = np.fmax(trial[lengths], ML_SHORTEST_PIECE_M)
        trial_residual, trial_s = distances(trial, node_s)
        if trial_residual @ trial_residual < residual @ residual:
            gain = residual @ residual - trial_residual @ trial_residual
            values, residual, node_s, damping = trial, trial_residual, trial_s, max(damping / 10.0, 1e-9)
            if gain < 1e-9 * (residual @ residual + 1e-12):
                break
        else:
            damping *= 10.0
            if damping > 1e6:
                break
    true_starts, fitted_starts = (
        curve_starts_s(pieces, warning_radius_m),
        curve_starts_s(road(values), warning_radius_m),
    )
    if len(fitted_starts) != len(true_starts):
        return np.full(len(true_starts), math.inf)
    return np.abs(fitted_starts - true_starts)


def error_quantile_m(bounds_m: np.ndarray, quantile: float) -> float:
    """The ``quantile`` of the start error of an efficient estimator over all curves: errors
    normal with the bounds as standard deviations, pooled, m."""
    sigma = np.asarray(bounds_m, dtype=float)
    if len(sigma) == 0:
        return math.nan

    def share_within(error_m: float) -> float:
        return float(np.mean([math.erf(error_m / (value * math.sqrt(2.0))) if value > 0 else 1.0 for value in sigma]))

    low, high = 0.0, float(sigma.max()) * 10.0 + 1e-9
    for _ in range(60):
        middle = (low + high) / 2.0
        low, high = (middle, high) if share_within(middle) < quantile else (low, middle)
    return (low + high) / 2.0
