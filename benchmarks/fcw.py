"""Measures the forward collision warning from a sensor's object list per frame: one vehicle, and a fleet.

Each vehicle has 10 objects: a lead and a car further ahead in its lane, the others in the lanes
beside (as a radar's track list on a motorway), closing at a few m/s, drawn at random; the subject
follows a gentle curve (yaw rate path), or, for the map rows, a map path of 20 knots.

* one vehicle in-process: :meth:`csws.fcw.tracker.ForwardCollisionWarning.update`, per frame
  (the best of several runs of many frames, as the machine is shared);
* a fleet of 1,000 vehicles in one call: :func:`csws.fcw.fleet.update_fleet`, per vehicle and frame.

Run with ``python -m benchmarks.fcw``; ``python -m benchmarks.fcw --profile`` prints instead where one
vehicle's frame goes (cProfile of the single loop: the functions by their own time, and the calls a frame).
"""

from __future__ import annotations

import argparse
import cProfile
import io
import pstats
import time

import numpy as np

from benchmarks.command import arguments
from csws.fcw.fleet import FleetEgo, FleetMemory, FleetObjects, FleetPaths, update_fleet
from csws.fcw.objects import EgoMotion, SensorObject
from csws.fcw.path import PathCurvature
from csws.fcw.settings import FcwSettings
from csws.fcw.tracker import ForwardCollisionWarning

OBJECTS = 10
FRAME_S = 0.05
TARGET_SINGLE_US = 30.0
TARGET_BATCH_US = 5.0


def _objects(rng: np.random.Generator, count: int) -> list[tuple[float, float, float, float]]:
    """(x, y, v_r, a) of ``count`` objects: two in the lane, the rest beside it."""
    lanes = np.concatenate(([0.0, 0.0], rng.choice([-3.5, 3.5], count - 2)))
    return [
        (float(rng.uniform(10.0, 150.0)), float(lane + rng.uniform(-0.5, 0.5)), float(rng.uniform(-8.0, 2.0)), 0.0)
        for lane in lanes
    ]


def _map_path() -> PathCurvature:
    """20 knots: a straight into a left R 400 m curve."""
    s = np.linspace(0.0, 190.0, 20)
    return PathCurvature(tuple(s.tolist()), tuple(np.clip((s - 40.0) / 40.0, 0.0, 1.0) / 400.0))


def _single_frame(map_path: bool, seed: int) -> tuple[EgoMotion, list[SensorObject]]:
    """One vehicle's frame: the subject on a gentle curve (or a map path) and :data:`OBJECTS` objects."""
    rng = np.random.default_rng(seed)
    objects = [SensorObject(i, *values) for i, values in enumerate(_objects(rng, OBJECTS))]
    return EgoMotion(25.0, yaw_rate_rps=25.0 / 2000.0, map_path=_map_path() if map_path else None), objects


def single_us(frames: int = 1000, runs: int = 12, map_path: bool = False, seed: int = 3) -> float:
    """µs per frame of one vehicle with :data:`OBJECTS` objects (the best run)."""
    ego, objects = _single_frame(map_path, seed)
    best = float("inf")
    for _ in range(runs):
        fcw = ForwardCollisionWarning(FcwSettings.for_category("M1"))
        start = time.perf_counter()
        for k in range(frames):
            fcw.update(k * FRAME_S, ego, objects)
        best = min(best, (time.perf_counter() - start) / frames)
    return best * 1e6


def batch_us(vehicles: int = 1000, frames: int = 20, map_path: bool = False, seed: int = 4) -> float:
    """µs per vehicle and frame of a fleet of ``vehicles`` with :data:`OBJECTS` objects each (the best frame)."""
    rng = np.random.default_rng(seed)
    values = np.array([_objects(rng, OBJECTS) for _ in range(vehicles)]).reshape(-1, 4)
    owner = np.repeat(np.arange(vehicles), OBJECTS)
    objects = FleetObjects.of(owner, np.tile(np.arange(OBJECTS), vehicles), *values.T)
    ego = FleetEgo.of(np.full(vehicles, 25.0), yaw_rate_rps=np.full(vehicles, 25.0 / 2000.0))
    paths = None
    if map_path:
        path = _map_path()
        knots = len(path.s_m)
        paths = FleetPaths(
            np.repeat(np.arange(vehicles), knots), np.tile(path.s_m, vehicles), np.tile(path.curvature_1pm, vehicles)
        )
    memory, settings, best = FleetMemory.new(vehicles), FcwSettings.for_category("M1"), float("inf")
    for k in range(frames):
        start = time.perf_counter()
        _, memory = update_fleet(settings, memory, k * FRAME_S, ego, objects, paths)
        best = min(best, time.perf_counter() - start)
    return best / vehicles * 1e6


def single_profile(frames: int = 2000, map_path: bool = False, top: int = 15, seed: int = 3) -> str:
    """cProfile of one vehicle's frames: the ``top`` functions by their own time, after the calls per frame."""
    ego, objects = _single_frame(map_path, seed)
    fcw = ForwardCollisionWarning(FcwSettings.for_category("M1"))
    profiler = cProfile.Profile()
    profiler.enable()
    for k in range(frames):
        fcw.update(k * FRAME_S, ego, objects)
    profiler.disable()
    text = io.StringIO()
    stats = pstats.Stats(profiler, stream=text)
    stats.sort_stats("tottime").print_stats(top)
    calls_per_frame = stats.total_calls / frames  # type: ignore[attr-defined]  # set by pstats, not in its stubs
    return f"{calls_per_frame:.0f} function calls a frame ({OBJECTS} objects)\n{text.getvalue()}"


def run() -> dict:
    """The figures, µs: one vehicle and a fleet of 1,000, each with the yaw rate path and with a map path."""
    return {
        "single_us": single_us(),
        "single_map_us": single_us(map_path=True),
        "batch_per_vehicle_us": batch_us(),
        "batch_map_per_vehicle_us": batch_us(map_path=True),
        "objects": OBJECTS,
        "batch_size": 1000,
    }


def _add_arguments(parser: argparse.ArgumentParser) -> None:
    """The one option: a profile of one vehicle's frames instead of the figures."""
    parser.add_argument("--profile", action="store_true", help="print a profile of one vehicle's frames instead")


def main() -> None:
    """Print the figures beside their targets (with ``--profile``: where one vehicle's frame goes)."""
    given = arguments("benchmarks.fcw", __doc__, _add_arguments)
    if given.profile:
        print(single_profile())
        return
    figures = run()
    print(f"{'figure (10 objects a vehicle)':<44} {'value':>9}  target")
    print(f"{'FCW objects: one vehicle, per frame':<44} {figures['single_us']:>7.1f}us  <= {TARGET_SINGLE_US:g} us")
    print(f"{'FCW objects: one vehicle, map path':<44} {figures['single_map_us']:>7.1f}us")
    print(
        f"{'FCW objects: fleet of 1000, per vehicle':<44} {figures['batch_per_vehicle_us']:>7.2f}us  "
        f"<= {TARGET_BATCH_US:g} us"
    )
    print(f"{'FCW objects: fleet of 1000, map path':<44} {figures['batch_map_per_vehicle_us']:>7.2f}us")


if __name__ == "__main__":
    main()
