"""The telematics benchmark's reference methods (benchmarks.telematics_reference) on constructed trajectories:
vehicles driving the junction town (tests/junction_town.py) straight on or into a side street, recorded at
0.1 s as SUMO records them, their sigma 8 m fixes matched by each method against the edges they drove.

Every method places a fix on one of its candidates (or, without one, by dead reckoning), so the share
whose true road is a candidate, or that has none, bounds each from above; the full-trace Viterbi sees
every fix the online matcher sees and more. On the main road, away from the junction, the nearest lane
agreeing with the heading is the true road, so the nearest-road share is at least the share of fixes
the test counts away from the junction.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from junction_town import JUNCTION_XY

from csws.road.roadmap import RoadMap

# The benchmarks are run from the repository, not installed: import them from there.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks.telematics_analysis import Noise  # noqa: E402
from benchmarks.telematics_fleet import STEP_S, Trajectories  # noqa: E402
from benchmarks.telematics_reference import reference_figures  # noqa: E402

NOISE = Noise(position_sigma_m=8.0, heading_sigma_deg=5.0, speed_sigma_kmh=0.5, drop_share=0.02)
SPEED_MPS = 12.0
#: Each vehicle's path of normal lanes (the connections filled in).
PATHS = (["WJ_0", "JE_0"], ["WJ_0", "JS_0"], ["WJ_0", "JN_0"]) * 4


def _recorded(town: RoadMap) -> Trajectories:
    """Each vehicle of PATHS driving its path from 100 m along at SPEED_MPS, a row every STEP_S."""
    columns: dict[str, list] = {name: [] for name in ("step", "vehicle", "x", "y", "heading", "lane", "pos")}
    lane_ids: list[str] = []
    for vehicle, lanes in enumerate(PATHS):
        path = town.expand_path(lanes)
        shapes = [np.asarray(town.lane_shape(lane)) for lane in path]
        vertex_s = [np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(shape, axis=0).T)))) for shape in shapes]
        offsets = np.concatenate(([0.0], np.cumsum([v[-1] for v in vertex_s])))
        start_step = 3 * vehicle  # each vehicle its own phase of the fix instants
        for k, s in enumerate(np.arange(100.0, offsets[-1] - 1.0, SPEED_MPS * STEP_S).tolist()):
            index = int(np.searchsorted(offsets, s, side="right")) - 1
            along, shape, v = s - offsets[index], shapes[index], vertex_s[index]
            segment = min(int(np.searchsorted(v, along, side="right")) - 1, len(shape) - 2)
            dx, dy = shape[segment + 1] - shape[segment]
            if path[index] not in lane_ids:
                lane_ids.append(path[index])
            columns["step"].append(start_step + k)
            columns["vehicle"].append(vehicle)
            columns["x"].append(float(np.interp(along, v, shape[:, 0])))
            columns["y"].append(float(np.interp(along, v, shape[:, 1])))
            columns["heading"].append((90.0 - math.degrees(math.atan2(dy, dx))) % 360.0)
            columns["lane"].append(lane_ids.index(path[index]))
            columns["pos"].append(along * town.lane(path[index]).position_factor)
    rows = len(columns["step"])
    return Trajectories(
        step=np.array(columns["step"]),
        vehicle=np.array(columns["vehicle"]),
        x_m=np.array(columns["x"]),
        y_m=np.array(columns["y"]),
        speed_mps=np.full(rows, SPEED_MPS),
        heading_deg=np.array(columns["heading"]),
        lane=np.array(columns["lane"]),
        lane_pos_m=np.array(columns["pos"]),
        vehicle_ids=[f"v{k}" for k in range(len(PATHS))],
        categories=["N"] * len(PATHS),
        lanes=lane_ids,
    )


def test_the_reference_methods_bound_each_other_on_the_same_fixes(town: RoadMap) -> None:
    trajectories = _recorded(town)
    figures = reference_figures(town, trajectories, NOISE, seed=7)
    sampled = np.flatnonzero(trajectories.step % 10 == 0)
    assert figures["fixes"] == pytest.approx(len(sampled) * (1.0 - NOISE.drop_share), abs=4.0 * math.sqrt(len(sampled)))
    ceiling = figures["reachable_true_road_share"]
    for method in ("online", "full_trace", "nearest"):
        assert 0.0 < figures[f"{method}_true_road_share"] <= ceiling, method
    # more than 3 sigma (24 m) from the junction along the main road only the road's own lane agrees with
    # the heading within the search radius, so at least those fixes' nearest lane is the true road
    main_lanes = [trajectories.lanes.index(lane) for lane in ("WJ_0", "JE_0")]
    on_main = np.isin(trajectories.lane[sampled], main_lanes)
    far = on_main & (np.abs(trajectories.x_m[sampled] - JUNCTION_XY[0]) > 40.0)
    far_share = far.sum() / len(sampled)
    assert figures["nearest_true_road_share"] >= far_share - 4.0 * math.sqrt(far_share / len(sampled))
    assert figures["full_trace_true_road_share"] >= figures["online_true_road_share"] - 0.02
    assert 0.0 <= figures["ambiguous_share"] <= 1.0
