"""Driving one row of the test procedure in SUMO (libsumo): the runs of 7.5.1 and what the system said.

A :class:`Task` is one row on one track at one step length. Its repetitions run in one
simulation, one test vehicle each, departing ``REPETITION_GAP_S`` apart so that they never
meet. Each vehicle

* drives at the constant test speed (``speedFactor`` 1, ``speedDev`` 0, ``sigma`` 0, its
  maximum speed set to the test speed) from well before the warning distance, so that it is
  stable for more than 3 s (7.5.1); the judge checks this from the record;
* starts at its own phase of the simulation step: its depart position is shifted by a
  fraction of the distance driven in one step, so the repetitions sample the road at
  different points;
* in Table 7, brakes at 4.9 m/s^2 (its vType's ``decel``) to the curve-2 speed at the first
  step where its true distance to curve 1 is at most curve 1's level-2 S_w (7.5.3.1.1).

Every step every test vehicle is evaluated by :class:`csws.engine.Engine` (one
``evaluate_many`` per step) from its SUMO lane and lane position with the test
equipment's accuracy of 7.2.2 as noise: position +-0.2 m (uniform) and speed 0.05 km/h RMS
(normal). The record keeps the true route position (from the network's truth file), the
true speed and the warning level.
"""

from __future__ import annotations

import json
import math
import tempfile
import zlib
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any
from xml.sax.saxutils import quoteattr

import numpy as np
import shapely

from csws.engine import Engine, EngineSettings, VehicleInput
from csws.geometry import Piece, sample_pieces
from csws.networks import networks_dir
from csws.networks.real_roads import REAL_ROADS_DIR
from csws.road.roadmap import RoadMap
from csws.standard import formula_1_m, kmh_to_mps, mps_to_kmh
from csws.sumo.binaries import QUIET_OPTIONS, sumo_binary
from csws.warning.rules import WarningSettings

from .rows import Row

__all__ = [
    "POSITION_ACCURACY_M",
    "SPEED_ACCURACY_KMH",
    "STABLE_S",
    "REPETITION_GAP_S",
    "PAST_LAST_CURVE_M",
    "Task",
    "Trace",
    "Truth",
    "truth",
    "track_file",
    "authored_pieces",
    "drive",
]

#: Positioning accuracy of the test equipment, m (7.2.2: +-20 cm); uniform noise of this bound.
POSITION_ACCURACY_M = 0.2
#: Speed accuracy of the test equipment, km/h RMS (7.2.2); normal noise of this deviation.
SPEED_ACCURACY_KMH = 0.05
#: The vehicle holds the test speed at least this long before the warning distance (7.5.1), s.
STABLE_S = 3.0
#: Extra constant-speed time before the warning distance beyond STABLE_S, s.
LEAD_MARGIN_S = 1.5
#: Time between the departures of two repetitions, s: they never come near each other.
REPETITION_GAP_S = 5.0
#: A run ends this far past the end of the last curve, m (its record covers the straight run-out).
PAST_LAST_CURVE_M = 40.0
#: A run that has not ended after this much simulated time is an error, s.
MAX_SIMULATED_S = 900.0


@dataclass(frozen=True)
class Task:
    """One row on one track at one step length, with its repetitions.

    Attributes
    ----------
    row
        The row of the procedure.
    track
        The bundled network it runs on.
    step_length_s
        SUMO's step length, s; also the engine's update period (latency compensation).
    repetitions
        How many runs.
    seed
        Seed of the phases and the measurement noise.
    """

    row: Row
    track: str
    step_length_s: float
    repetitions: int
    seed: int

    @property
    def key(self) -> str:
        """A readable identifier of the task."""
        return f"{self.row.row_id}@{self.track}@{self.step_length_s:g}s"


@dataclass(frozen=True)
class Trace:
    """The record of one run: one entry per simulation step while the test vehicle drove.

    Attributes
    ----------
    repetition
        Which run of the task (0-based).
    phase
        Its depart offset as a fraction of one step's travel.
    time_s
        Simulation time, s.
    route_s_m
        True position of the vehicle's front along the route (truth file), m.
    speed_kmh
        True speed, km/h.
    level
        Warning level the system gave.
    """

    repetition: int
    phase: float
    time_s: np.ndarray
    route_s_m: np.ndarray
    speed_kmh: np.ndarray
    level: np.ndarray


@dataclass(frozen=True)
class Truth:
    """What the judge needs from a track's truth file.

    Attributes
    ----------
    name
        The track.
    curve_start_s_m, curve_end_s_m
        Start and end of each curve along the route, in driving order, m.
    lane_start_s_m
        Route position of the start of each lane of the route, m.
    route_edges
        The route.
    line
        The authored road, for tracks whose lanes do not follow it from edge to edge (the
        real-road tracks, with netconvert's junctions inside curves): positions are
        projected onto it. None for the standard's tracks.
    """

    name: str
    curve_start_s_m: tuple[float, ...]
    curve_end_s_m: tuple[float, ...]
    lane_start_s_m: dict[str, float]
    route_edges: tuple[str, ...]
    line: shapely.LineString | None = None


def track_file(track: str, suffix: str) -> Path:
    """A bundled track's ``.net.xml`` or ``.truth.json``: the standard's, or a real-road track's."""
    real_road = networks_dir() / REAL_ROADS_DIR / f"{track}{suffix}"
    return real_road if real_road.is_file() else networks_dir() / f"{track}{suffix}"


def authored_pieces(content: dict) -> list[Piece]:
    """The authored road of a real-road track's truth file."""
    return [
        Piece(p["length_m"], p["curvature"], None if p["end_curvature"] == p["curvature"] else p["end_curvature"])
        for p in content["pieces"]
    ]


@cache
def truth(track: str) -> Truth:
    """The truth of a bundled track, read from ``NAME.truth.json`` (written by the track generator)."""
    content = json.loads(track_file(track, ".truth.json").read_text("utf-8"))
    curves = content["curves"]
    if "pieces" not in content:
        lanes = {lane["lane"]: float(lane["start_s"]) for lane in content["lanes"]}
        line = None
    else:
        lanes = {f"{edge}_0": float(start_s) for edge, start_s in content["edge_start_s"].items()}
        line = shapely.LineString(sample_pieces(authored_pieces(content), 0.25)[0])
    return Truth(
        name=track,
        curve_start_s_m=tuple(float(c["start_s"]) for c in curves),
        curve_end_s_m=tuple(float(c["end_s"]) for c in curves),
        lane_start_s_m=lanes,
        route_edges=tuple(content["route"]["edges"]),
        line=line,
    )


@cache
def _road_map(track: str) -> RoadMap:
    """The road map of a bundled track, loaded once per process."""
    return RoadMap.load(track_file(track, ".net.xml"))


def _route_s(track_truth: Truth, road_map: RoadMap, lane_id: str, lane_pos_m: float, xy: tuple[float, float]) -> float:
    """True route position of a vehicle: its place ``xy`` projected onto the authored road
    where the truth has it, else its lane position on the route.

    A junction's internal lane has no geometric length on the standard's tracks
    (netconvert's 0.1 m minimum): it is placed at the start of the lane it leads to.
    """
    if track_truth.line is not None:
        return float(track_truth.line.project(shapely.Point(xy)))
    start_s = track_truth.lane_start_s_m.get(lane_id)
    if start_s is not None:
        return start_s + lane_pos_m
    following = road_map.successors(lane_id)
    return track_truth.lane_start_s_m[following[0]] if following else math.nan


def _lead_m(row: Row) -> float:
    """How far before curve 1 the runs start, m: the largest S_w plus the stable time and a margin.

    Rows without a table's S_w reach as far as formula (1) can at their speed (V_w = 0).
    """
    speed_mps = kmh_to_mps(row.speed_kmh)
    reach_m = max([c.table_distance_m for c in row.checks if c.table_distance_m] or [formula_1_m(speed_mps, 0.0)])
    return reach_m + (STABLE_S + LEAD_MARGIN_S) * speed_mps


def _routes_xml(task: Task, depart_pos_m: list[float], depart_time_s: list[float]) -> str:
    """The route file of a task: the test vehicle type and one vehicle per repetition."""
    row = task.row
    speed_mps = kmh_to_mps(row.speed_kmh)
    decel = row.decel_mps2 or 4.5
    vtype = (
        f'<vType id="test" vClass="passenger" length="5" accel="2.6" decel="{decel:g}" emergencyDecel="9" '
        f'sigma="0" speedFactor="1" speedDev="0" maxSpeed="{speed_mps:.12g}"/>'
    )
    edges = " ".join(truth(task.track).route_edges)
    vehicles = "".join(
        f'<vehicle id="run{i}" type="test" depart="{t:.6f}" departLane="0" departPos="{p:.6f}" '
        f'departSpeed="{speed_mps:.12g}"><route edges={quoteattr(edges)}/></vehicle>'
        for i, (p, t) in enumerate(zip(depart_pos_m, depart_time_s, strict=False))
    )
    return f"<routes>{vtype}{vehicles}</routes>"


def _rng(task: Task) -> np.random.Generator:
    """The task's own random stream (phases and noise), from the seed and the task's key."""
    return np.random.default_rng([task.seed, zlib.crc32(task.key.encode())])


def _departures(task: Task, rng: np.random.Generator) -> tuple[list[float], list[float], list[float]]:
    """Phases, depart positions (m, on the first lane) and depart times (s) of the repetitions.

    Repetition ``i`` starts at phase ``(i + u) / n`` of a step (``u`` uniform), i.e. that
    fraction of one step's travel earlier on the road.
    """
    row, step = task.row, task.step_length_s
    track_truth = truth(task.track)
    first_lane_start_s = min(track_truth.lane_start_s_m.values())
    base_m = track_truth.curve_start_s_m[0] - _lead_m(row) - first_lane_start_s
    if base_m < 0:
        raise ValueError(f"track {task.track} is too short for row {row.row_id}")
    n = task.repetitions
    phases = [(i + float(rng.uniform())) / n for i in range(n)]
    travel_m = kmh_to_mps(row.speed_kmh) * step
    positions = [base_m - phase * travel_m for phase in phases]
    gap_steps = math.ceil(REPETITION_GAP_S / step - 1e-9)
    times = [round(i * gap_steps * step, 9) for i in range(n)]
    return phases, positions, times


@dataclass
class _Record:
    """A run's record while it is being written."""

    repetition: int
    phase: float
    time_s: list[float]
    route_s_m: list[float]
    speed_kmh: list[float]
    level: list[int]
    braking: bool = False

    def trace(self) -> Trace:
        """The finished run as arrays."""
        return Trace(
            self.repetition,
            self.phase,
            np.array(self.time_s),
            np.array(self.route_s_m),
            np.array(self.speed_kmh),
            np.array(self.level, dtype=np.int8),
        )


def drive(task: Task) -> list[Trace]:
    """Run a task's repetitions in SUMO and return their records, in repetition order.

    Raises
    ------
    RuntimeError
        When a run does not finish within ``MAX_SIMULATED_S``.
    """
    import libsumo

    runs = _Runs(task)
    with tempfile.TemporaryDirectory(prefix="csws-conformance-") as work:
        routes = Path(work) / "runs.rou.xml"
        routes.write_text(_routes_xml(task, runs.positions_m, runs.times_s), encoding="utf-8")
        libsumo.start(_sumo_command(task, routes))
        try:
            while len(runs.finished) < task.repetitions:
                libsumo.simulationStep()
                runs.step(libsumo)
        finally:
            libsumo.close()
    return [record.trace() for record in sorted(runs.finished, key=lambda r: r.repetition)]


def _sumo_command(task: Task, routes: Path) -> list[str]:
    """SUMO's command line for a task: its track, its routes and step length, quiet, seed 0."""
    return [
        str(sumo_binary("sumo")),
        "-n",
        str(track_file(task.track, ".net.xml")),
        "-r",
        str(routes),
        "--step-length",
        f"{task.step_length_s:g}",
        *QUIET_OPTIONS,
        "--seed",
        "0",
    ]


class _Runs:
    """A task's runs while SUMO drives them: the engine that judges them and their records.

    Parameters
    ----------
    task
        The task; its random stream gives first the runs' phases, then each step's measurement noise.
    """

    def __init__(self, task: Task) -> None:
        self.task, self.row = task, task.row
        self.rng = _rng(task)
        phases, self.positions_m, self.times_s = _departures(task, self.rng)
        self.track_truth, self.road_map = truth(task.track), _road_map(task.track)
        warning = WarningSettings(update_period_s=task.step_length_s)
        self.engine = Engine(self.road_map, EngineSettings(warning=warning))
        self.end_s = self.track_truth.curve_end_s_m[-1] + PAST_LAST_CURVE_M
        self.records = {f"run{i}": _Record(i, phases[i], [], [], [], []) for i in range(task.repetitions)}
        self.finished: list[_Record] = []

    def step(self, libsumo: Any) -> None:
        """Read the vehicles after a simulation step, ask the engine and record its answers."""
        from traci import constants as tc

        now_s = libsumo.simulation.getTime()
        if now_s > MAX_SIMULATED_S:
            raise RuntimeError(f"{self.task.key}: runs did not finish within {MAX_SIMULATED_S:g} s")
        for vehicle_id in libsumo.simulation.getDepartedIDList():
            libsumo.vehicle.subscribe(vehicle_id, (tc.VAR_LANE_ID, tc.VAR_LANEPOSITION, tc.VAR_SPEED, tc.VAR_POSITION))
        state = libsumo.vehicle.getAllSubscriptionResults()
        if not state:
            return
        ids = list(state)
        lanes = [state[v][tc.VAR_LANE_ID] for v in ids]
        lane_pos = np.array([state[v][tc.VAR_LANEPOSITION] for v in ids])
        speed_kmh = mps_to_kmh(np.array([state[v][tc.VAR_SPEED] for v in ids]))
        route_s = np.array(
            [
                _route_s(self.track_truth, self.road_map, lane, pos, state[v][tc.VAR_POSITION])
                for v, lane, pos in zip(ids, lanes, lane_pos, strict=False)
            ]
        )
        levels = self._levels(now_s, ids, lanes, lane_pos, speed_kmh)
        self._record(libsumo, now_s, ids, levels, route_s, speed_kmh)

    def _levels(
        self, now_s: float, ids: list[str], lanes: list[str], lane_pos: np.ndarray, speed_kmh: np.ndarray
    ) -> list[int]:
        """The engine's warning level of each vehicle, given positions and speeds through the test
        equipment's accuracy (7.2.2)."""
        rng, row, route_edges = self.rng, self.row, self.track_truth.route_edges
        measured_pos = lane_pos + rng.uniform(-POSITION_ACCURACY_M, POSITION_ACCURACY_M, len(ids))
        measured_speed = np.maximum(speed_kmh + rng.normal(0.0, SPEED_ACCURACY_KMH, len(ids)), 0.0)
        answers = self.engine.evaluate_many(
            [
                VehicleInput(
                    v,
                    row.category.value,
                    float(measured_speed[i]),
                    lanes[i],
                    float(measured_pos[i]),
                    route_edges,
                    now_s,
                )
                for i, v in enumerate(ids)
            ]
        )
        return [int(answer.level) for answer in answers]

    def _record(
        self,
        libsumo: Any,
        now_s: float,
        ids: list[str],
        levels: list[int],
        route_s: np.ndarray,
        speed_kmh: np.ndarray,
    ) -> None:
        """Append the step to each run's record, brake the Table 7 runs when due and take the runs
        past the last curve off the road."""
        for i, (vehicle_id, level) in enumerate(zip(ids, levels, strict=False)):
            record = self.records[vehicle_id]
            record.time_s.append(now_s)
            record.route_s_m.append(route_s[i])
            record.speed_kmh.append(speed_kmh[i])
            record.level.append(level)
            _brake_if_due(libsumo, self.row, self.track_truth, vehicle_id, record, route_s[i])
            if route_s[i] > self.end_s:
                libsumo.vehicle.unsubscribe(vehicle_id)
                libsumo.vehicle.remove(vehicle_id)
                self.finished.append(record)


def _brake_if_due(
    libsumo: Any, row: Row, track_truth: Truth, vehicle_id: str, record: _Record, route_s_m: float
) -> None:
    """Table 7: at the first step within curve 1's level-2 S_w, brake to the curve-2 speed and hold it."""
    if row.decel_trigger_m is None or record.braking:
        return
    if track_truth.curve_start_s_m[0] - route_s_m <= row.decel_trigger_m:
        libsumo.vehicle.setSpeed(vehicle_id, kmh_to_mps(row.final_speed_kmh))
        record.braking = True
