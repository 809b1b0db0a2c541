"""Driving one FCW row in SUMO (libsumo): one simulation per run, what the system said at every step.

A :class:`Task` is one row at one step length with its repetitions. Each run

* puts the row's vehicles on the road at their start positions and speeds (``insertionChecks``
  off, so vehicles closer than SUMO's safe gap start where the test wants them), keeps them in
  their lanes (``laneChangeMode`` 0) and drives them by ``setSpeed`` with ``speedMode`` 6: their
  own acceleration and deceleration limits, not SUMO's safe speed, so the subject closes on
  a stationary target as the test asks. The target's ``decel`` is the row's
  :attr:`FcwRow.lead_brake_mps2` (0.3 g but in Euro NCAP's CCRb): a commanded stop is a
  constant braking at it;
* starts at its own phase of the simulation step: the subject starts a fraction of one step's
  travel further back, so the runs sample the approach at different points;
* evaluates the subject every step with the co-simulation's object FCW
  (:class:`csws.cosim.fcw.FleetFcw`: the subject's sensor view of the other vehicles and
  :func:`csws.fcw.fleet.update_fleet`, with the settings of its category), through the test
  equipment's accuracy as noise (IVISTA 4.2.2, the FCW counterpart of T/ITS 0091's 7.2.2):
  positions +-0.03 m per vehicle, speeds +-0.1 km/h, accelerations +-0.1 m/s^2, uniform;
* records the true clearance along the subject's lane (from the track's truth), the true
  speeds, and what the system said, until the script's end (:attr:`Script.done`).
"""

from __future__ import annotations

import json
import math
import tempfile
import zlib
from dataclasses import dataclass, field, replace
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

from csws.cosim.categories import category_of
from csws.cosim.fcw import FleetFcw
from csws.fcw.fleet import FleetEgo, FleetObjects
from csws.fcw.physics import time_to_collision_s
from csws.networks import networks_dir
from csws.networks.fcw_tracks import FCW_DIR
from csws.standard import kmh_to_mps
from csws.sumo.binaries import QUIET_OPTIONS, sumo_binary

from .rows import CAR_LENGTH_M, FcwRow
from .scripts import script_of

__all__ = ["POSITION_ACCURACY_M", "SPEED_ACCURACY_MPS", "ACCEL_ACCURACY_MPS2", "Task", "Trace", "track_truth", "drive"]

#: IVISTA 4.2.2: position +-0.03 m, speed +-0.1 km/h, longitudinal acceleration +-0.1 m/s^2.
POSITION_ACCURACY_M = 0.03
SPEED_ACCURACY_MPS = kmh_to_mps(0.1)
ACCEL_ACCURACY_MPS2 = 0.1
#: A run that has not ended after this much simulated time is an error, s.
MAX_SIMULATED_S = 200.0
#: Where the subject starts on the track, m of lane position (its front).
SUBJECT_START_M = {"fcw_straight": 20.0}
#: On the curve tracks the subject starts this far into the arc, m.
INTO_CURVE_M = 10.0

_VTYPES = (
    '<vType id="truck" vClass="truck" length="12" width="2.5" minGap="2.5" accel="1.5" decel="4" '
    'emergencyDecel="9" sigma="0" speedFactor="1" speedDev="0" maxSpeed="40"/>'
    f'<vType id="car" vClass="passenger" length="{CAR_LENGTH_M:g}" width="1.8" minGap="2.5" accel="2.6" '
    'decel="2.941995" emergencyDecel="9" sigma="0" speedFactor="1" speedDev="0" maxSpeed="40"/>'
    '<vType id="truck_target" vClass="truck" length="10" width="2.53" minGap="2.5" accel="1.5" '
    'decel="2.941995" emergencyDecel="9" sigma="0" speedFactor="1" speedDev="0" maxSpeed="40"/>'
)


@dataclass(frozen=True)
class Task:
    """One row at one step length, with its repetitions and seed."""

    row: FcwRow
    step_length_s: float
    repetitions: int
    seed: int

    @property
    def key(self) -> str:
        return f"{self.row.row_id}@{self.step_length_s:g}s"

    @property
    def track(self) -> str:
        return self.row.track


@dataclass(frozen=True)
class Trace:
    """The record of one run, one entry per step from the first.

    Attributes
    ----------
    repetition, phase
        Which run, and its start offset as a fraction of one step's travel.
    time_s
        Simulation time, s.
    clearance_m
        True clearance from the subject's front to the target's (``tv``) rear along its lane, m.
    closing_mps
        True closing speed v_SV - v_TV, m/s.
    subject_mps, target_mps
        True speeds of the subject and the target, m/s.
    target_accel_mps2
        The target's true acceleration over the last step, m/s^2.
    adjacent_ahead_m
        How far the adjacent vehicle's rear is ahead of the subject's front, m (``nan`` without one).
    lateral_m
        The subject's lateral offset from the target's axis, m.
    level
        The warning the system gave (0 outside the active state).
    target
        The id of the system's target (empty without one).
    phase_index
        The script's phase at each step (:class:`csws.conformance.fcw.scripts.Script`).
    """

    repetition: int
    phase: float
    time_s: np.ndarray
    clearance_m: np.ndarray
    closing_mps: np.ndarray
    subject_mps: np.ndarray
    target_mps: np.ndarray
    target_accel_mps2: np.ndarray
    adjacent_ahead_m: np.ndarray
    lateral_m: np.ndarray
    level: np.ndarray
    target: tuple[str, ...]
    phase_index: np.ndarray

    @property
    def ttc_s(self) -> np.ndarray:
        """True TTC, s (formula (2) on the true values; ``inf`` while not closing)."""
        return time_to_collision_s(self.clearance_m, -self.closing_mps)


@cache
def track_truth(track: str) -> dict:
    """A FCW track's truth (``networks/fcw/NAME.truth.json``)."""
    return json.loads((networks_dir() / FCW_DIR / f"{track}.truth.json").read_text("utf-8"))


def lane_metres(track: str, lane: str, from_pos_m: float, to_pos_m: float) -> float:
    """Metres driven on ``lane`` between two lane positions: SUMO's positions follow the road's centre
    line, a lane on the arc is longer or shorter by its radius over the centre line's."""
    curve = track_truth(track)["curve"]
    if curve is None:
        return to_pos_m - from_pos_m
    on_arc = max(0.0, min(to_pos_m, curve["end_pos_m"]) - max(from_pos_m, curve["start_pos_m"]))
    return to_pos_m - from_pos_m + on_arc * (curve["lane_factor"][lane] - 1.0)


def _routes_xml(row: FcwRow, start_m: float, behind_m: float) -> str:
    """The route file: the vehicle types and the row's vehicles, all departing at once, the subject
    ``behind_m`` behind ``start_m`` (its phase)."""
    lengths = {"truck": 12.0, "car": CAR_LENGTH_M, "truck_target": 10.0}
    vehicles = []
    for actor in row.actors:
        front_m = start_m - behind_m if actor.vehicle_id == "sv" else start_m + actor.ahead_m + lengths[actor.vtype]
        vehicles.append(
            f'<vehicle id="{actor.vehicle_id}" type="{actor.vtype}" depart="0" departLane="{actor.lane}" '
            f'departPos="{front_m:.6f}" departSpeed="{actor.speed_mps:.9g}" insertionChecks="none">'
            '<route edges="road"/></vehicle>'
        )
    return f"<routes>{_VTYPES}{''.join(vehicles)}</routes>"


@dataclass
class _Record:
    columns: dict = field(
        default_factory=lambda: {
            name: []
            for name in (
                "time_s",
                "clearance_m",
                "closing_mps",
                "subject_mps",
                "target_mps",
                "target_accel_mps2",
                "adjacent_ahead_m",
                "lateral_m",
                "level",
                "target",
                "phase_index",
            )
        }
    )

    def add(self, **values: float | str | int) -> None:
        """Append one step's values, by column."""
        for name, value in values.items():
            self.columns[name].append(value)

    def trace(self, repetition: int, phase: float) -> Trace:
        c = self.columns
        arrays = {
            name: np.array(values, dtype=float)
            for name, values in c.items()
            if name not in ("level", "target", "phase_index")
        }
        return Trace(
            repetition,
            phase,
            level=np.array(c["level"], dtype=np.int8),
            target=tuple(c["target"]),
            phase_index=np.array(c["phase_index"], dtype=np.int8),
            **arrays,
        )


class _Equipment:
    """The test equipment's accuracy as noise on what the system is given."""

    def __init__(self, rng: np.random.Generator) -> None:
        self.rng = rng

    def uniform(self, bound: float, count: int | None = None) -> Any:
        """Uniform noise in +-``bound``: one number, or ``count`` of them as an array."""
        return self.rng.uniform(-bound, bound, count)

    def measure(self, ego: FleetEgo, objects: FleetObjects) -> tuple[FleetEgo, FleetObjects]:
        """The subject and its objects as the equipment measures them: the subject's speed +-0.1 km/h and
        acceleration +-0.1 m/s^2; each object's position (two vehicles', each +-0.03 m) in x and y, its
        relative speed (two speeds) and its acceleration."""
        n, m = ego.speed_mps.size, objects.x_m.size
        position, speeds = 2.0 * POSITION_ACCURACY_M, 2.0 * SPEED_ACCURACY_MPS
        measured_ego = replace(
            ego,
            speed_mps=np.maximum(ego.speed_mps + self.uniform(SPEED_ACCURACY_MPS, n), 0.0),
            accel_mps2=ego.accel_mps2 + self.uniform(ACCEL_ACCURACY_MPS2, n),
        )
        measured_objects = replace(
            objects,
            x_m=objects.x_m + self.uniform(position, m),
            y_m=objects.y_m + self.uniform(position, m),
            relative_speed_mps=objects.relative_speed_mps + self.uniform(speeds, m),
            accel_mps2=objects.accel_mps2 + self.uniform(ACCEL_ACCURACY_MPS2, m),
        )
        return measured_ego, measured_objects


def _subject_start_m(task: Task) -> float:
    curve = track_truth(task.track)["curve"]
    return SUBJECT_START_M.get(task.track) or curve["start_pos_m"] + INTO_CURVE_M


def _rng(task: Task) -> np.random.Generator:
    return np.random.default_rng([task.seed, zlib.crc32(task.key.encode())])


def drive(task: Task) -> list[Trace]:
    """Run every repetition of a task in SUMO; their records, in order."""
    rng = _rng(task)
    return [
        _run(task, repetition, (repetition + float(rng.uniform())) / task.repetitions, _Equipment(rng))
        for repetition in range(task.repetitions)
    ]


def _run(task: Task, repetition: int, phase: float, equipment: _Equipment) -> Trace:
    """One run: the subject starts ``phase`` of one step's travel further back."""
    import libsumo

    row, step_s = task.row, task.step_length_s
    subject = row.actor("sv")
    behind_m = phase * subject.speed_mps * step_s
    script = script_of(row)
    record = _Record()
    lane_of = {actor.vehicle_id: f"road_{actor.lane}" for actor in row.actors}
    with tempfile.TemporaryDirectory(prefix="csws-fcw-conformance-") as work:
        routes = Path(work) / "run.rou.xml"
        routes.write_text(_routes_xml(row, _subject_start_m(task), behind_m), encoding="utf-8")
        libsumo.start(
            [
                str(sumo_binary("sumo")),
                "-n",
                str(networks_dir() / FCW_DIR / f"{task.track}.net.xml"),
                "-r",
                str(routes),
                "--step-length",
                f"{step_s:g}",
                *QUIET_OPTIONS,
                "--seed",
                "0",
                "--collision.action",
                "none",
            ]
        )
        try:
            libsumo.simulationStep()
            system = FleetFcw(libsumo, measure=equipment.measure)
            category = category_of(libsumo.vehicle.getVehicleClass("sv"))
            for actor in row.actors:
                libsumo.vehicle.setLaneChangeMode(actor.vehicle_id, 0)
                libsumo.vehicle.setSpeedMode(actor.vehicle_id, 6)
                libsumo.vehicle.setSpeed(actor.vehicle_id, actor.speed_mps)
            libsumo.vehicle.setDecel("tv", row.lead_brake_mps2)
            while not script.done:
                now_s = libsumo.simulation.getTime()
                if now_s > MAX_SIMULATED_S:
                    raise RuntimeError(f"{task.key}: run {repetition + 1} did not end within {MAX_SIMULATED_S:g} s")
                truth = _true_state(libsumo, task.track, lane_of)
                said = system(["sv"], [category.value if category else ""], [True])
                level, target_id = said.level[0], said.target_id[0]
                record.add(time_s=now_s, level=level, target=target_id or "", phase_index=script.phase, **truth)
                for vehicle_id, speed_mps in script.step(now_s, truth, level, target_id).items():
                    libsumo.vehicle.setSpeed(vehicle_id, speed_mps)
                libsumo.simulationStep()
        finally:
            libsumo.close()
    return record.trace(repetition, phase)


def _true_state(sumo: Any, track: str, lane_of: dict[str, str]) -> dict[str, float]:
    """The true clearance to ``tv`` along the subject's lane, speeds, the adjacent vehicle's place."""
    vehicle = sumo.vehicle
    subject_m = vehicle.getLanePosition("sv")
    target_rear_m = vehicle.getLanePosition("tv") - vehicle.getLength("tv")
    adjacent = math.nan
    if "adj" in lane_of:
        adjacent = lane_metres(
            track, lane_of["sv"], subject_m, vehicle.getLanePosition("adj") - vehicle.getLength("adj")
        )
    subject_mps, target_mps = vehicle.getSpeed("sv"), vehicle.getSpeed("tv")
    return {
        "clearance_m": lane_metres(track, lane_of["sv"], subject_m, target_rear_m),
        "closing_mps": subject_mps - target_mps,
        "subject_mps": subject_mps,
        "target_mps": target_mps,
        "target_accel_mps2": vehicle.getAcceleration("tv"),
        "adjacent_ahead_m": adjacent,
        "lateral_m": vehicle.getLateralLanePosition("sv") - vehicle.getLateralLanePosition("tv"),
    }
