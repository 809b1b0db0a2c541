"""Accuracy and speed of the radius profile against the three-point circumcircle.

Every case is built exactly with :mod:`csws.geometry`, so the true radius and curve
start point (3.4) are known:

* dense: SUMO-like lane shapes, straight-arc-straight, vertices 0.5-1 m apart,
  coordinates rounded to 0.01 m;
* sparse: map-like ways, the same roads with nodes 5-30 m apart at irregular arc
  lengths and 0.5 m RMS isotropic Gaussian noise on every node, unrestricted: an arc
  may be shorter than the node spacing (R = 25 m at 20 degrees is 8.7 m of arc between
  nodes up to 30 m apart) and then carries no information on where it starts;
* mapped: the sparse ways as mapping practice draws them, the case the sparse targets
  are judged on. Mappers put nodes on a curve so that the polyline follows the road,
  so on an arc the node gaps are scaled down until none exceeds a third of the arc's
  length nor half its radius (at least three chords per arc; the polyline then stays
  within R/32 of the road). Straights are as in the sparse case;
* straights, dense and sparse, on which no curve may be found;
* the standard's multi curves (Tables 8 and 9): R1 = 200 m (L1 40-70 m) or
  R1 = 120 m (L1 15-35 m) joined directly to R2 = 40 m, where the R2 part must start
  within 1 m of the truth.

Arcs of R 25-500 m turn 20-120 degrees; arc cases are searched for curves with a
warning radius of 1,000 m so that every arc is a curve, straights with the default
R_c of 300 m. The three-point method's curves are maximal runs of vertices whose
circumcircle radius is <= R_c and that turn the same way; its radius is the median
over the run. Of several curves found on an arc, the one overlapping the arc most is
scored; an arc where none is found scores an infinite error.

On the sparse ways two references say what the nodes allow: the Cramér-Rao bound on
the start's standard deviation (:func:`start_bound_m`), and the maximum-likelihood road
of the true form (:func:`reference_start_error_m`), a fit told that the road is
straight-arc-straight and searched from starts about the truth. An extractor, which
must also find the form, cannot be expected to start arcs closer than that fit does.

Speed: vertices per second on a synthetic network of dense lane shapes and on the sparse
ways (the bundled real network's load is timed by :mod:`benchmarks.roadmap`).

Run with ``python -m benchmarks.curvature``; :func:`run` returns the figures.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from benchmarks.bounds import road_information, start_bounds_m
from benchmarks.command import arguments
from csws.curvature import find_curves, radius_profiles, three_point_radius
from csws.geometry import Piece, arc, piece_starts_s, pose_at, sample_pieces, straight
from csws.standard import DEFAULT_POLICY, DEFAULT_WARNING_RADIUS_M

SEED = 20180091
CASES_PER_CATEGORY = 300
#: Warning radius used on the arc cases, so that every arc of R <= 500 m is a curve, m.
ARC_WARNING_RADIUS_M = 1000.0
DENSE_SPACING_M = (0.5, 1.0)
SPARSE_SPACING_M = (5.0, 30.0)
SPARSE_NOISE_RMS_M = 0.5
#: On mapped ways, the longest node gap on an arc as a fraction of its length and of its radius.
MAPPED_ARC_FRACTION = 1.0 / 3.0
MAPPED_RADIUS_FRACTION = 0.5
ROUNDING_M = 0.01
#: Vertices in the throughput network (about 1,500 lane-km of dense shapes).
THROUGHPUT_VERTICES = 300_000

#: The targets: (dense, sparse) limits of each figure.
TARGETS = {
    "median_radius_error_pct": (0.5, 5.0),
    "max_start_error_m": (1.0, 5.0),
    "false_curves_on_straights": (0, 0),
}
MULTI_STEP_TARGET_M = 1.0
#: The sparse target on the curve start, m: the bound figures count the arcs started further off.
SPARSE_START_LIMIT_M = TARGETS["max_start_error_m"][1]
#: The maximum-likelihood reference (:func:`reference_start_error_m`): its starting roads
#: (arc start moved, m; arc lengthened, curvature kept turning the same angle), its
#: Levenberg-Marquardt iterations and the central-difference steps of its parameters.
ORACLE_START_SHIFTS_M = (-10.0, -5.0, 0.0, 5.0, 10.0)
ORACLE_LENGTH_FACTORS = (0.7, 1.0, 1.4)
ORACLE_ITERATIONS = 60
ORACLE_DIFFERENCE_STEPS = (1e-5, 1e-5, 1e-7, 1e-9, 1e-5)

#: A found curve: (start_s, end_s, radius_m).
FoundCurve = tuple[float, float, float]


@dataclass(frozen=True)
class Road:
    """A constructed polyline with its truth: the arc's start and end, its radius and
    signed curvature, and where the road starts (the first node's true place) and heads."""

    xy: np.ndarray
    arc_start_s: float
    arc_end_s: float
    radius_m: float
    curvature: float
    origin_xy: tuple[float, float]
    heading: float


def _random_pose(rng: np.random.Generator) -> tuple[tuple[float, float], float]:
    """A random start point (network-sized coordinates) and heading."""
    return (float(rng.uniform(-5000, 5000)), float(rng.uniform(-5000, 5000))), float(rng.uniform(-np.pi, np.pi))


Pose = tuple[tuple[float, float], float]


def dense_shape(pieces: list[Piece], rng: np.random.Generator, pose: Pose | None = None) -> np.ndarray:
    """A SUMO-like lane shape: vertices 0.5-1 m apart, coordinates rounded to 1 cm, starting
    at ``pose`` (random if not given)."""
    start_xy, heading = pose or _random_pose(rng)
    xy, _ = sample_pieces(pieces, float(rng.uniform(*DENSE_SPACING_M)), start_xy, heading)
    return np.round(xy / ROUNDING_M) * ROUNDING_M


def _node_arc_lengths(pieces: list[Piece], rng: np.random.Generator, mapped: bool) -> np.ndarray:
    """Arc lengths of a way's nodes: gaps drawn from :data:`SPARSE_SPACING_M`; when
    ``mapped``, a gap that overlaps an arc is scaled down so that it is at most
    :data:`MAPPED_ARC_FRACTION` of the arc's length and :data:`MAPPED_RADIUS_FRACTION` of
    its radius."""
    starts = piece_starts_s(pieces)
    arcs = [(starts[i], starts[i + 1], piece) for i, piece in enumerate(pieces) if piece.curvature != 0]
    s = [0.0]
    while s[-1] < starts[-1]:
        gap = float(rng.uniform(*SPARSE_SPACING_M))
        for arc_start, arc_end, piece in arcs if mapped else ():
            if s[-1] < arc_end and s[-1] + gap > arc_start:
                longest_m = min(
                    SPARSE_SPACING_M[1], MAPPED_ARC_FRACTION * piece.length_m, MAPPED_RADIUS_FRACTION * piece.radius_m
                )
                gap *= longest_m / SPARSE_SPACING_M[1]
        s.append(s[-1] + gap)
    return np.append(np.array(s[:-1]), starts[-1])


def sparse_way(
    pieces: list[Piece], rng: np.random.Generator, pose: Pose | None = None, mapped: bool = False
) -> np.ndarray:
    """A map-like way: nodes at irregular arc lengths 5-30 m apart (closer on arcs when
    ``mapped``, see :func:`_node_arc_lengths`), 0.5 m RMS noise, starting at ``pose``."""
    start_xy, heading = pose or _random_pose(rng)
    s = _node_arc_lengths(pieces, rng, mapped)
    x, y, _ = pose_at(pieces, s, start_xy, heading)
    noise = rng.normal(0.0, SPARSE_NOISE_RMS_M / np.sqrt(2.0), size=(len(s), 2))
    return np.column_stack((x, y)) + noise


def mapped_way(pieces: list[Piece], rng: np.random.Generator, pose: Pose | None = None) -> np.ndarray:
    """A sparse way whose nodes follow mapping practice on arcs (:func:`sparse_way`)."""
    return sparse_way(pieces, rng, pose, mapped=True)


def arc_road(rng: np.random.Generator, shape: Callable[..., np.ndarray]) -> Road:
    """Straight, arc of R 25-500 m turning 20-120 degrees either way, straight."""
    radius_m = float(np.exp(rng.uniform(np.log(25.0), np.log(500.0))))
    before_m = float(rng.uniform(50, 150))
    pieces = [
        straight(before_m),
        arc(radius_m, float(rng.uniform(20, 120)), str(rng.choice(["left", "right"]))),
        straight(float(rng.uniform(50, 150))),
    ]
    pose = _random_pose(rng)
    return Road(shape(pieces, rng, pose), before_m, before_m + pieces[1].length_m, radius_m, pieces[1].curvature, *pose)


def straight_road(
    rng: np.random.Generator, shape: Callable[[list[Piece], np.random.Generator], np.ndarray]
) -> np.ndarray:
    """A straight of 200-1,000 m."""
    return shape([straight(float(rng.uniform(200, 1000)))], rng)


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


# --------------------------------------------------------------------------- the two methods


def ours(xy: np.ndarray, warning_radius_m: float) -> list[FoundCurve]:
    """Curves of :func:`csws.curvature.find_curves`."""
    return [(c.start_s, c.end_s, c.min_radius_m) for c in find_curves(xy, warning_radius_m, policy=DEFAULT_POLICY)]


def three_point(xy: np.ndarray, warning_radius_m: float) -> list[FoundCurve]:
    """Curves of the three-point circumcircle: runs of same-turn vertices with radius <= R_c."""
    keep = np.concatenate(([True], np.any(np.diff(xy, axis=0) != 0, axis=1)))
    xy = xy[keep]
    s = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))))
    radius = three_point_radius(xy)
    turn = np.zeros(len(xy))
    if len(xy) >= 3:
        d1, d2 = xy[1:-1] - xy[:-2], xy[2:] - xy[1:-1]
        turn[1:-1] = np.sign(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])
    label = np.where(radius <= warning_radius_m, turn, 0.0)
    curves = []
    change = np.flatnonzero(np.diff(np.concatenate(([0.0], label, [0.0]))) != 0)
    for first, stop in zip(change[:-1], change[1:], strict=False):
        if label[first] != 0:
            curves.append((float(s[first]), float(s[stop - 1]), float(np.median(radius[first:stop]))))
    return curves


def _score(found: list[FoundCurve], road: Road) -> tuple[float, float]:
    """Radius error (%) and start error (m) of the found curve overlapping the arc most."""
    overlap = [min(end, road.arc_end_s) - max(start, road.arc_start_s) for start, end, _ in found]
    if not found or max(overlap) <= 0:
        return np.inf, np.inf
    start, _, radius = found[int(np.argmax(overlap))]
    return 100.0 * abs(radius / road.radius_m - 1.0), abs(start - road.arc_start_s)


def accuracy(roads: list[Road], straights: list[np.ndarray], method: Callable) -> dict:
    """Radius and start errors on the arcs and false curves on the straights."""
    scores = np.array([_score(method(r.xy, ARC_WARNING_RADIUS_M), r) for r in roads])
    return {
        "median_radius_error_pct": float(np.median(scores[:, 0])),
        "p90_radius_error_pct": float(np.percentile(scores[:, 0], 90)),
        "median_start_error_m": float(np.median(scores[:, 1])),
        "p90_start_error_m": float(np.percentile(scores[:, 1], 90)),
        "max_start_error_m": float(np.max(scores[:, 1])),
        "arcs_started_over_5_m": int(np.sum(scores[:, 1] > SPARSE_START_LIMIT_M)),
        "missed_arcs": int(np.sum(~np.isfinite(scores[:, 0]))),
        "false_curves_on_straights": int(sum(len(method(xy, DEFAULT_WARNING_RADIUS_M)) for xy in straights)),
    }


def multi_curve_step_errors(rng: np.random.Generator, count: int) -> dict:
    """Where the R2 = 40 m part of the standard's multi curves starts, against the truth (dense)."""
    errors, multi = [], 0
    for i in range(count):
        radius_1, length_1 = (200.0, rng.uniform(40, 70)) if i % 2 == 0 else (120.0, rng.uniform(15, 35))
        direction = str(rng.choice(["left", "right"]))
        before_m = float(rng.uniform(50, 150))
        pieces = [
            straight(before_m),
            arc(radius_1, float(np.degrees(length_1 / radius_1)), direction),
            arc(40.0, float(np.degrees(rng.uniform(28, 60) / 40.0)), direction),
            straight(float(rng.uniform(50, 150))),
        ]
        step_s = before_m + pieces[1].length_m
        curves = find_curves(dense_shape(pieces, rng), policy=DEFAULT_POLICY)
        parts = [p for c in curves for p in c.parts]
        multi += len(curves) == 1 and len(parts) == 2
        starts = [p.start_s for p in parts if abs(p.radius_m - 40.0) < 4.0]
        errors.append(abs(starts[0] - step_s) if starts else np.inf)
    return {
        "max_step_error_m": float(np.max(errors)),
        "median_step_error_m": float(np.median(errors)),
        "found_as_one_multi_curve": multi,
        "cases": count,
    }


def _network_lane(rng: np.random.Generator) -> np.ndarray:
    """A lane of a SUMO-like network: a two-point straight, a junction turn or a curved road."""
    kind = rng.random()
    if kind < 0.4:
        return dense_shape([straight(float(rng.uniform(20, 300)))], rng)[[0, -1]]
    if kind < 0.8:
        return dense_shape([arc(float(rng.uniform(8, 30)), float(rng.uniform(30, 90)), "right")], rng)
    pieces = [
        straight(float(rng.uniform(10, 100))),
        arc(float(rng.uniform(50, 500)), float(rng.uniform(10, 60))),
        straight(float(rng.uniform(10, 100))),
    ]
    return dense_shape(pieces, rng)


def throughput(rng: np.random.Generator) -> dict:
    """Vertices per second of :func:`radius_profiles` on a network of lane shapes.

    The network mixes two-point straights, dense junction turns and dense curved roads,
    as netconvert writes them, until it holds :data:`THROUGHPUT_VERTICES` vertices.
    """
    lanes, vertices = [], 0
    while vertices < THROUGHPUT_VERTICES:
        lanes.append(_network_lane(rng))
        vertices += len(lanes[-1])
    start = time.perf_counter()
    radius_profiles(lanes)
    seconds = time.perf_counter() - start
    return {"lanes": len(lanes), "vertices": vertices, "seconds": seconds, "vertices_per_s": vertices / seconds}


def sparse_throughput(ways: list[np.ndarray]) -> dict:
    """Vertices per second of :func:`radius_profiles` on map-like ways (the sparse fit, in batches)."""
    start = time.perf_counter()
    radius_profiles(ways)
    seconds = time.perf_counter() - start
    vertices = sum(len(xy) for xy in ways)
    return {"lanes": len(ways), "vertices": vertices, "seconds": seconds, "vertices_per_s": vertices / seconds}


def run(cases: int = CASES_PER_CATEGORY, seed: int = SEED) -> dict:
    """All the figures: per input kind and method, the multi curves, and throughput."""
    rng = np.random.default_rng(seed)
    figures: dict = {}
    for kind, shape in (("dense", dense_shape), ("sparse", sparse_way), ("mapped", mapped_way)):
        roads = [arc_road(rng, shape) for _ in range(cases)]
        straights = [straight_road(rng, shape) for _ in range(cases // 3)]
        figures[kind] = {
            name: accuracy(roads, straights, method) for name, method in (("ours", ours), ("three_point", three_point))
        }
        if kind != "dense":
            figures[kind]["bound"] = bound_figures(roads, SPARSE_START_LIMIT_M)
            figures[kind]["reference"] = reference_figures(roads, SPARSE_START_LIMIT_M)
        if kind == "sparse":
            figures["sparse_throughput"] = sparse_throughput([road.xy for road in roads] + straights)
    figures["multi_curve"] = multi_curve_step_errors(rng, cases // 3)
    figures["throughput"] = throughput(rng)
    return figures


def _verdict(value: float, limit: float) -> str:
    return "PASS" if value <= limit else "FAIL"


def report(figures: dict) -> str:
    """The figures as a table, each beside its target."""
    lines = [
        "sparse: nodes 5-30 m apart everywhere (unrestricted); mapped: the same, but node gaps on an arc",
        f"at most {MAPPED_ARC_FRACTION:.2g} of its length and {MAPPED_RADIUS_FRACTION:.2g} of its radius "
        "(mapping practice)",
        f"{'case':7} {'figure':27} {'ours':>10} {'3-point':>10} {'target':>8}  ours  3-point",
    ]
    for column, kind in ((0, "dense"), (1, "sparse"), (1, "mapped")):
        for name in (
            "median_radius_error_pct",
            "p90_radius_error_pct",
            "median_start_error_m",
            "p90_start_error_m",
            "max_start_error_m",
            "arcs_started_over_5_m",
            "missed_arcs",
            "false_curves_on_straights",
        ):
            ours_value, baseline = figures[kind]["ours"][name], figures[kind]["three_point"][name]
            if name in TARGETS:
                limit = TARGETS[name][column]
                verdicts = f"  {_verdict(ours_value, limit):5} {_verdict(baseline, limit)}"
                target = f"{limit:>8g}"
            else:
                verdicts, target = "", f"{'':>8}"
            lines.append(f"{kind:7} {name:27} {ours_value:>10.3f} {baseline:>10.3f} {target}{verdicts}")
    for kind in ("sparse", "mapped"):
        bound = figures[kind]["bound"]
        lines.append(
            f"{kind:7} start-error bound (Cramér-Rao, 0.5 m noise): median {bound['median_start_bound_m']:.2f} m, "
            f"p90 {bound['p90_start_bound_m']:.2f} m; arcs started > {SPARSE_START_LIMIT_M:g} m off: ours "
            f"{figures[kind]['ours']['arcs_started_over_5_m']}, "
            f"an efficient estimator {bound['expected_beyond_limit']:.1f} expected "
            f"(it misses none with probability {bound['chance_none_beyond_limit']:.3f})"
        )
        reference, ours_figures = figures[kind]["reference"], figures[kind]["ours"]
        lines.append(
            f"{kind:7} start error of the maximum-likelihood road told its form (straight-arc-straight), "
            "ours beside it: "
            + ", ".join(
                f"{label} {reference[key]:.2f} m ({ours_figures[key]:.2f})"
                for label, key in (
                    ("median", "median_start_error_m"),
                    ("p90", "p90_start_error_m"),
                    ("max", "max_start_error_m"),
                )
            )
            + f"; arcs started > {SPARSE_START_LIMIT_M:g} m off {reference['arcs_started_over_5_m']} "
            f"({ours_figures['arcs_started_over_5_m']})"
        )
    multi = figures["multi_curve"]
    lines.append(
        f"multi   max_step_error_m            {multi['max_step_error_m']:>10.3f} {'':>10} {MULTI_STEP_TARGET_M:>8g}  "
        f"{_verdict(multi['max_step_error_m'], MULTI_STEP_TARGET_M)}"
    )
    lines.append(f"multi   median_step_error_m         {multi['median_step_error_m']:>10.3f}")
    lines.append(f"multi   found as one multi curve    {multi['found_as_one_multi_curve']:>6d} / {multi['cases']}")
    for label, key in (("throughput", "throughput"), ("sparse ways", "sparse_throughput")):
        speed = figures[key]
        lines.append(
            f"{label}: {speed['vertices']:,} vertices in {speed['lanes']:,} polylines profiled in "
            f"{speed['seconds']:.2f} s = {speed['vertices_per_s']:,.0f} vertices/s"
        )
    return "\n".join(lines)


def main() -> None:
    """Print the benchmark table."""
    arguments("benchmarks.curvature", __doc__)
    start = time.perf_counter()
    print(report(run()))
    print(f"(benchmark took {time.perf_counter() - start:.1f} s)")


if __name__ == "__main__":
    main()
