"""The road model on real-road geometry: families of constructed roads, dense and sparse.

Every road is built from exact pieces (:mod:`csws.geometry`: straights, arcs, clothoids),
so its curvature at every arc length, and with it every curve's start (3.4), end (3.5),
smallest radius and angle, is known. Each road is sampled two ways:

* dense, as SUMO writes a lane: vertices 0.5-1 m apart, coordinates rounded to 1 cm;
* sparse, as a mapped way relates to the road: the dense line simplified by
  Douglas-Peucker at a tolerance drawn from 0.3-2 m, then 0.5 m RMS isotropic noise on
  every node.

The families:

* ``spirals``: straight, clothoid entry of 20-80 m, arc of R 30-450 m, clothoid exit;
* ``compound``: two or three arcs of decreasing radius (e.g. 250 -> 90 -> 35 m), with or
  without clothoids between them;
* ``s_curves``: two arcs turning opposite ways, joined directly or by one clothoid
  through the inflection;
* ``split``: a single arc with a node at a random point inside it (kept by both samplings);
* ``hairpins``: arcs of R 15-40 m turning 150-180 degrees;
* ``corners``: right-angle corners, a rounded corner of R 8-25 m drawn with one to three
  nodes on the arc and the straights' nodes;
* ``gentle``: arcs of R 350-450 m turning 30-60 degrees, with spirals.

Curves are searched with R_c = 500 m, so that every arc of a family is one. A true curve
is found when a found curve overlaps it (in the true road's arc length, found ends
projected onto the true line); its start error is the distance between the starts, its
radius error that of the smallest radii. Missed: a true curve of 20 degrees or more that
no found curve overlaps (also counted apart where the way has no more nodes than the road
has numbers, so that the nodes cannot determine it). False: a found curve of 20 degrees or more that overlaps no true
curve. Below the floor: found curves whose radius is under
:data:`csws.curvature.corners.FLOOR_RADIUS_M` (reported as the floor, never measured).

The ``spirals`` family was the one the clothoid fit was developed on; the others were
not looked at before their figures were first printed.

Beside the sparse figures stands what the nodes allow (:mod:`benchmarks.bounds`), on the
same nodes: the median and p90 start error and the median radius error of an efficient
estimator told the road's form, from the Cramér-Rao bounds of every true curve's start
and smallest radius; and the median and p90 start error of the maximum-likelihood road
told the road's form and started from the truth, the reference method. A target below
the bound is out of reach of the nodes, whatever the extractor; one below the reference
is beyond what the nodes tell even an estimator that knows which pieces the road has.

Run with ``python -m benchmarks.roads``; :func:`run` returns the figures.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely

from benchmarks.bounds import (
    error_quantile_m,
    ml_start_errors_m,
    parameter_count,
    radius_bounds,
    road_information,
    start_bounds_m,
)
from benchmarks.command import arguments
from csws.curvature import find_curves
from csws.curvature.corners import FLOOR_RADIUS_M
from csws.geometry import Piece, arc, clothoid, piece_starts_s, sample_pieces, straight
from csws.networks.real_roads import true_curves as real_road_curves
from csws.standard import DEFAULT_POLICY

SEED = 20261124
CASES_PER_FAMILY = 40
WARNING_RADIUS_M = 500.0
DENSE_SPACING_M = (0.5, 1.0)
ROUNDING_M = 0.01
SIMPLIFY_TOLERANCE_M = (0.3, 2.0)
NODE_NOISE_RMS_M = 0.5
MIN_COUNTED_ANGLE_DEG = 20.0
APPROACH_M = 150.0

#: Targets: (figure, sampling) -> limit; each figure is per family.
TARGETS = {
    ("max_start_error_m", "dense"): 1.0,
    ("median_radius_error", "sparse"): 0.02,
    ("median_start_error_m", "sparse"): 3.0,
    ("missed", "sparse"): 0,
    ("false", "sparse"): 0,
    ("below_floor", "sparse"): 0,
    ("missed", "dense"): 0,
    ("false", "dense"): 0,
}


@dataclass(frozen=True)
class TrueCurve:
    start_s: float
    end_s: float
    min_radius_m: float
    angle_deg: float


def _direction(rng: np.random.Generator) -> str:
    return str(rng.choice(["left", "right"]))


def _spirals(rng: np.random.Generator) -> list[Piece]:
    radius, side = rng.uniform(30.0, 450.0), _direction(rng)
    angle = max(rng.uniform(10.0, 60.0), math.degrees(15.0 / radius))
    return [
        clothoid(rng.uniform(20.0, 80.0), math.inf, radius, side),
        arc(radius, angle, side),
        clothoid(rng.uniform(20.0, 80.0), radius, math.inf, side),
    ]


def _compound(rng: np.random.Generator) -> list[Piece]:
    side = _direction(rng)
    radii = sorted(rng.choice([250.0, 180.0, 120.0, 90.0, 60.0, 35.0], size=int(rng.integers(2, 4)), replace=False))[
        ::-1
    ]
    with_spirals = bool(rng.integers(0, 2))
    pieces: list[Piece] = [clothoid(40.0, math.inf, radii[0], side)] if with_spirals else []
    for index, radius in enumerate(radii):
        pieces.append(arc(radius, max(15.0, math.degrees(25.0 / radius)), side))
        if with_spirals and index + 1 < len(radii):
            pieces.append(clothoid(30.0, radius, radii[index + 1], side))
    if with_spirals:
        pieces.append(clothoid(40.0, radii[-1], math.inf, side))
    return pieces


def _s_curves(rng: np.random.Generator) -> list[Piece]:
    first, second = rng.uniform(40.0, 300.0, size=2)
    sign = 1.0 if _direction(rng) == "left" else -1.0
    pieces = [Piece(first * math.radians(rng.uniform(20.0, 50.0)), sign / first)]
    if rng.integers(0, 2):
        pieces.append(Piece(rng.uniform(30.0, 80.0), sign / first, -sign / second))
    pieces.append(Piece(second * math.radians(rng.uniform(20.0, 50.0)), -sign / second))
    return pieces


def _split(rng: np.random.Generator) -> list[Piece]:
    radius, side = rng.uniform(40.0, 300.0), _direction(rng)
    angle = max(rng.uniform(20.0, 70.0), math.degrees(20.0 / radius))
    where = rng.uniform(0.1, 0.9)
    return [arc(radius, angle * where, side), arc(radius, angle * (1.0 - where), side)]


def _hairpins(rng: np.random.Generator) -> list[Piece]:
    radius = rng.uniform(15.0, 40.0)
    return [arc(radius, rng.uniform(150.0, 180.0), _direction(rng))]


def _corners(rng: np.random.Generator) -> list[Piece]:
    return [arc(rng.uniform(8.0, 25.0), 90.0, _direction(rng))]


def _gentle(rng: np.random.Generator) -> list[Piece]:
    radius, side = rng.uniform(350.0, 450.0), _direction(rng)
    return [
        clothoid(40.0, math.inf, radius, side),
        arc(radius, rng.uniform(30.0, 60.0), side),
        clothoid(40.0, radius, math.inf, side),
    ]


FAMILIES = {
    "spirals": _spirals,
    "compound": _compound,
    "s_curves": _s_curves,
    "split": _split,
    "hairpins": _hairpins,
    "corners": _corners,
    "gentle": _gentle,
}


def _road(middle: list[Piece]) -> list[Piece]:
    return [straight(APPROACH_M), *middle, straight(APPROACH_M)]


def true_curves(pieces: list[Piece], warning_radius_m: float = WARNING_RADIUS_M) -> list[TrueCurve]:
    """The curves of the constructed road from its exact curvature, sampled every 1 cm
    (:func:`csws.networks.real_roads.true_curves`)."""
    return [
        TrueCurve(c["start_s"], c["end_s"], c["min_radius_m"], c["angle_deg"])
        for c in real_road_curves(pieces, warning_radius_m, sampling_m=0.01)
    ]


def _node_points(
    pieces: list[Piece], family: str, rng: np.random.Generator, dense_xy: np.ndarray, dense_s: np.ndarray
) -> np.ndarray:
    """The sparse way's nodes on the true road: Douglas-Peucker of the dense line, plus the
    family's own nodes (the split node; a corner's one to three nodes and its straights')."""
    simplified = shapely.simplify(shapely.LineString(dense_xy), float(rng.uniform(*SIMPLIFY_TOLERANCE_M)))
    nodes = shapely.get_coordinates(simplified)
    starts = piece_starts_s(pieces)
    extra_s: list[float] = []
    if family == "split":
        extra_s.append(float(starts[2]))
    if family == "corners":
        count = int(rng.integers(1, 4))
        extra_s += list(starts[1] + (np.arange(count) + 0.5) / count * pieces[1].length_m)
        nodes = nodes[[0, -1]]  # a corner's way: its ends, nodes along the straights and on the arc
        extra_s += list(np.arange(10.0, APPROACH_M - 5.0, 25.0)) + list(
            starts[2] + np.arange(5.0, APPROACH_M - 10.0, 25.0)
        )
    if extra_s:
        extra = np.column_stack([np.interp(extra_s, dense_s, dense_xy[:, k]) for k in (0, 1)])
        line = shapely.LineString(dense_xy)
        order_s = np.concatenate((line.project(shapely.points(nodes)), extra_s))
        nodes = np.concatenate((nodes, extra))[np.argsort(order_s, kind="stable")]
    return nodes


def sample(pieces: list[Piece], family: str, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The road's dense line (exact, 5 cm apart) with its arc lengths, and its dense and sparse samplings."""
    exact_xy, exact_s = sample_pieces(pieces, 0.05)
    dense = np.round(sample_pieces(pieces, float(rng.uniform(*DENSE_SPACING_M)))[0] / ROUNDING_M) * ROUNDING_M
    nodes = _node_points(pieces, family, rng, exact_xy, exact_s)
    noisy = nodes + rng.normal(0.0, NODE_NOISE_RMS_M / math.sqrt(2.0), nodes.shape)
    return np.column_stack((exact_xy, exact_s)), dense, noisy


def node_references(pieces: list[Piece], truth: list[TrueCurve], exact: np.ndarray, nodes: np.ndarray) -> dict:
    """What the sparse way's ``nodes`` allow, taken at their places along the true road
    (``exact``: its dense line and arc lengths): the Cramér-Rao bounds of every true
    curve's start (m) and relative smallest radius, and the start errors of the
    maximum-likelihood road told the road's form (m); and whether the nodes are too few to
    determine the road (:func:`benchmarks.bounds.parameter_count`)."""
    node_s = shapely.LineString(exact[:, :2]).project(shapely.points(nodes))
    information = road_information(pieces, np.sort(node_s), NODE_NOISE_RMS_M)
    return {
        "undetermined": len(nodes) <= parameter_count(pieces),
        "start_bounds_m": start_bounds_m(information, WARNING_RADIUS_M),
        "radius_bounds": radius_bounds(information, [(c.start_s, c.end_s) for c in truth]),
        "ml_start_errors_m": ml_start_errors_m(pieces, nodes, node_s, WARNING_RADIUS_M),
    }


def _true_s(line: shapely.LineString, xy: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Arc lengths along a sampled polyline mapped to the true road's, by projecting onto it."""
    step = np.hypot(*np.diff(xy, axis=0).T)
    along = np.concatenate(([0.0], np.cumsum(step)))
    points = np.column_stack((np.interp(s, along, xy[:, 0]), np.interp(s, along, xy[:, 1])))
    return line.project(shapely.points(points))


def score(truth: list[TrueCurve], exact: np.ndarray, xy: np.ndarray) -> dict:
    """Per true curve the start and radius errors; the missed, false and below-floor counts."""
    line = shapely.LineString(exact[:, :2])
    found = find_curves(xy, WARNING_RADIUS_M, policy=DEFAULT_POLICY)
    ends = (
        _true_s(line, xy, np.array([[c.start_s, c.end_s] for c in found]).reshape(-1)).reshape(-1, 2)
        if found
        else np.zeros((0, 2))
    )
    start_errors, radius_errors, missed, matched = [], [], 0, set()
    for curve in truth:
        overlap = np.minimum(ends[:, 1], curve.end_s) - np.maximum(ends[:, 0], curve.start_s)
        if not np.any(overlap > 0):
            missed += curve.angle_deg >= MIN_COUNTED_ANGLE_DEG
            continue
        best = int(np.argmax(overlap))
        matched.add(best)
        start_errors.append(abs(ends[best, 0] - curve.start_s))
        radius_errors.append(abs(found[best].min_radius_m / curve.min_radius_m - 1.0))
    false = sum(
        1
        for index, curve in enumerate(found)
        if index not in matched
        and curve.angle_deg >= MIN_COUNTED_ANGLE_DEG
        and not any(min(ends[index, 1], t.end_s) > max(ends[index, 0], t.start_s) for t in truth)
    )
    below = sum(curve.min_radius_m < FLOOR_RADIUS_M - 1e-9 for curve in found)
    return {
        "start_errors": start_errors,
        "radius_errors": radius_errors,
        "missed": missed,
        "false": false,
        "below_floor": below,
    }


def _summary(scores: list[dict]) -> dict:
    start = np.array([e for s in scores for e in s["start_errors"]])
    bounds = np.array([b for s in scores for b in s.get("start_bounds_m", ())])
    radius_bound = np.array([b for s in scores for b in s.get("radius_bounds", ()) if np.isfinite(b)])
    reference = np.array([e for s in scores for e in s.get("ml_start_errors_m", ())])
    radius = np.array([e for s in scores for e in s["radius_errors"]])
    return {
        "curves": int(len(start)),
        "median_radius_error": float(np.median(radius)) if len(radius) else math.inf,
        "median_start_error_m": float(np.median(start)) if len(start) else math.inf,
        "p90_start_error_m": float(np.percentile(start, 90)) if len(start) else math.inf,
        "max_start_error_m": float(start.max()) if len(start) else math.inf,
        "missed": int(sum(s["missed"] for s in scores)),
        "missed_undetermined": int(sum(s["missed"] for s in scores if s.get("undetermined"))),
        "false": int(sum(s["false"] for s in scores)),
        "below_floor": int(sum(s["below_floor"] for s in scores)),
    } | (
        {
            "bound_median_start_error_m": error_quantile_m(bounds, 0.5),
            "bound_p90_start_error_m": error_quantile_m(bounds, 0.9),
            "bound_median_radius_error": error_quantile_m(radius_bound, 0.5),
            "reference_median_start_error_m": float(np.median(reference)),
            "reference_p90_start_error_m": float(np.percentile(reference, 90)),
        }
        if len(bounds)
        else {}
    )


def run(cases: int = CASES_PER_FAMILY, seed: int = SEED) -> dict:
    """Every family's figures, dense and sparse: ``{family: {"dense": {...}, "sparse": {...}}}``."""
    rng = np.random.default_rng(seed)
    figures = {}
    for family, build in FAMILIES.items():
        scores: dict[str, list[dict]] = {"dense": [], "sparse": []}
        for _ in range(cases):
            pieces = _road(build(rng))
            truth = true_curves(pieces)
            exact, dense, sparse = sample(pieces, family, rng)
            scores["dense"].append(score(truth, exact, dense))
            scores["sparse"].append(score(truth, exact, sparse) | node_references(pieces, truth, exact, sparse))
        figures[family] = {sampling: _summary(values) for sampling, values in scores.items()}
    return figures


def verdicts(figures: dict) -> list[tuple[str, float, float, bool]]:
    """``(figure name, value, limit, passed)`` for every target of every family."""
    rows = []
    for family, samplings in figures.items():
        for (name, sampling), limit in TARGETS.items():
            value = samplings[sampling][name]
            rows.append((f"roads {family} {sampling}: {name}", value, limit, value <= limit))
    return rows


def report(figures: dict) -> str:
    columns = (
        "curves",
        "median_radius_error",
        "median_start_error_m",
        "p90_start_error_m",
        "max_start_error_m",
        "missed",
        "false",
        "below_floor",
        "bound_median_start_error_m",
        "bound_p90_start_error_m",
        "bound_median_radius_error",
        "reference_median_start_error_m",
        "reference_p90_start_error_m",
    )
    lines = ["family    sampling  " + "  ".join(f"{c:>10.10}" for c in columns)]
    for family, samplings in figures.items():
        for sampling, values in samplings.items():
            lines.append(
                f"{family:<9} {sampling:<8}  " + "  ".join(f"{values.get(c, math.nan):>10.3g}" for c in columns)
            )
    lines += [
        f"{'PASS' if passed else 'FAIL'}  {name} = {value:.3g} (target <= {limit:g})"
        for name, value, limit, passed in verdicts(figures)
    ]
    return "\n".join(lines)


def main() -> None:
    arguments("benchmarks.roads", __doc__)
    print(report(run()))


if __name__ == "__main__":
    main()
