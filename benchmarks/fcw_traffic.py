"""False and missed forward collision warnings in mixed SUMO traffic, every vehicle equipped.

Two bundled scenarios run whole in libsumo at 0.1 s steps with the co-simulation's object FCW
(:class:`csws.cosim.fcw.FleetFcw`, the settings of each vehicle's category) on every vehicle of a
covered class: Bad Hersfeld (``networks/badhersfeld.sumocfg``: a town's streets, junctions,
queues at stop lines, curves) and the fleet road (``networks/fleet_scenario/``: several lanes,
lane changes, mixed cars, buses and trucks).

Each vehicle's map path ahead (the curve warning's horizon on its lane and route, as ``csws cosim``
passes it) assigns the objects' lanes where the vehicle is map-matched.

The truth each step is SUMO's own: each vehicle's leader along its lanes (``getLeader``: the gap
plus ``minGap`` is the clearance) and the true TTC to it, and SUMO's collisions. Counted:

* a **false warning** is a warning onset (level 0 -> >= 1) after which, within
  :data:`FOLLOW_S`, the vehicle's true TTC never fell below :data:`NEAR_TTC_S` and it did not
  collide; per equipped vehicle-hour (target :data:`TARGET_FALSE_PER_HOUR`), with the situations
  they came in (the target ahead stopped or moving, on the same road or across a junction,
  the subject turning);
* a **missed conflict** is a collision, or the true TTC falling below :data:`CONFLICT_TTC_S` while
  the subject's system is active (at or above V_min, 4.3.3), without a warning on at least
  :data:`REACTION_S` (4.5.4's least reaction time) before it, within :data:`FOLLOW_S` (target 0).
  Conflicts below V_min, where the system is in standby, are counted apart.

Run with ``python -m benchmarks.fcw_traffic``; about 1-5 minutes.
"""

from __future__ import annotations

import math
import os
import time
from collections import Counter
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from csws.ahead.horizon import PathAhead
from csws.ahead.lookahead import LookAhead
from csws.cosim.categories import category_of
from csws.cosim.config import _config_scenario
from csws.cosim.fcw import FleetFcw
from csws.networks import networks_dir
from csws.road.roadmap import RoadMap
from csws.sumo.binaries import sumo_binary, sumo_home

STEP_S = 0.1
SCENARIOS = {
    "Bad Hersfeld": networks_dir() / "badhersfeld.sumocfg",
    "fleet road": networks_dir() / "fleet_scenario" / "fleet.sumocfg",
}
#: A warning is judged by what follows it within this time, s.
FOLLOW_S = 4.0
#: A warning is false if the true TTC stays above this in the following FOLLOW_S, s.
NEAR_TTC_S = 1.5
#: A conflict: the true TTC below this, s (or a collision).
CONFLICT_TTC_S = 1.0
#: A warning is in time for a conflict if it was on at least this long before it (4.5.4), s.
REACTION_S = 0.8
#: How far SUMO is asked for each vehicle's leader, m.
LEADER_RANGE_M = 200.0
#: A subject turning faster than this is "turning" in the situations, degrees per second.
TURNING_DEG_PER_S = 3.0
TARGET_FALSE_PER_HOUR = 0.1
TARGET_MISSED = 0


@dataclass
class _Counts:
    """What one scenario's run counted."""

    vehicle_hours: float = 0.0
    active_hours: float = 0.0
    onsets: int = 0
    false_warnings: int = 0
    false_situations: Counter[str] = field(default_factory=Counter)
    conflicts: int = 0
    missed: int = 0
    missed_situations: Counter[str] = field(default_factory=Counter)
    standby_conflicts: int = 0
    collisions: int = 0


@dataclass
class _Pending:
    """A warning onset waiting for what follows it."""

    vehicle_id: str
    time_s: float
    situation: str
    near: bool = False


def _true_ttc_s(sumo: Any, vehicle_id: str, speed_mps: float) -> tuple[float, str | None]:
    """The true TTC to the vehicle's leader along its lanes (``inf`` while not closing) and the leader."""
    vehicle = sumo.vehicle
    leader = vehicle.getLeader(vehicle_id, LEADER_RANGE_M)
    if not leader or not leader[0]:
        return math.inf, None
    clearance_m = leader[1] + vehicle.getMinGap(vehicle_id)
    closing_mps = speed_mps - vehicle.getSpeed(leader[0])
    if closing_mps <= 0.0:
        return math.inf, leader[0]
    return max(clearance_m, 0.0) / closing_mps, leader[0]


def _situation(sumo: Any, vehicle_id: str, target_id: str | None, leader_id: str | None, yaw_turning: bool) -> str:
    """Where a warning came: its target stopped or moving, the subject's leader or another vehicle, turning."""
    if target_id is None:
        return "no target"
    vehicle = sumo.vehicle
    parts = ["target stopped" if vehicle.getSpeed(target_id) < 0.5 else "target moving"]
    if target_id != leader_id:
        parts.append("not the leader (other lane or road)")
    elif vehicle.getRoadID(target_id) != vehicle.getRoadID(vehicle_id):
        parts.append("leader across a junction")
    if yaw_turning:
        parts.append("subject turning")
    return ", ".join(parts)


@dataclass
class _Watch:
    """What a scenario's run keeps per vehicle between steps."""

    counts: _Counts = field(default_factory=_Counts)
    pending: list[_Pending] = field(default_factory=list)
    levels: dict[str, int] = field(default_factory=dict)
    warned_since: dict[str, float] = field(default_factory=dict)
    warned_until: dict[str, float] = field(default_factory=dict)
    in_conflict: set[str] = field(default_factory=set)
    categories: dict[str, str | None] = field(default_factory=dict)
    last_angle: dict[str, float] = field(default_factory=dict)


def _equipped(sumo: Any, watch: _Watch) -> list[str]:
    """The vehicles of a covered class (every one is equipped)."""
    ids = []
    for vehicle_id in sumo.vehicle.getIDList():
        if vehicle_id not in watch.categories:
            found = category_of(sumo.vehicle.getVehicleClass(vehicle_id))
            watch.categories[vehicle_id] = None if found is None else found.value
        if watch.categories[vehicle_id] is not None:
            ids.append(vehicle_id)
    return ids


def _paths_ahead(sumo: Any, lookahead: LookAhead, ids: list[str], routes: dict[str, tuple[str, ...]]) -> list:
    """Each vehicle's map path ahead (the curve warning's horizon on its lane and route), None off the map."""
    vehicle = sumo.vehicle
    lanes = [vehicle.getLaneID(v) for v in ids]
    on_map = [i for i, lane in enumerate(lanes) if lane and lookahead.road_map.has_lane(lane)]
    paths: list[PathAhead | None] = [None] * len(ids)
    if not on_map:
        return paths
    for i in on_map:
        road = vehicle.getRoadID(ids[i])
        if ids[i] not in routes or not (road.startswith(":") or road in routes[ids[i]]):
            routes[ids[i]] = tuple(vehicle.getRoute(ids[i]))
    ahead = lookahead.many(
        [lanes[i] for i in on_map],
        np.array([vehicle.getLanePosition(ids[i]) for i in on_map]),
        np.array([vehicle.getSpeed(ids[i]) * 3.6 for i in on_map]),
        [routes[ids[i]] for i in on_map],
    )
    for i, path in zip(on_map, ahead.paths_ahead(), strict=True):
        paths[i] = path
    return paths


def _run_scenario(config: Any, use_map: bool = True) -> _Counts:
    """One scenario whole: the FCW of every equipped vehicle against SUMO's truth (with each vehicle's
    map path ahead where it is map-matched, as the co-simulation gives it, unless ``use_map`` is False)."""
    import libsumo

    lookahead = LookAhead(RoadMap.load(_config_scenario(config).net)) if use_map else None
    routes: dict[str, tuple[str, ...]] = {}
    libsumo.start(
        [str(sumo_binary("sumo")), "-c", str(config), "--step-length", f"{STEP_S:g}", "--no-warnings", "true"]
        + ["--no-step-log", "true", "--duration-log.disable", "true", "--seed", "0"]
    )
    watch = _Watch()
    try:
        fcw = FleetFcw(libsumo)
        while libsumo.simulation.getMinExpectedNumber() > 0:
            libsumo.simulationStep()
            now_s = libsumo.simulation.getTime()
            fcw.forget(libsumo.simulation.getArrivedIDList())
            ids = _equipped(libsumo, watch)
            paths = _paths_ahead(libsumo, lookahead, ids, routes) if lookahead is not None else None
            columns = fcw(ids, [watch.categories[v] or "" for v in ids], [True] * len(ids), paths)
            collided = set(libsumo.simulation.getCollidingVehiclesIDList())
            watch.counts.collisions += len(collided & set(ids))
            watch.counts.vehicle_hours += len(ids) * STEP_S / 3600.0
            for i, vehicle_id in enumerate(ids):
                active = columns.state[i] == "active"
                watch.counts.active_hours += STEP_S / 3600.0 if active else 0.0
                _watch_vehicle(
                    libsumo,
                    watch,
                    now_s,
                    vehicle_id,
                    (columns.level[i], columns.target_id[i], active),
                    vehicle_id in collided,
                )
            watch.pending = _settle(watch.counts, watch.pending, now_s)
        _settle(watch.counts, watch.pending, math.inf)
    finally:
        libsumo.close()
    return watch.counts


def _watch_vehicle(
    sumo: Any, watch: _Watch, now_s: float, vehicle_id: str, said: tuple[int, str | None, bool], collided: bool
) -> None:
    """One vehicle's step: its warning onset (judged later), and a conflict's onset (judged now)."""
    level, target_id, active = said
    speed_mps = sumo.vehicle.getSpeed(vehicle_id)
    ttc_s, leader_id = _true_ttc_s(sumo, vehicle_id, speed_mps)
    angle = sumo.vehicle.getAngle(vehicle_id)
    turn = abs((angle - watch.last_angle.get(vehicle_id, angle) + 180.0) % 360.0 - 180.0) / STEP_S
    watch.last_angle[vehicle_id] = angle
    previous, watch.levels[vehicle_id] = watch.levels.get(vehicle_id, 0), level
    if level > 0:
        watch.warned_until[vehicle_id] = now_s
    if level > 0 and previous == 0:
        watch.warned_since[vehicle_id] = now_s
        watch.counts.onsets += 1
        situation = _situation(sumo, vehicle_id, target_id, leader_id, turn > TURNING_DEG_PER_S)
        watch.pending.append(_Pending(vehicle_id, now_s, situation))
    if ttc_s < NEAR_TTC_S or collided:
        for waiting in watch.pending:
            waiting.near = waiting.near or waiting.vehicle_id == vehicle_id
    conflict = ttc_s < CONFLICT_TTC_S or collided
    if conflict and vehicle_id not in watch.in_conflict:
        watch.in_conflict.add(vehicle_id)
        _count_conflict(watch.counts, vehicle_id, now_s, active, speed_mps, watch.warned_since, watch.warned_until)
    elif not conflict:
        watch.in_conflict.discard(vehicle_id)


def _count_conflict(
    counts: _Counts, vehicle_id: str, now_s: float, active: bool, speed_mps: float, onsets: dict, until: dict
) -> None:
    """Count a conflict's onset: missed unless a warning came on at least REACTION_S before it and was
    on within FOLLOW_S of it."""
    if not active:
        counts.standby_conflicts += 1
        return
    counts.conflicts += 1
    onset_s = onsets.get(vehicle_id, math.inf)
    if onset_s <= now_s - REACTION_S and until.get(vehicle_id, -math.inf) >= now_s - FOLLOW_S:
        return
    counts.missed += 1
    counts.missed_situations[f"{speed_mps:.0f} m/s, warned {'late' if onset_s <= now_s else 'never'}"] += 1


def _settle(counts: _Counts, pending: list[_Pending], now_s: float) -> list[_Pending]:
    """Judge the onsets whose FOLLOW_S has passed; the rest wait."""
    waiting = []
    for onset in pending:
        if now_s - onset.time_s < FOLLOW_S:
            waiting.append(onset)
        elif not onset.near:
            counts.false_warnings += 1
            counts.false_situations[onset.situation] += 1
    return waiting


def run() -> dict:
    """Every scenario's figures, and the totals."""
    os.environ.setdefault("SUMO_HOME", str(sumo_home()))
    started = time.perf_counter()
    scenarios = {name: _figures(_run_scenario(config)) for name, config in SCENARIOS.items()}
    hours = sum(s["vehicle_hours"] for s in scenarios.values())
    false = sum(s["false_warnings"] for s in scenarios.values())
    return {
        "scenarios": scenarios,
        "vehicle_hours": hours,
        "false_per_vehicle_hour": false / hours if hours else math.nan,
        "missed": sum(s["missed"] for s in scenarios.values()),
        "seconds": time.perf_counter() - started,
    }


def _figures(counts: _Counts) -> dict:
    """One scenario's counts as figures (the situations by how often they came)."""
    figures = asdict(counts)
    figures["false_situations"] = dict(counts.false_situations.most_common())
    figures["missed_situations"] = dict(counts.missed_situations.most_common())
    return figures


def main() -> None:
    """Print the figures."""
    figures = run()
    for name, s in figures["scenarios"].items():
        print(
            f"{name}: {s['vehicle_hours']:.2f} vehicle-h ({s['active_hours']:.2f} active), {s['onsets']} onsets, "
            f"{s['false_warnings']} false, {s['conflicts']} conflicts while active, {s['missed']} missed, "
            f"{s['standby_conflicts']} below V_min, {s['collisions']} collisions"
        )
        for situation, count in s["false_situations"].items():
            print(f"  false: {count} x {situation}")
        for situation, count in s["missed_situations"].items():
            print(f"  missed: {count} x {situation}")
    print(
        f"false warnings per vehicle-hour {figures['false_per_vehicle_hour']:.3f} (target <= {TARGET_FALSE_PER_HOUR}), "
        f"missed conflicts {figures['missed']} (target {TARGET_MISSED}), "
        f"{figures['vehicle_hours']:.2f} vehicle-h in {figures['seconds']:.0f} s"
    )


if __name__ == "__main__":
    main()
