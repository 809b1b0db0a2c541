"""The telematics benchmark's fleet: trucks, buses and cars driven by SUMO, each vehicle's trajectory
recorded every step.

:func:`drive_fleet` keeps a fleet of a given size on a network for a given time in libsumo at 0.1 s
steps: each vehicle of the fleet's mix (:data:`csws.networks.fleet.FLEET_TYPES`) drives a trip
between two random edges its class may use, at least :data:`MIN_TRIP_M` apart by road, and a vehicle
that arrives is replaced by a new one on a new trip, so the fleet keeps its size. Every step records
each vehicle's front position (network x/y), speed, heading (SUMO's angle: degrees clockwise from
north), lane and lane position: the truth the sampled feeds are drawn from and judged against.
:func:`lonlat` turns network x/y into WGS84 lon/lat with the network's own projection.
"""

from __future__ import annotations

import gzip
import multiprocessing
import os
import re
import tempfile
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from csws.cosim.categories import VCLASS_CATEGORY
from csws.cosim.sumo import sumo_arguments
from csws.networks.fleet import FLEET_TYPES, FleetType, draw_types, vtype_xml
from csws.sumo.binaries import sumo_binary, sumo_home

__all__ = ["STEP_S", "MIN_TRIP_M", "Trajectories", "drive_fleet", "lonlat"]

#: SUMO's step, s: the exact feed's period.
STEP_S = 0.1
#: A trip is at least this long by road, m (shorter draws are redrawn).
MIN_TRIP_M = 1500.0
#: How many destinations are drawn for a trip before its vehicle is left out.
TRIP_DRAWS = 20
#: Edges shorter than this are not a trip's start, m (a vehicle must fit on its first edge).
MIN_START_EDGE_M = 20.0


@dataclass
class Trajectories:
    """Every vehicle's state at every step it was on the network, one row per vehicle and step.

    Attributes
    ----------
    step
        The step of each row (time = step * STEP_S, s).
    vehicle
        Index into ``vehicle_ids`` of each row.
    x_m, y_m
        Front position, network metres.
    speed_mps
        Speed, m/s.
    heading_deg
        Heading, degrees clockwise from north.
    lane
        Index into ``lanes`` of each row's lane.
    lane_pos_m
        Position on that lane, m.
    vehicle_ids, categories
        Each vehicle's id and its category (``M1``, ``N``, ...).
    lanes
        The lane ids the rows index.
    """

    step: np.ndarray
    vehicle: np.ndarray
    x_m: np.ndarray
    y_m: np.ndarray
    speed_mps: np.ndarray
    heading_deg: np.ndarray
    lane: np.ndarray
    lane_pos_m: np.ndarray
    vehicle_ids: list[str]
    categories: list[str]
    lanes: list[str]


def _category(fleet_type: FleetType) -> str:
    """A fleet type's category: its own, else its vehicle class's."""
    return fleet_type.category or VCLASS_CATEGORY[fleet_type.vclass].value


def _usable_edges(sumo: Any, vclasses: set[str]) -> list[str]:
    """The network's edges with a lane that every class of the fleet may use, long enough to start on."""
    usable = []
    for edge_id in sumo.edge.getIDList():
        if edge_id.startswith(":") or sumo.lane.getLength(f"{edge_id}_0") < MIN_START_EDGE_M:
            continue
        for index in range(sumo.edge.getLaneNumber(edge_id)):
            lane_id = f"{edge_id}_{index}"
            allowed, disallowed = set(sumo.lane.getAllowed(lane_id)), set(sumo.lane.getDisallowed(lane_id))
            if (not allowed or vclasses <= allowed) and not vclasses & disallowed:
                usable.append(edge_id)
                break
    return usable


def _add_vehicle(sumo: Any, vehicle_id: str, fleet_type: FleetType, edges: list[str], rng: np.random.Generator) -> bool:
    """Add a vehicle on a trip between two random edges at least MIN_TRIP_M apart; False if none was found."""
    for _ in range(TRIP_DRAWS):
        start, end = (edges[int(i)] for i in rng.integers(len(edges), size=2))
        route = sumo.simulation.findRoute(start, end, fleet_type.type_id)
        if route.edges and route.length >= MIN_TRIP_M:
            sumo.route.add(vehicle_id, list(route.edges))
            sumo.vehicle.add(
                vehicle_id, vehicle_id, fleet_type.type_id, depart="now", departPos="random_free", departSpeed="avg"
            )
            return True
    return False


class _Recorder:
    """The rows recorded so far, as growing lists."""

    def __init__(self) -> None:
        self.columns: dict[str, list] = {name: [] for name in ("step", "vehicle", "x", "y", "speed", "angle", "lane")}
        self.columns["pos"] = []
        self.lane_index: dict[str, int] = {}
        self.vehicle_index: dict[str, int] = {}

    def record(self, sumo: Any, step: int) -> None:
        """Every vehicle on the network now (subscribed when it departed)."""
        columns = self.columns
        for vehicle_id, values in sumo.vehicle.getAllSubscriptionResults().items():
            lane_id = values[sumo.constants.VAR_LANE_ID]
            if not lane_id:
                continue
            x, y = values[sumo.constants.VAR_POSITION]
            columns["step"].append(step)
            columns["vehicle"].append(self.vehicle_index[vehicle_id])
            columns["x"].append(x)
            columns["y"].append(y)
            columns["speed"].append(values[sumo.constants.VAR_SPEED])
            columns["angle"].append(values[sumo.constants.VAR_ANGLE])
            columns["lane"].append(self.lane_index.setdefault(lane_id, len(self.lane_index)))
            columns["pos"].append(values[sumo.constants.VAR_LANEPOSITION])


def _drive(net: Path, vehicles: int, duration_s: float, seed: int) -> Trajectories:
    """The fleet's run in this process (libsumo holds one simulation per process)."""
    os.environ.setdefault("SUMO_HOME", str(sumo_home()))
    import libsumo

    rng = np.random.default_rng(seed)
    with tempfile.TemporaryDirectory(prefix="csws-telematics-") as work:
        types_file = Path(work) / "types.rou.xml"
        types_file.write_text("<routes>" + "".join(vtype_xml(t) for t in FLEET_TYPES) + "</routes>\n", "utf-8")
        arguments = sumo_arguments(None, net, [types_file], STEP_S, seed, None)
        libsumo.start([str(sumo_binary("sumo")), *arguments, "--time-to-teleport", "-1"])
        try:
            return _run_fleet(libsumo, vehicles, round(duration_s / STEP_S), rng)
        finally:
            libsumo.close()


def _run_fleet(sumo: Any, vehicles: int, steps: int, rng: np.random.Generator) -> Trajectories:
    """Keep ``vehicles`` on the road for ``steps`` steps, recording every step."""
    edges = _usable_edges(sumo, {t.vclass for t in FLEET_TYPES})
    recorder = _Recorder()
    types: dict[str, FleetType] = {}
    variables = [sumo.constants.VAR_POSITION, sumo.constants.VAR_SPEED, sumo.constants.VAR_ANGLE]
    variables += [sumo.constants.VAR_LANE_ID, sumo.constants.VAR_LANEPOSITION]
    for fleet_type in draw_types(vehicles, rng):
        vehicle_id = f"{fleet_type.type_id}{len(types)}"
        if _add_vehicle(sumo, vehicle_id, fleet_type, edges, rng):
            types[vehicle_id] = fleet_type
    for step in range(1, steps + 1):
        sumo.simulationStep()
        for vehicle_id in sumo.simulation.getDepartedIDList():
            recorder.vehicle_index[vehicle_id] = len(recorder.vehicle_index)
            sumo.vehicle.subscribe(vehicle_id, variables)
        for arrived in sumo.simulation.getArrivedIDList():
            fleet_type = types[arrived]
            vehicle_id = f"{fleet_type.type_id}{len(types)}"
            if _add_vehicle(sumo, vehicle_id, fleet_type, edges, rng):
                types[vehicle_id] = fleet_type
        recorder.record(sumo, step)
    columns = {name: np.asarray(values) for name, values in recorder.columns.items()}
    ids = list(recorder.vehicle_index)
    return Trajectories(
        step=columns["step"].astype(np.int64),
        vehicle=columns["vehicle"].astype(np.int64),
        x_m=columns["x"].astype(float),
        y_m=columns["y"].astype(float),
        speed_mps=columns["speed"].astype(float),
        heading_deg=columns["angle"].astype(float),
        lane=columns["lane"].astype(np.int64),
        lane_pos_m=columns["pos"].astype(float),
        vehicle_ids=ids,
        categories=[_category(types[v]) for v in ids],
        lanes=list(recorder.lane_index),
    )


def drive_fleet(net: Path, vehicles: int, duration_s: float, seed: int = 0) -> Trajectories:
    """Drive a fleet of ``vehicles`` on ``net`` for ``duration_s`` in a fresh process and return every
    vehicle's recorded trajectory."""
    with ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn")) as pool:
        return pool.submit(_drive, net, vehicles, duration_s, seed).result()


def lonlat(net: Path, x_m: np.ndarray, y_m: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """WGS84 lon/lat of network x/y, degrees, with the network's projection; None if it has none."""
    import pyproj

    opener = gzip.open if net.suffix == ".gz" else open
    with opener(net, "rt", encoding="utf-8") as text:
        head = text.read(20_000)
    location = re.search(r'<location netOffset="([^",]+),([^"]+)".*?projParameter="([^"]*)"', head, re.S)
    if location is None or location.group(3) in ("", "!"):
        return None
    offset_x, offset_y = float(location.group(1)), float(location.group(2))
    projection = pyproj.Proj(location.group(3))
    lon, lat = projection(x_m - offset_x, y_m - offset_y, inverse=True)
    return np.asarray(lon), np.asarray(lat)
