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

What the standard asks of the warning's timing bounds the first figure from below. GB/T 33577
asks the collision warning once a_req (3.22, formula (4)) reaches a threshold of at most 0.68 g
computed with a reaction time of at least 0.8 s (4.5.3, 4.5.4; 0 while the driver brakes), and
5.4.1 checks the warning distance against formula (5), that same a_req of 6.67 m/s^2 after 0.8 s
for a steady subject. The **least-demanding conforming warning** (:func:`standard_requires_warning`)
is that threshold with those least figures, to SUMO's true leader (perfect perception), with every
suppression 4.5.5 allows that SUMO's values show: below V_min = 11.2 m/s, the highest 4.3.3 allows
(4.5.5 g), at a TTC above 4 s (4.5.5 e), while the subject already decelerates at the threshold
(4.5.5 a), and, in a second variant, whenever the driver brakes (4.5.5 d: SUMO's brake light).
Run as a **reference system on the same data** (:mod:`benchmarks.fcw_references`, its level held
as the design's is), its false warnings per vehicle-hour are a floor: any conforming system warns
at those moments too, and they are false by this benchmark's rule. Each of the design's false
onsets is also classed **required by the standard** (the least-demanding warning, without
4.5.5 d, was due at that frame or the next) or **by design choice** (the design's reaction time
of 1.2 s and its preliminary warning warned earlier), with how much earlier.

Run with ``python -m benchmarks.fcw_traffic``; 8-15 minutes on a shared two-core machine (load 6-15).
"""

from __future__ import annotations

import math
import os
import statistics
import time
from collections import Counter
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from benchmarks.command import arguments
from csws.ahead.horizon import PathAhead
from csws.ahead.lookahead import LookAhead
from csws.cosim.categories import category_of
from csws.cosim.config import _config_scenario
from csws.cosim.fcw import BRAKE_LIGHT, FleetFcw
from csws.fcw.conforming import Lead, standard_requires_warning
from csws.fcw.settings import MIN_REACTION_TIME_S
from csws.networks import networks_dir
from csws.road.roadmap import RoadMap
from csws.sumo.binaries import sumo_binary, sumo_home

from .fcw_references import FOLLOW_S, NEAR_TTC_S, REFERENCES, Pending, Reference, settle, situation_of

STEP_S = 0.1
SCENARIOS = {
    "Bad Hersfeld": networks_dir() / "badhersfeld.sumocfg",
    "fleet road": networks_dir() / "fleet_scenario" / "fleet.sumocfg",
}
#: A conflict: the true TTC below this, s (or a collision).
CONFLICT_TTC_S = 1.0
#: A warning is in time for a conflict if it was on at least this long before it (4.5.4), s.
REACTION_S = MIN_REACTION_TIME_S
#: How far SUMO is asked for each vehicle's leader, m.
LEADER_RANGE_M = 200.0
#: A subject turning faster than this is "turning" in the situations, degrees per second.
TURNING_DEG_PER_S = 3.0
TARGET_FALSE_PER_HOUR = 0.1
TARGET_MISSED = 0
#: A design onset is "required by the standard" where the least-demanding warning was due within one frame, s.
REQUIRED_WITHIN_S = STEP_S


@dataclass
class _Counts:
    """What one scenario's run counted (the design's onsets; ``required_lead_s``: of the false ones by design
    that the standard came to require within FOLLOW_S, how long before it the design warned, s)."""

    vehicle_hours: float = 0.0
    active_hours: float = 0.0
    onsets: int = 0
    false_warnings: int = 0
    false_required: int = 0
    false_by_design: int = 0
    required_lead_s: list[float] = field(default_factory=list)
    false_situations: Counter[str] = field(default_factory=Counter)
    conflicts: int = 0
    missed: int = 0
    missed_situations: Counter[str] = field(default_factory=Counter)
    standby_conflicts: int = 0
    collisions: int = 0


def _read_lead(sumo: Any, vehicle_id: str) -> Lead:
    """The vehicle and its leader along its lanes, SUMO's truth."""
    vehicle = sumo.vehicle
    speed_mps, accel_mps2 = vehicle.getSpeed(vehicle_id), vehicle.getAcceleration(vehicle_id)
    braking = bool(vehicle.getSignals(vehicle_id) & BRAKE_LIGHT)
    leader = vehicle.getLeader(vehicle_id, LEADER_RANGE_M)
    if not leader or not leader[0]:
        return Lead(None, math.inf, speed_mps, subject_accel_mps2=accel_mps2, braking=braking)
    return Lead(
        leader[0],
        leader[1] + vehicle.getMinGap(vehicle_id),
        speed_mps,
        vehicle.getSpeed(leader[0]),
        accel_mps2,
        vehicle.getAcceleration(leader[0]),
        braking,
    )


@dataclass
class _Watch:
    """What a scenario's run keeps per vehicle between steps."""

    counts: _Counts = field(default_factory=_Counts)
    pending: list[Pending] = field(default_factory=list)
    references: dict[str, Reference] = field(
        default_factory=lambda: {name: Reference(rule) for name, rule in REFERENCES.items()}
    )
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


def _run_scenario(config: Any, use_map: bool = True) -> _Watch:
    """One scenario whole: the FCW of every equipped vehicle against SUMO's truth (with each vehicle's
    map path ahead where it is map-matched, as the co-simulation gives it, unless ``use_map`` is False),
    and the reference systems on the same run."""
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
            _settle_all(watch, now_s)
        _settle_all(watch, math.inf)
    finally:
        libsumo.close()
    return watch


def _watch_vehicle(
    sumo: Any, watch: _Watch, now_s: float, vehicle_id: str, said: tuple[int, str | None, bool], collided: bool
) -> None:
    """One vehicle's step: its warning onset (judged later), the reference systems' step, and a
    conflict's onset (judged now)."""
    level, target_id, active = said
    lead = _read_lead(sumo, vehicle_id)
    ttc_s, leader_id = lead.ttc_s, lead.leader_id
    angle = sumo.vehicle.getAngle(vehicle_id)
    turning = abs((angle - watch.last_angle.get(vehicle_id, angle) + 180.0) % 360.0 - 180.0) / STEP_S
    watch.last_angle[vehicle_id] = angle
    required = standard_requires_warning(lead)
    for reference in watch.references.values():
        reference.step(sumo, now_s, vehicle_id, lead, turning > TURNING_DEG_PER_S)
    previous, watch.levels[vehicle_id] = watch.levels.get(vehicle_id, 0), level
    if level > 0:
        watch.warned_until[vehicle_id] = now_s
    if level > 0 and previous == 0:
        watch.warned_since[vehicle_id] = now_s
        watch.counts.onsets += 1
        situation = situation_of(sumo, vehicle_id, target_id, leader_id, turning > TURNING_DEG_PER_S)
        watch.pending.append(Pending(vehicle_id, now_s, situation))
    near = ttc_s < NEAR_TTC_S or collided
    for waiting in _waiting_for(watch, vehicle_id):
        waiting.near = waiting.near or near
    for waiting in (w for w in watch.pending if w.vehicle_id == vehicle_id and w.required_after_s is None):
        waiting.required_after_s = now_s - waiting.time_s if required else None
    conflict = ttc_s < CONFLICT_TTC_S or collided
    if conflict and vehicle_id not in watch.in_conflict:
        watch.in_conflict.add(vehicle_id)
        _count_conflict(
            watch.counts, vehicle_id, now_s, active, lead.subject_mps, watch.warned_since, watch.warned_until
        )
    elif not conflict:
        watch.in_conflict.discard(vehicle_id)


def _waiting_for(watch: _Watch, vehicle_id: str) -> list[Pending]:
    """The onsets of one vehicle, the design's and the reference systems', still waiting to be judged."""
    waiting = [w for w in watch.pending if w.vehicle_id == vehicle_id]
    for reference in watch.references.values():
        waiting.extend(w for w in reference.pending if w.vehicle_id == vehicle_id)
    return waiting


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


def _settle_all(watch: _Watch, now_s: float) -> None:
    """Judge the design's and the reference systems' onsets whose FOLLOW_S has passed; class the design's
    false ones by whether the least-demanding conforming warning was due within one frame of them."""
    counts = watch.counts
    watch.pending, false = settle(watch.pending, now_s)
    for onset in false:
        counts.false_warnings += 1
        counts.false_situations[onset.situation] += 1
        after_s = onset.required_after_s
        if after_s is not None and after_s <= REQUIRED_WITHIN_S + 1e-9:
            counts.false_required += 1
            continue
        counts.false_by_design += 1
        if after_s is not None:
            counts.required_lead_s.append(after_s)
    for reference in watch.references.values():
        reference.settle(now_s)


def run() -> dict:
    """Every scenario's figures, and the totals (per equipped vehicle-hour: the design's false warnings,
    those the standard required and those by design choice, and each reference system's)."""
    os.environ.setdefault("SUMO_HOME", str(sumo_home()))
    started = time.perf_counter()
    scenarios = {name: _figures(_run_scenario(config)) for name, config in SCENARIOS.items()}
    hours = sum(s["vehicle_hours"] for s in scenarios.values())

    def per_hour(count: float) -> float:
        return count / hours if hours else math.nan

    def total(key: str) -> int:
        return sum(s[key] for s in scenarios.values())

    return {
        "scenarios": scenarios,
        "vehicle_hours": hours,
        "false_per_vehicle_hour": per_hour(total("false_warnings")),
        "false_required_per_vehicle_hour": per_hour(total("false_required")),
        "false_by_design_per_vehicle_hour": per_hour(total("false_by_design")),
        "references_false_per_vehicle_hour": {
            name: per_hour(sum(s["references"][name]["false_warnings"] for s in scenarios.values()))
            for name in REFERENCES
        },
        "missed": total("missed"),
        "seconds": time.perf_counter() - started,
    }


def _figures(watch: _Watch) -> dict:
    """One scenario's counts as figures (the situations by how often they came)."""
    counts = watch.counts
    figures = asdict(counts)
    figures["false_situations"] = dict(counts.false_situations.most_common())
    figures["missed_situations"] = dict(counts.missed_situations.most_common())
    figures["references"] = {
        name: {
            "onsets": reference.onsets,
            "false_warnings": reference.false_warnings,
            "false_situations": dict(reference.false_situations.most_common()),
        }
        for name, reference in watch.references.items()
    }
    return figures


def main() -> None:
    """Print the figures."""
    arguments("benchmarks.fcw_traffic", __doc__)
    figures = run()
    for name, s in figures["scenarios"].items():
        print(
            f"{name}: {s['vehicle_hours']:.2f} vehicle-h ({s['active_hours']:.2f} active), {s['onsets']} onsets, "
            f"{s['false_warnings']} false ({s['false_required']} required by the standard, "
            f"{s['false_by_design']} by design choice), {s['conflicts']} conflicts while active, "
            f"{s['missed']} missed, {s['standby_conflicts']} below V_min, {s['collisions']} collisions"
        )
        for situation, count in s["false_situations"].items():
            print(f"  false: {count} x {situation}")
        for situation, count in s["missed_situations"].items():
            print(f"  missed: {count} x {situation}")
        if s["required_lead_s"]:
            lead = s["required_lead_s"]
            print(
                f"  by design, later required: {len(lead)}, warned {min(lead):.1f}-{max(lead):.1f} s "
                f"(median {statistics.median(lead):.1f} s) before the standard's latest warning"
            )
        for reference, r in s["references"].items():
            print(f"  {reference}: {r['onsets']} onsets, {r['false_warnings']} false")
            for situation, count in r["false_situations"].items():
                print(f"    false: {count} x {situation}")
    print(
        f"false warnings per vehicle-hour {figures['false_per_vehicle_hour']:.3f} (target <= {TARGET_FALSE_PER_HOUR}): "
        f"{figures['false_required_per_vehicle_hour']:.3f} the standard requires, "
        f"{figures['false_by_design_per_vehicle_hour']:.3f} by design choice; "
        f"missed conflicts {figures['missed']} (target {TARGET_MISSED}), "
        f"{figures['vehicle_hours']:.2f} vehicle-h in {figures['seconds']:.0f} s"
    )
    for name, rate in figures["references_false_per_vehicle_hour"].items():
        print(f"reference, {name}: {rate:.3f} false warnings per vehicle-hour")


if __name__ == "__main__":
    main()
