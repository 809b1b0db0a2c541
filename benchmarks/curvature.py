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

On the sparse ways two references say what the nodes allow (:mod:`benchmarks.curvature_reference`):
the Cramér-Rao bound on the start's standard deviation, and the maximum-likelihood road of the
true form, a fit told that the road is straight-arc-straight and searched from starts about the
truth. An extractor, which must also find the form, cannot be expected to start arcs closer than
that fit does. The roads themselves are built by :mod:`benchmarks.curvature_roads`.

Speed: vertices per second on a synthetic network of dense lane shapes and on the sparse
ways (the bundled real network's load is timed by :mod:`benchmarks.roadmap`).

Run with ``python -m benchmarks.curvature``; :func:`run` returns the figures.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from benchmarks.command import arguments
from benchmarks.curvature_reference import bound_figures, reference_figures
from benchmarks.curvature_roads import (
    ARC_WARNING_RADIUS_M,
    MAPPED_ARC_FRACTION,
    MAPPED_RADIUS_FRACTION,
    Road,
    arc_road,
    dense_shape,
    mapped_way,
    sparse_way,
    straight_road,
)
from csws.curvature import find_curves, radius_profiles, three_point_radius
from csws.geometry import arc, straight
from csws.standard import DEFAULT_POLICY, DEFAULT_WARNING_RADIUS_M

SEED = 20180091
CASES_PER_CATEGORY = 300
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
#: A found curve: (start_s, end_s, radius_m).
FoundCurve = tuple[float, float, float]


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
