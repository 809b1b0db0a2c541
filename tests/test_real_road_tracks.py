"""The real-road tracks: their networks against the generator and the constructed truth, their
judge against formula (1) computed here, and real runs in SUMO.

What formula (1) requires is computed in this file from the authored pieces in the truth
file, Tables 1-2 and formula (1), point by point; the judge's own code is not used for it.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from csws.conformance.drive import Trace, truth
from csws.conformance.realroads import REAL_ROAD_TABLE, judge_real_road_run, real_road_rows
from csws.conformance.run import conformance, select_rows
from csws.geometry import Piece, curvature_at, sample_pieces
from csws.networks import networks_dir
from csws.networks.real_roads import compare_real_roads, real_road_specs
from csws.road.roadmap import RoadMap
from csws.standard import Category, kmh_to_mps, warning_distance, warning_speed

REAL_ROADS = networks_dir() / "real_roads"
TRACKS = [spec.name for spec in real_road_specs()]


def _content(track: str) -> dict:
    return json.loads((REAL_ROADS / f"{track}.truth.json").read_text("utf-8"))


def _pieces(content: dict) -> list[Piece]:
    return [
        Piece(p["length_m"], p["curvature"], None if p["end_curvature"] == p["curvature"] else p["end_curvature"])
        for p in content["pieces"]
    ]


@pytest.mark.sumo
def test_the_shipped_real_road_networks_are_the_generator_s() -> None:
    assert compare_real_roads(REAL_ROADS) == []


@pytest.mark.parametrize("track", TRACKS)
def test_the_map_s_curves_are_the_constructed_ones(track: str) -> None:
    content = _content(track)
    road_map = RoadMap.load(REAL_ROADS / f"{track}.net.xml")
    path = road_map.path_profile(road_map.expand_path([f"{edge}_0" for edge in content["route"]["edges"]]))
    found = path.road_curves()
    assert len(found) == len(content["curves"])
    for curve, true in zip(found, content["curves"], strict=False):
        assert curve.start_s == pytest.approx(true["start_s"], abs=0.5)
        assert curve.end_s == pytest.approx(true["end_s"], abs=0.5)
        assert curve.min_radius_m == pytest.approx(true["min_radius_m"], rel=0.01)
        assert curve.direction == true["direction"]


def test_the_truth_curves_follow_from_the_pieces() -> None:
    # Where the authored curvature crosses 1/R_c, found here by bisection on the exact pieces.
    for track in TRACKS:
        content = _content(track)
        pieces = _pieces(content)
        for curve in content["curves"]:
            for s, inside in (
                (curve["start_s"] - 0.01, False),
                (curve["start_s"] + 0.01, True),
                (curve["end_s"] - 0.01, True),
                (curve["end_s"] + 0.01, False),
            ):
                radius_m = 1.0 / max(abs(float(curvature_at(pieces, np.array([s]))[0])), 1e-12)
                assert (radius_m <= content["warning_radius_m"]) == inside, (track, s, radius_m)


def _formula_1_levels(track: str, category: Category, speed_kmh: float, route_s: np.ndarray) -> np.ndarray:
    """Per position, the highest level formula (1) requires at some curve point ahead or under it."""
    content = _content(track)
    pieces = _pieces(content)
    points = np.concatenate([np.arange(c["start_s"], c["end_s"], 0.1) for c in content["curves"]])
    radii = 1.0 / np.abs(curvature_at(pieces, points))
    levels = np.zeros(len(route_s), dtype=np.int8)
    for level in (1, 2):
        v_w = np.array([warning_speed(r, category, level) for r in radii])
        s_w = np.array([warning_distance(speed_kmh, v) if speed_kmh >= v else -math.inf for v in v_w])
        for i, s in enumerate(route_s):
            ahead = points - s
            if np.any((ahead >= 0) & (ahead <= s_w)):
                levels[i] = level
    return levels


def _trace(track: str, row, levels: np.ndarray, route_s: np.ndarray, step_s: float) -> Trace:
    time_s = np.arange(len(route_s)) * step_s
    return Trace(0, 0.0, time_s, route_s, np.full(len(route_s), row.speed_kmh), levels.astype(np.int8))


def test_the_judge_passes_formula_1_and_fails_late_early_and_short_warnings() -> None:
    track = "rr_compound"
    row = next(
        r
        for r in real_road_rows()
        if r.tracks == (track,) and r.category is Category.N and r.speed_kmh > warning_speed(35.0, Category.N, 2)
    )
    step_s = 0.05
    travel_m = kmh_to_mps(row.speed_kmh) * step_s
    first = truth(track).curve_start_s_m[0]
    route_s = np.arange(first - 250.0, truth(track).curve_end_s_m[-1] + 40.0, travel_m)
    exact = _formula_1_levels(track, Category.N, row.speed_kmh, route_s)
    assert set(exact) == {0, 1, 2}
    ok = judge_real_road_run(row, _trace(track, row, exact, route_s, step_s), truth(track))
    assert ok.passed, [c.reason for c in ok.checks]

    late = np.roll(exact, round(3.0 / travel_m))  # every change 3 m late
    result = judge_real_road_run(row, _trace(track, row, late, route_s, step_s), truth(track))
    assert not result.passed and "not yet on" in result.checks[0].reason

    early = exact.copy()
    onset = int(np.flatnonzero(exact >= 1)[0])
    early[onset - round(15.0 / travel_m) : onset] = 1  # 15 m before formula (1) asks
    result = judge_real_road_run(row, _trace(track, row, early, route_s, step_s), truth(track))
    assert not result.passed and "raised" in result.checks[0].reason

    short = exact.copy()
    last = int(np.flatnonzero(exact >= 1)[-1])
    short[last - round(5.0 / travel_m) : last + 1] = 0  # off 5 m before the last point that requires it
    result = judge_real_road_run(row, _trace(track, row, short, route_s, step_s), truth(track))
    assert not result.passed and " off at" in result.checks[0].reason


def test_every_category_runs_every_track_at_a_level_1_and_a_level_2_speed() -> None:
    rows = real_road_rows()
    assert {row.tracks[0] for row in rows} == set(TRACKS)
    assert all(row.table == REAL_ROAD_TABLE for row in rows)
    for track in TRACKS:
        for category in Category:
            speeds = sorted(r.speed_kmh for r in rows if r.tracks == (track,) and r.category is category)
            radius_m = min(c["min_radius_m"] for c in _content(track)["curves"])
            level1, level2 = warning_speed(radius_m, category, 1), warning_speed(radius_m, category, 2)
            assert len(speeds) == 2 and level1 < speeds[0] < level2 < speeds[1]


@pytest.mark.slow
@pytest.mark.sumo
def test_a_curve_with_a_node_inside_and_a_compound_curve_pass_in_sumo(tmp_path) -> None:
    rows = select_rows(patterns=["RR-node_in_curve-M1-*", "RR-compound-N-*"])
    outcomes = conformance(rows, tmp_path, (0.01, 0.2), seed=5, jobs=1)
    assert len(outcomes) == 4
    failures = [(o.row.row_id, run.checks) for o in outcomes for g in o.groups for run in g.runs if not run.passed]
    assert all(o.passed for o in outcomes), failures
    report = (tmp_path / "report.md").read_text("utf-8")
    assert "real-road tracks: **PASS**" in report and "Real-road tracks, judged by formula (1)" in report
    assert all((tmp_path / o.plot).is_file() for o in outcomes)


def test_the_authored_line_is_the_pieces() -> None:
    # The line the judge projects positions onto ends where the route ends.
    for track in TRACKS:
        content = _content(track)
        xy, s = sample_pieces(_pieces(content), 0.25)
        assert s[-1] == pytest.approx(content["route"]["length_m"], abs=1e-5)  # truth rounded to 1 um per piece
        assert truth(track).line.length == pytest.approx(content["route"]["length_m"], abs=0.01)
