"""What any matcher can reach with a feed's fixes: reference methods on the same fixes the service is sent.

The service matches each fix when it arrives (:class:`csws.road.hmm.SequenceMatcher`, online). On the
very same fixes (same rows, same noise, same seed; network x/y, the service's ``accuracy_m``) this
module measures, against the same truth (:func:`benchmarks.telematics_judge.true_roads`):

* **online**: the sequence matcher fed fix by fix, one batch per second, as the service feeds it;
* **after 1 fix, after 2 fixes**: each fix on the Viterbi path of the fixes up to one (two) after it
  (:meth:`SequenceMatcher.match_trace` with ``lag``): what the online matcher decides of a fix once the
  next fix (two) has arrived, e.g. the connection a fix inside a junction is on once the next fix shows it;
* **full trace**: the same hidden-Markov model over each vehicle's whole trace, each fix on the Viterbi
  path the later fixes confirm (:meth:`SequenceMatcher.match_trace`): the offline best of the model;
* **nearest road**: the nearest lane by plain distance among those whose direction agrees with the heading;
* **true road reachable**: the true road among the fix's candidates (lanes within the search radius
  agreeing with the heading), or no candidate at all (dead reckoning may place the fix on it): the
  ceiling of the sequence matcher, which places a fix on a candidate or, without one, by dead reckoning;
* **ambiguous**: fixes within one sigma of two or more roads agreeing with the heading (by geometry
  alone, no matcher can tell which one the fix is on).

Run alone with ``python -m benchmarks.telematics_reference [--quick] [--city NAME]``: the fleet is
driven in SUMO (or read back from ``out/telematics/`` where an earlier run left it) and only the
sigma 8 m 1 Hz fixes are matched, in-process, no service.
"""

from __future__ import annotations

import argparse
import math
import pickle
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

from benchmarks.telematics_analysis import Noise
from benchmarks.telematics_feed import feed_fixes, feed_rows
from benchmarks.telematics_fleet import STEP_S, Trajectories, drive_fleet
from benchmarks.telematics_judge import on_true_road, true_roads
from csws.road.hmm import Fixes, SequenceMatcher, Track
from csws.road.match_settings import MatchSettings
from csws.road.matching import Probes, compass_to_math_rad
from csws.road.roadmap import RoadMap

__all__ = ["reference_figures", "LAGS"]

#: The hindsight methods: each fix on the Viterbi path of the fixes up to this many after it (None: all).
LAGS = {"lag_1": 1, "lag_2": 2, "full_trace": None}


def _fixes_of(
    x_m: np.ndarray, y_m: np.ndarray, heading: np.ndarray, speed: np.ndarray, time_s: np.ndarray, sigma_m: float
) -> Fixes:
    """The sequence matcher's fixes in network x/y, with the receiver's sigma as their accuracy."""
    return Fixes.of(Probes.everywhere(np.column_stack((x_m, y_m))), time_s, heading, speed, np.full(len(x_m), sigma_m))


def _online(matcher: SequenceMatcher, fixes: Fixes, vehicle: np.ndarray, step: np.ndarray) -> list[str | None]:
    """Each fix's lane as the service answers it: one batch per instant, each vehicle continuing its track."""
    lanes: list[str | None] = [None] * len(vehicle)
    tracks: dict[int, Track | None] = defaultdict(lambda: None)
    cuts = np.flatnonzero(np.diff(step)) + 1
    for batch in np.split(np.arange(len(step)), cuts):
        matches = matcher.match(_subset(fixes, batch), [tracks[int(v)] for v in vehicle[batch]])
        for row, lane_id, track in zip(batch.tolist(), matches.lane_id, matches.tracks, strict=True):
            lanes[row] = lane_id
            tracks[int(vehicle[row])] = track
    return lanes


def _subset(fixes: Fixes, rows: np.ndarray) -> Fixes:
    """Some of the fixes (one probe each), renumbered from 0."""
    xy = fixes.probes.xy[rows]
    columns = (fixes.time_s, fixes.heading_deg, fixes.speed_mps, fixes.accuracy_m)
    return Fixes(Probes.everywhere(xy), *(column[rows] for column in columns))


def _traced(matcher: SequenceMatcher, fixes: Fixes, vehicle: np.ndarray, lag: int | None) -> list[str | None]:
    """Each fix's lane on its vehicle's Viterbi path over the fixes up to ``lag`` after it (None: the whole trace)."""
    lanes: list[str | None] = [None] * len(vehicle)
    for number in np.unique(vehicle).tolist():
        rows = np.flatnonzero(vehicle == number)
        matches = matcher.match_trace(_subset(fixes, rows), lag=lag)
        for row, lane_id in zip(rows.tolist(), matches.lane_id, strict=True):
            lanes[row] = lane_id
    return lanes


def _geometry(
    matcher: SequenceMatcher, fixes: Fixes, roads: list[set[str]], sigma_m: float
) -> tuple[list[str | None], np.ndarray, np.ndarray]:
    """Per fix: the nearest lane agreeing with its heading, whether its true road is reachable (among its
    candidates, or no candidate at all), and whether two or more roads agreeing with its heading lie within
    one sigma of it."""
    settings = matcher.settings
    radius_m = max(settings.tolerance_m, settings.search_sigmas * sigma_m)
    found = matcher.index.nearby(fixes.probes, np.full(fixes.probes.count, radius_m))
    fix = fixes.probes.fix[found.point_index]
    off_rad = np.angle(np.exp(1j * (found.heading_rad - compass_to_math_rad(fixes.heading_deg[fix]))))
    agrees = np.abs(off_rad) <= math.radians(settings.heading_tolerance_deg)
    nearest: list[str | None] = [None] * fixes.probes.count
    best_m = np.full(fixes.probes.count, np.inf)
    candidate = np.zeros(fixes.probes.count, dtype=bool)
    near_roads: list[set[str]] = [set() for _ in range(fixes.probes.count)]
    for f, lane_id, distance_m in zip(
        fix[agrees].tolist(), found.lane_id[agrees].tolist(), found.distance_m[agrees].tolist(), strict=True
    ):
        edge = str(lane_id).rpartition("_")[0]
        candidate[f] |= edge in roads[f]
        if distance_m < best_m[f]:
            best_m[f], nearest[f] = distance_m, str(lane_id)
        if distance_m <= sigma_m:
            near_roads[f].add(edge)
    reachable = candidate | (np.bincount(fix[agrees], minlength=fixes.probes.count) == 0)
    return nearest, reachable, np.array([len(edges) >= 2 for edges in near_roads], dtype=bool)


def reference_figures(
    road_map: RoadMap, trajectories: Trajectories, noise: Noise, seed: int, settings: MatchSettings | None = None
) -> dict:
    """The shares of a 1 Hz feed's fixes on their true road by each method (see the module), on the fixes
    the service is sent with that noise and seed."""
    rows, measured = feed_fixes(trajectories, feed_rows(trajectories, 1.0), noise, seed)
    order = np.lexsort((trajectories.vehicle[rows], trajectories.step[rows]))
    rows = rows[order]
    vehicle, step = trajectories.vehicle[rows], trajectories.step[rows]
    sigma_m = noise.position_sigma_m
    fixes = _fixes_of(
        measured.x_m[order],
        measured.y_m[order],
        measured.heading_deg[order],
        measured.speed_kmh[order] / 3.6,
        step * STEP_S,
        sigma_m,
    )
    matcher = SequenceMatcher([road_map], settings or MatchSettings())
    roads = true_roads(trajectories, rows)
    nearest, reachable, ambiguous = _geometry(matcher, fixes, roads, sigma_m)
    online = _online(matcher, fixes, vehicle, step)
    return {
        "fixes": len(rows),
        "online_true_road_share": float(on_true_road(online, roads).mean()),
        "online_no_match_share": float(np.mean([lane is None for lane in online])),
        **{
            f"{name}_true_road_share": float(on_true_road(_traced(matcher, fixes, vehicle, lag), roads).mean())
            for name, lag in LAGS.items()
        },
        "nearest_true_road_share": float(on_true_road(nearest, roads).mean()),
        "reachable_true_road_share": float(reachable.mean()),
        "ambiguous_share": float(ambiguous.mean()),
    }


def summary(figures: dict) -> str:
    """The reference figures in one line."""
    return (
        f"true road: online {figures['online_true_road_share']:.1%} (no match {figures['online_no_match_share']:.2%}), "
        f"after 1 fix {figures['lag_1_true_road_share']:.2%}, after 2 fixes {figures['lag_2_true_road_share']:.2%}, "
        f"full-trace Viterbi {figures['full_trace_true_road_share']:.2%}, nearest road "
        f"{figures['nearest_true_road_share']:.1%}, reachable at all {figures['reachable_true_road_share']:.1%}; "
        f"within sigma of 2+ roads {figures['ambiguous_share']:.1%} of {figures['fixes']:,} fixes"
    )


def _trajectories(net: Path, vehicles: int, duration_s: float, out: Path) -> Trajectories:
    """The fleet's trajectories, driven in SUMO or read back from an earlier run's copy in ``out``."""
    saved = out / f"fleet-{net.name.split('.')[0]}-{vehicles}-{duration_s:g}.pickle"
    if saved.is_file():
        with open(saved, "rb") as stored:
            return pickle.load(stored)  # noqa: S301 - written by this module
    trajectories = drive_fleet(net, vehicles, duration_s)
    out.mkdir(parents=True, exist_ok=True)
    with open(saved, "wb") as stored:
        pickle.dump(trajectories, stored)
    return trajectories


def main(argv: list[str] | None = None) -> int:
    """Drive (or read back) a city's fleet and print the reference figures of its sigma 8 m 1 Hz fixes."""
    from benchmarks.telematics import CITIES, DEFAULT_OUT, SIGMA_8_1_HZ

    parser = argparse.ArgumentParser(
        prog="python -m benchmarks.telematics_reference", description=__doc__.splitlines()[0]
    )
    parser.add_argument("--quick", action="store_true", help="the quick fleet")
    parser.add_argument("--city", default="Bad Hersfeld", help="the city whose name starts with this")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="where the fleet's trajectories are kept")
    args = parser.parse_args(argv)
    city = next(city for city in CITIES if city.name.startswith(args.city))
    if city.net is None:
        parser.error(f"{city.name} has no bundled network")
    vehicles, duration_s = (
        (city.quick_vehicles, city.quick_duration_s) if args.quick else (city.vehicles, city.duration_s)
    )
    trajectories = _trajectories(city.net, vehicles, duration_s, args.out)
    assert SIGMA_8_1_HZ.noise is not None
    figures = reference_figures(RoadMap.load(city.net), trajectories, SIGMA_8_1_HZ.noise, SIGMA_8_1_HZ.seed)
    print(f"{city.name} | {SIGMA_8_1_HZ.name}: {summary(figures)}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
