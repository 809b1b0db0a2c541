"""How long map matching over the fix sequence takes per fix in a fleet batch.

10,000 vehicles on the bundled Bad Hersfeld network, each at a random position on a normal
lane, send a fix (σ 3 m position noise, 5 degree heading noise) and, one second later,
another after driving on along the road at 10 to 20 m/s: the first batch starts every
vehicle's sequence, the second continues it (candidates, transitions on the lane graph,
the junction rule, the states kept). As in the service, what was loaded is kept out of the garbage
collector's reach (``gc.freeze``). Each batch is matched in one
:meth:`csws.road.hmm.SequenceMatcher.match`; the figure is the time of the second per fix, the best
of three, both on the wall clock and in CPU time of the process (the CPU time is what is judged: on a
machine shared with other work the wall clock shows the others' load too, printed beside it).

With ``--group-sizes`` it times instead what a gateway's small groups cost: the same continuing fixes
matched in groups of 1, 4, 16, 64 and 10,000 vehicles, one :meth:`~csws.road.hmm.SequenceMatcher.match`
per group, in CPU time per call and per fix (best of three rounds over up to 256 groups of each size), and
the fixed cost per call a straight line through the small groups' figures gives.

Run with ``python -m benchmarks.matching`` (``--group-sizes``: the cost per call by group size).
"""

from __future__ import annotations

import argparse
import gc
import math
import os
import time

import numpy as np

from benchmarks.command import arguments
from csws.networks import networks_dir
from csws.road.fixes import subset
from csws.road.hmm import Fixes, SequenceMatcher
from csws.road.matching import Probes, lane_points
from csws.road.roadmap import RoadMap

REAL_NET = networks_dir() / "badhersfeld.net.xml.gz"
#: Most matching time per fix in a batch of 10,000 continuing their sequences, µs.
TARGET_US_PER_FIX = 30.0
#: Group sizes timed by ``--group-sizes``, and the most groups of each timed per round.
GROUP_SIZES = (1, 4, 16, 64, 10_000)
GROUPS_PER_ROUND = 256


def _headings_deg(road_map: RoadMap, lane_ids: list[str], lane_pos_m: np.ndarray) -> np.ndarray:
    """The GNSS heading of each lane position (degrees clockwise from north), from a point 1 m further."""
    headings = []
    for lane_id, pos_m in zip(lane_ids, lane_pos_m.tolist(), strict=True):
        length_m = road_map.lane(lane_id).length_m
        here, ahead = lane_points(road_map, lane_id, np.array([min(pos_m, length_m - 1.0), min(pos_m + 1.0, length_m)]))
        dx, dy = ahead - here
        headings.append((90.0 - math.degrees(math.atan2(dy, dx))) % 360.0)
    return np.array(headings)


def _fixes(road_map: RoadMap, lanes: list[str], pos_m: np.ndarray, time_s: float, rng: np.random.Generator) -> Fixes:
    """Noisy fixes of vehicles at the lane positions."""
    xy = np.vstack([lane_points(road_map, lane, np.array([p])) for lane, p in zip(lanes, pos_m.tolist(), strict=True)])
    xy += rng.normal(0.0, 3.0, xy.shape)
    heading = (_headings_deg(road_map, lanes, pos_m) + rng.normal(0.0, 5.0, len(lanes))) % 360.0
    return Fixes.of(Probes.everywhere(xy), np.full(len(lanes), time_s), heading)


def _fleet(road_map: RoadMap, vehicle_count: int, seed: int) -> tuple[list[str], Fixes, Fixes]:
    """Each vehicle's true lane and its fixes one second apart, driving on along that lane."""
    rng = np.random.default_rng(seed)
    normal = [lane for lane in road_map.lane_ids if not road_map.lane(lane).is_internal]
    long_enough = [lane for lane in normal if road_map.lane(lane).length_m > 45.0]
    lanes = [long_enough[i] for i in rng.integers(0, len(long_enough), vehicle_count).tolist()]
    lengths_m = np.array([road_map.lane(lane).length_m for lane in lanes])
    speed_mps = rng.uniform(10.0, 20.0, vehicle_count)
    first_pos_m = rng.uniform(0.0, lengths_m - speed_mps - 1.0)
    first = _fixes(road_map, lanes, first_pos_m, 0.0, rng)
    second = _fixes(road_map, lanes, first_pos_m + speed_mps, 1.0, rng)
    return lanes, first, second


def run(vehicle_count: int = 10_000, seed: int = 1) -> dict:
    """Match two batches of ``vehicle_count`` fixes; return the µs per fix of each and the share of the
    second batch's fixes matched to their true lane's edge."""
    road_map = RoadMap.load(REAL_NET)
    started = time.perf_counter()
    matcher = SequenceMatcher([road_map])
    built_s = time.perf_counter() - started
    lanes, first, second = _fleet(road_map, vehicle_count, seed)
    gc.freeze()  # as the service does once its networks are loaded (service.app)
    started = time.perf_counter()
    begun = matcher.match(first, [None] * vehicle_count)
    first_s = time.perf_counter() - started
    second_s, second_cpu_s = math.inf, math.inf
    for _repeat in range(3):
        started, started_cpu = time.perf_counter(), time.process_time()
        continued = matcher.match(second, begun.tracks)
        second_s = min(second_s, time.perf_counter() - started)
        second_cpu_s = min(second_cpu_s, time.process_time() - started_cpu)
    true_edges = [road_map.lane(lane).edge_id for lane in lanes]
    on_edge = [
        lane is not None and road_map.lane(lane).edge_id == edge
        for lane, edge in zip(continued.lane_id, true_edges, strict=True)
    ]
    return {
        "vehicles": vehicle_count,
        "graph_build_s": round(built_s, 3),
        "first_us_per_fix": round(first_s / vehicle_count * 1e6, 1),
        "continued_us_per_fix": round(second_s / vehicle_count * 1e6, 1),
        "continued_cpu_us_per_fix": round(second_cpu_s / vehicle_count * 1e6, 1),
        "load_average": round(os.getloadavg()[0], 1),
        "continued_on_true_edge": round(float(np.mean(on_edge)), 4),
    }


def _group_cpu_s(matcher: SequenceMatcher, second: Fixes, tracks: list, size: int) -> tuple[float, int]:
    """CPU time of one round of matching the continuing fixes in consecutive groups of ``size`` (at most
    :data:`GROUPS_PER_ROUND` groups), s, and how many groups it matched."""
    groups = [
        np.arange(start, start + size) for start in range(0, second.probes.count - size + 1, size)[:GROUPS_PER_ROUND]
    ]
    parts = [(subset(second, rows), [tracks[row] for row in rows.tolist()]) for rows in groups]
    started_cpu = time.process_time()
    for fixes, group_tracks in parts:
        matcher.match(fixes, group_tracks)
    return time.process_time() - started_cpu, len(parts)


def run_group_sizes(sizes: tuple[int, ...] = GROUP_SIZES, vehicle_count: int = 10_000, seed: int = 1) -> dict:
    """The CPU time per call and per fix of :meth:`SequenceMatcher.match` for groups of each size of vehicles
    continuing their sequences (best of three rounds), and the fixed cost per call and the cost per fix of a
    least-squares line through the sizes under 100, µs."""
    road_map = RoadMap.load(REAL_NET)
    matcher = SequenceMatcher([road_map])
    _lanes, first, second = _fleet(road_map, vehicle_count, seed)
    tracks = matcher.match(first, [None] * vehicle_count).tracks
    gc.freeze()
    per_call_us = {}
    for size in sizes:
        best_s, groups = math.inf, 1
        for _repeat in range(3):
            round_s, groups = _group_cpu_s(matcher, second, tracks, size)
            best_s = min(best_s, round_s)
        per_call_us[size] = best_s / groups * 1e6
    small = [size for size in sizes if size < 100]
    per_fix_us, fixed_us = np.polyfit(small, [per_call_us[size] for size in small], 1)
    return {
        "per_call_us": {size: round(us, 1) for size, us in per_call_us.items()},
        "per_fix_us": {size: round(us / size, 2) for size, us in per_call_us.items()},
        "fixed_us_per_call": round(float(fixed_us), 1),
        "marginal_us_per_fix": round(float(per_fix_us), 2),
        "load_average": round(os.getloadavg()[0], 1),
    }


def _print_group_sizes(figures: dict) -> None:
    """Print the cost per call and per fix by group size."""
    for size, us in figures["per_call_us"].items():
        print(f"group of {size:>6}: {us:10.1f} µs CPU per call, {figures['per_fix_us'][size]:8.2f} µs per fix")
    print(
        f"groups under 100: {figures['fixed_us_per_call']} µs fixed per call + "
        f"{figures['marginal_us_per_fix']} µs per fix (load average {figures['load_average']})"
    )


def _add_arguments(parser: argparse.ArgumentParser) -> None:
    """The module's one option, ``--group-sizes``."""
    parser.add_argument("--group-sizes", action="store_true", help="only the CPU per call and per fix by group size")


def main() -> None:
    """Print the µs per fix beside the target (``--group-sizes``: the cost per call by group size)."""
    args = arguments("benchmarks.matching", __doc__, _add_arguments)
    if args.group_sizes:
        _print_group_sizes(run_group_sizes())
        return
    figures = run()
    verdict = "PASS" if figures["continued_cpu_us_per_fix"] <= TARGET_US_PER_FIX else "FAIL"
    print(
        f"map matching over the fix sequence, batch of {figures['vehicles']}: "
        f"{figures['continued_cpu_us_per_fix']} µs/fix CPU continuing, target <= {TARGET_US_PER_FIX:g}: {verdict} "
        f"(wall clock {figures['continued_us_per_fix']} µs/fix at load average {figures['load_average']}; "
        f"first fix {figures['first_us_per_fix']} µs/fix); "
        f"{figures['continued_on_true_edge']:.2%} on the true edge; lane graph built in {figures['graph_build_s']} s"
    )


if __name__ == "__main__":
    main()
