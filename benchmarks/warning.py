"""Measures how long the warning takes per vehicle: one at a time, and a fleet in one vectorised batch.

Two figures, each on a bundled test track (Table 9, M1, test 1) with vehicles spread
over the 300 m before the curves at test speed:

* one vehicle in-process: ``Engine.evaluate`` (look-ahead, warning of clause 6 and the
  system state), median over many calls; and the warning step alone
  (``csws.warning.single.evaluate`` on the vehicle's CPOIs);
* a batch: ``Engine.evaluate_many`` for 1,000 vehicles, per vehicle; and the same with
  timestamps 0.1 s apart, so that the release rule keeps each warned vehicle's places and times
  (rules 2 and 4) as a fleet sending timestamps has it do;
* the forward collision warning of 1,000 vehicles in one batch (:func:`csws.fcw.physics.evaluate_fcw`),
  per vehicle;
* the same engine in a city (Bad Hersfeld): vehicles of every category on lanes drawn at random,
  anywhere along them, at 0.7-1.1 times the lane's speed limit, their fixes 0.1 s apart: one vehicle
  at a time (median) and 1,000 in one batch (``Engine.evaluate_fleet``), per vehicle.

Run with ``python -m benchmarks.warning``.
"""

from __future__ import annotations

import json
import statistics
import time
from dataclasses import replace

import numpy as np

from benchmarks.command import arguments
from csws.engine import Engine, VehicleInput
from csws.fcw.physics import evaluate_fcw
from csws.networks import networks_dir
from csws.road.roadmap import RoadMap
from csws.warning.single import evaluate

TRACK = "t9_m1_test1_left"
CITY_NET = "badhersfeld.net.xml.gz"
#: The categories of the city's vehicles, drawn in turn.
CITY_CATEGORIES = ("M1", "M1", "M1", "N", "M2", "M3", "N")
TARGET_SINGLE_US = 30.0
TARGET_BATCH_US = 5.0
TARGET_FCW_BATCH_US = 5.0


def _vehicles(truth: dict, count: int, speed_kmh: float) -> list[VehicleInput]:
    """``count`` vehicles on the 300 m before the first curve, at ``speed_kmh``."""
    start_s = truth["curves"][0]["start_s"]
    lanes = truth["lanes"]
    vehicles = []
    for i, s in enumerate(np.linspace(start_s - 300.0, start_s + 20.0, count)):
        lane = next(lane for lane in reversed(lanes) if lane["start_s"] <= s)
        vehicles.append(
            VehicleInput(
                f"v{i}", "M1", speed_kmh, lane["lane"], float(s - lane["start_s"]), route_edges=truth["route"]["edges"]
            )
        )
    return vehicles


def _median_us(function, arguments, repeat: int) -> float:
    """Median wall time of ``function(argument)`` over the arguments, repeated, µs."""
    for argument in arguments:
        function(argument)  # warm the caches
    samples = []
    for _ in range(repeat):
        for argument in arguments:
            start = time.perf_counter()
            function(argument)
            samples.append(time.perf_counter() - start)
    return statistics.median(samples) * 1e6


def _batch_us(engine: Engine, fleet: list[VehicleInput], period_s: float | None = None, repeat: int = 7) -> float:
    """Least wall time per vehicle of ``engine.evaluate_many(fleet)``, µs; with ``period_s`` each update
    carries timestamps that period apart, so that the release rule keeps its memories' places and times."""
    timings = []
    for update in range(repeat + 1):
        if period_s is not None:
            fleet = [replace(vehicle, timestamp_s=update * period_s) for vehicle in fleet]
        start = time.perf_counter()
        engine.evaluate_many(fleet)
        if update:  # the first warms the caches
            timings.append(time.perf_counter() - start)
    return min(timings) / len(fleet) * 1e6


def _fcw_batch_us(count: int, seed: int = 2) -> float:
    """µs per vehicle of the forward collision warning of ``count`` subject vehicles with
    targets drawn at random (clearance, closing speed, accelerations, some drivers braking)."""
    rng = np.random.default_rng(seed)
    columns = (
        rng.uniform(-4.0, 1.0, count),
        rng.uniform(1.0, 150.0, count),
        rng.uniform(-25.0, 5.0, count),
        rng.uniform(-6.0, 1.0, count),
        rng.random(count) < 0.1,
    )
    timings = []
    for _ in range(20):
        start = time.perf_counter()
        evaluate_fcw(*columns)
        timings.append(time.perf_counter() - start)
    return min(timings) / count * 1e6


def _city_vehicles(road_map: RoadMap, count: int, seed: int = 1) -> list[VehicleInput]:
    """``count`` vehicles on the city's lanes (normal lanes open to cars, longer than 20 m) drawn at random,
    anywhere along them, at 0.7-1.1 times the lane's speed limit."""
    rng = np.random.default_rng(seed)
    lanes = [
        road_map.lane(lane_id)
        for lane_id in road_map.lane_ids
        if not lane_id.startswith(":")
        and road_map.lane(lane_id).length_m > 20.0
        and "passenger" in road_map.lane(lane_id).allowed_vclasses
    ]
    vehicles = []
    for i, k in enumerate(rng.choice(len(lanes), count).tolist()):
        lane = lanes[k]
        vehicles.append(
            VehicleInput(
                f"c{i}",
                CITY_CATEGORIES[i % len(CITY_CATEGORIES)],
                float(lane.speed_limit_mps * 3.6 * rng.uniform(0.7, 1.1)),
                lane.lane_id,
                float(rng.uniform(0.0, lane.length_m)),
            )
        )
    return vehicles


def _city_us(count: int, repeat: int = 5, period_s: float = 0.1) -> tuple[float, float]:
    """The engine in the city: median µs of one vehicle evaluated alone, and least µs per vehicle of
    ``count`` evaluated in one batch, every vehicle's fixes ``period_s`` apart."""
    road_map = RoadMap.load(networks_dir() / CITY_NET)
    fleet = _city_vehicles(road_map, count)
    engine = Engine(road_map)
    samples = []
    for update in range(repeat + 1):
        for vehicle in fleet[: max(count // 4, 1)]:
            vehicle = replace(vehicle, timestamp_s=update * period_s)
            start = time.perf_counter()
            engine.evaluate(vehicle)
            if update:  # the first warms the caches
                samples.append(time.perf_counter() - start)
    batch = Engine(road_map)
    ids = [vehicle.vehicle_id for vehicle in fleet]
    categories = [vehicle.category for vehicle in fleet]
    speeds_kmh = [vehicle.speed_kmh for vehicle in fleet]
    lanes = [vehicle.lane_id for vehicle in fleet]
    positions_m = [vehicle.lane_pos_m for vehicle in fleet]
    timings = []
    for update in range(repeat + 2):
        start = time.perf_counter()
        times_s = [update * period_s] * count
        batch.evaluate_fleet(ids, categories, speeds_kmh, lanes, positions_m, [None] * count, timestamp_s=times_s)
        if update:  # the first warms the caches
            timings.append(time.perf_counter() - start)
    return statistics.median(samples) * 1e6, min(timings) / count * 1e6


def run(batch_size: int = 1000) -> dict:
    """The figures: µs per vehicle alone (whole engine, warning step only) and in a batch, on the test track
    and in the city."""
    truth = json.loads((networks_dir() / f"{TRACK}.truth.json").read_text())
    engine = Engine(RoadMap.load(networks_dir() / f"{TRACK}.net.xml"))
    singles = _vehicles(truth, 200, 130.0)
    engine_us = _median_us(engine.evaluate, singles, repeat=5)
    paths = [engine.evaluate(v).path for v in singles]
    cpois = [path.cpois for path in paths if path is not None]
    if len(cpois) != len(singles):
        raise RuntimeError(f"{len(singles) - len(cpois)} of the track's vehicles matched no lane")
    warning_us = _median_us(lambda c: evaluate(130.0, "M1", c), cpois, repeat=5)
    fleet = _vehicles(truth, batch_size, 130.0)
    batch_us = _batch_us(engine, fleet)
    timed_us = _batch_us(Engine(engine.road_map), fleet, period_s=0.1)
    city_single_us, city_batch_us = _city_us(batch_size)
    return {
        "engine_city_single_median_us": city_single_us,
        "engine_city_batch_per_vehicle_us": city_batch_us,
        "fcw_batch_per_vehicle_us": _fcw_batch_us(batch_size),
        "engine_single_median_us": engine_us,
        "warning_single_median_us": warning_us,
        "engine_batch_per_vehicle_us": batch_us,
        "engine_batch_timed_per_vehicle_us": timed_us,
        "batch_size": batch_size,
    }


def main() -> None:
    """Print the figures beside their targets."""
    arguments("benchmarks.warning", __doc__)
    figures = run()
    print(f"{'figure':<34} {'value':>10}  target")
    print(
        f"{'engine, one vehicle (median)':<34} {figures['engine_single_median_us']:>8.1f}us  <= {TARGET_SINGLE_US:g} us"
    )
    print(f"{'warning step, one vehicle (median)':<34} {figures['warning_single_median_us']:>8.1f}us")
    print(
        f"{'engine, batch of 1000, per vehicle':<34} {figures['engine_batch_per_vehicle_us']:>8.1f}us  "
        f"<= {TARGET_BATCH_US:g} us"
    )
    print(f"{'  the same with timestamps at 10 Hz':<34} {figures['engine_batch_timed_per_vehicle_us']:>8.1f}us")
    print(
        f"{'FCW, batch of 1000, per vehicle':<34} {figures['fcw_batch_per_vehicle_us']:>8.2f}us  "
        f"<= {TARGET_FCW_BATCH_US:g} us"
    )
    print(f"{'city: engine, one vehicle (median)':<34} {figures['engine_city_single_median_us']:>8.1f}us")
    print(f"{'city: engine, batch of 1000, per veh.':<34} {figures['engine_city_batch_per_vehicle_us']:>8.1f}us")


if __name__ == "__main__":
    main()
