"""What the nodes of a sparse way allow of an arc's start: the references beside the curvature benchmark's figures.

Two references (:mod:`benchmarks.curvature`): the Cramér-Rao bound on the start's standard
deviation of any unbiased estimate (:func:`start_bound_m`, from :mod:`benchmarks.bounds`), and
the start error of the maximum-likelihood road of the true form, straight-arc-straight, fitted
to the nodes from starts about the truth (:func:`reference_start_error_m`). An extractor, which
must also find the form, cannot be expected to start arcs closer than that fit does.
"""

from __future__ import annotations

import math

import numpy as np

from benchmarks.bounds import road_information, start_bounds_m
from benchmarks.curvature_roads import ARC_WARNING_RADIUS_M, SPARSE_NOISE_RMS_M, Road
from csws.geometry import Piece, straight

#: The maximum-likelihood reference (:func:`reference_start_error_m`): its starting roads
#: (arc start moved, m; arc lengthened, curvature kept turning the same angle), its
#: Levenberg-Marquardt iterations and the central-difference steps of its parameters.
ORACLE_START_SHIFTS_M = (-10.0, -5.0, 0.0, 5.0, 10.0)
ORACLE_LENGTH_FACTORS = (0.7, 1.0, 1.4)
ORACLE_ITERATIONS = 60
ORACLE_DIFFERENCE_STEPS = (1e-5, 1e-5, 1e-7, 1e-9, 1e-5)


def start_bound_m(road: Road) -> float:
    """The Cramér-Rao bound on the standard deviation of any unbiased estimate of the arc's
    start from the nodes of ``road`` (sparse cases), m: :func:`benchmarks.bounds.start_bounds_m`
    of the straight-arc-straight road, the nodes taken at their arc lengths along the polyline."""
    s = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(road.xy, axis=0).T))))
    arc_length_m = road.arc_end_s - road.arc_start_s
    pieces = [straight(road.arc_start_s), Piece(arc_length_m, road.curvature), straight(s[-1] + 100.0)]
    return float(start_bounds_m(road_information(pieces, s, SPARSE_NOISE_RMS_M), ARC_WARNING_RADIUS_M)[0])


def bound_figures(roads: list[Road], limit_m: float) -> dict:
    """What the Cramér-Rao bound allows: the median and p90 bound on the start's standard
    deviation, the number of arcs an efficient estimator is expected to start more than
    ``limit_m`` off, and the chance it misses none by that much."""
    sigma = np.array([start_bound_m(road) for road in roads])
    beyond = np.array([math.erfc(limit_m / (value * math.sqrt(2.0))) for value in sigma])
    return {
        "median_start_bound_m": float(np.median(sigma)),
        "p90_start_bound_m": float(np.percentile(sigma, 90)),
        "expected_beyond_limit": float(beyond.sum()),
        "chance_none_beyond_limit": float(np.prod(1.0 - beyond)),
    }


def _road_distances(parameters: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Signed distances (left positive) ``(k, n)`` of the nodes ``uv`` ``(n, 2)`` from the
    straight-arc-straight roads ``parameters`` ``(k, 5)``: the arc's start point (two
    coordinates), the heading there, the arc's curvature and length. The straights run on
    without end; a node beside no piece takes its distance from the nearer piece end."""
    along, side, heading, curvature, length = (parameters[:, column, None] for column in range(5))
    curvature = np.where(np.abs(curvature) < 1e-9, np.where(curvature < 0, -1e-9, 1e-9), curvature)
    z = ((uv[None, :, 0] - along) + 1j * (uv[None, :, 1] - side)) * np.exp(-1j * heading)
    centre = 1j / curvature
    turned = np.angle((z - centre) / -centre) * np.sign(curvature)
    turn = np.abs(curvature * length)
    before = (np.where(z.real <= 0.0, np.abs(z.imag), np.abs(z)), z.imag)
    on_arc = (turned >= 0.0) & (turned <= turn)
    arc_side = (np.abs(1.0 / curvature) - np.abs(z - centre)) * np.sign(curvature)
    arc_piece = (np.where(on_arc, np.abs(arc_side), np.inf), arc_side)
    beyond = (z - (centre - centre * np.exp(1j * curvature * length))) * np.exp(-1j * curvature * length)
    after = (np.where(beyond.real >= 0.0, np.abs(beyond.imag), np.abs(beyond)), beyond.imag)
    unsigned = np.stack((before[0], arc_piece[0], after[0]))
    signed = np.stack((before[1], arc_piece[1], after[1]))
    return np.take_along_axis(signed, np.argmin(unsigned, axis=0)[None], axis=0)[0]


def _fitted_roads(starts: np.ndarray, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Levenberg-Marquardt fits of straight-arc-straight roads (:func:`_road_distances`)
    from each of the ``starts`` ``(k, 5)`` to the nodes ``uv``; returns the fitted
    parameters and their sums of squared distances."""
    parameters, damping = starts.copy(), np.full(len(starts), 1e-3)
    distances = _road_distances(parameters, uv)
    squares = np.einsum("kn,kn->k", distances, distances)
    for _ in range(ORACLE_ITERATIONS):
        jacobian = np.empty(distances.shape + (5,))
        for column, step in enumerate(ORACLE_DIFFERENCE_STEPS):
            moved = np.zeros(5)
            moved[column] = step
            jacobian[..., column] = (
                _road_distances(parameters + moved, uv) - _road_distances(parameters - moved, uv)
            ) / (2.0 * step)
        normal = np.swapaxes(jacobian, 1, 2) @ jacobian
        diagonal = np.einsum("kmm->km", normal)
        normal += np.eye(5) * (damping[:, None] * diagonal + 1e-12)[:, None, :]
        trial = parameters + np.linalg.solve(normal, -np.einsum("knm,kn->km", jacobian, distances)[..., None])[..., 0]
        trial[:, 4] = np.fmax(trial[:, 4], 0.1)
        trial_distances = _road_distances(trial, uv)
        trial_squares = np.einsum("kn,kn->k", trial_distances, trial_distances)
        better = trial_squares < squares
        parameters[better], distances[better], squares[better] = (
            trial[better],
            trial_distances[better],
            trial_squares[better],
        )
        damping = np.where(better, np.fmax(damping / 10.0, 1e-9), damping * 10.0)
    return parameters, squares


def _polyline_s(xy: np.ndarray, point: complex) -> float:
    """Arc length along the polyline ``xy`` of the point of it nearest ``point``."""
    start, chord = xy[:-1, 0] + 1j * xy[:-1, 1], np.diff(xy[:, 0] + 1j * xy[:, 1])
    fraction = np.clip(np.real((point - start) * np.conj(chord)) / np.fmax(np.abs(chord) ** 2, 1e-12), 0.0, 1.0)
    nearest = int(np.argmin(np.abs(start + fraction * chord - point)))
    return float(np.sum(np.abs(chord[:nearest])) + fraction[nearest] * np.abs(chord[nearest]))


def reference_start_error_m(road: Road) -> float:
    """The start error of the maximum-likelihood road of the true form: the straight-arc-
    straight road whose nodes' squared distances are least, searched from
    :data:`ORACLE_START_SHIFTS_M` x :data:`ORACLE_LENGTH_FACTORS` starts about the truth.
    Told the form, it knows more than any extractor; it is scored as the extractor is,
    along the polyline (m)."""
    origin = road.origin_xy[0] + 1j * road.origin_xy[1]
    local = (road.xy[:, 0] + 1j * road.xy[:, 1] - origin) * np.exp(-1j * road.heading)
    length_m = road.arc_end_s - road.arc_start_s
    starts = np.array(
        [
            (road.arc_start_s + shift, 0.0, 0.0, road.curvature / factor, length_m * factor)
            for shift in ORACLE_START_SHIFTS_M
            for factor in ORACLE_LENGTH_FACTORS
        ]
    )
    parameters, squares = _fitted_roads(starts, np.column_stack((local.real, local.imag)))
    best = parameters[int(np.argmin(squares))]
    start_point = origin + (best[0] + 1j * best[1]) * np.exp(1j * road.heading)
    return abs(_polyline_s(road.xy, start_point) - road.arc_start_s)


def reference_figures(roads: list[Road], limit_m: float) -> dict:
    """The start-error figures of :func:`reference_start_error_m` on ``roads``."""
    errors = np.array([reference_start_error_m(road) for road in roads])
    return {
        "median_start_error_m": float(np.median(errors)),
        "p90_start_error_m": float(np.percentile(errors, 90)),
        "max_start_error_m": float(errors.max()),
        "arcs_started_over_5_m": int(np.sum(errors > limit_m)),
    }
