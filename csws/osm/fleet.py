"""A fleet scenario on a real network: trucks, buses and coaches on its twistiest roads.

The routes seek curves: every edge of the chosen road types is scored by the turning
angle (3.6) of the curves in the curve index, and each route is the shortest path a
truck may drive between two high-scoring edges a few kilometres apart, the one with
the most turning among a handful of candidates. The result is standard SUMO XML (a
route file with ``vType`` of vClass truck, bus and coach, and a ``.sumocfg``), so any
co-simulation can run it. Each ``vType`` carries a ``csws.category`` parameter with its
GB/T 15089 category (N for trucks, M3 for buses and coaches).

Everything is deterministic: the same network gives the same scenario.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from xml.sax.saxutils import quoteattr

import sumolib

from csws.road.roadmap import RoadMap, read_sumo_net

__all__ = ["FleetRoute", "VEHICLE_TYPES", "twisty_routes", "write_fleet_scenario"]

#: Vehicle types of the fleet: id -> (vClass, length m, max speed m/s, category, share of the fleet).
VEHICLE_TYPES = {
    "truck": ("truck", 12.0, 25.0, "N", 2),
    "bus": ("bus", 12.0, 22.2, "M3", 1),
    "coach": ("coach", 13.5, 27.8, "M3", 1),
}

#: A route runs between edges this far apart (straight line), m.
ROUTE_SPAN_M = (3000.0, 12000.0)
#: Destinations tried per route.
CANDIDATES_PER_ROUTE = 12
#: Seconds between two departures.
DEPARTURE_GAP_S = 10.0


@dataclass(frozen=True)
class FleetRoute:
    """One route of the fleet.

    Attributes
    ----------
    route_id
        Its id in the route file.
    edges
        Edge ids in driving order.
    length_m
        Its length, m.
    turning_deg
        Sum of the curve angles (3.6) on its edges, degrees.
    """

    route_id: str
    edges: tuple[str, ...]
    length_m: float
    turning_deg: float


def _edge_turning_deg(road_map: RoadMap, road_types: Sequence[str]) -> dict[str, float]:
    """Turning of the curves on the rightmost lane of every edge of ``road_types``, degrees."""
    turning: dict[str, float] = {}
    for lane_curve in road_map.curves():
        lane = road_map.lane(lane_curve.lane_id)
        if lane.index == 0 and lane.road_type in road_types:
            turning[lane.edge_id] = turning.get(lane.edge_id, 0.0) + lane_curve.curve.angle_deg
    return turning


def _allows_fleet(edge: sumolib.net.edge.Edge) -> bool:
    """Whether every vehicle class of the fleet may drive the edge."""
    return all(edge.allows(vclass) for vclass, *_ in VEHICLE_TYPES.values())


def _centre(edge: sumolib.net.edge.Edge) -> tuple[float, float]:
    xs, ys = zip(*edge.getShape(), strict=False)
    return sum(xs) / len(xs), sum(ys) / len(ys)


def twisty_routes(net: sumolib.net.Net, road_map: RoadMap, count: int, road_types: Sequence[str]) -> list[FleetRoute]:
    """Up to ``count`` routes through the most turning of ``road_types``, most turning first.

    Each route starts on the highest-scoring edge not yet used and ends on the
    candidate edge (at :data:`ROUTE_SPAN_M`) whose shortest truck path turns most.
    """
    turning = _edge_turning_deg(road_map, road_types)
    seeds = [
        edge_id for edge_id in sorted(turning, key=lambda e: (-turning[e], e)) if _allows_fleet(net.getEdge(edge_id))
    ]
    found: list[tuple[tuple[str, ...], float, float]] = []
    used: set[str] = set()
    for start_id in seeds:
        if len(found) == count:
            break
        if start_id in used:
            continue
        best = _best_route(net, net.getEdge(start_id), seeds, used, turning)
        if best is not None:
            used.update(best[0])
            found.append(best)
    found.sort(key=lambda route: -route[2])
    return [FleetRoute(f"route_{number}", *route) for number, route in enumerate(found)]


def _best_route(
    net: sumolib.net.Net,
    start: sumolib.net.edge.Edge,
    seeds: Sequence[str],
    used: set[str],
    turning: dict[str, float],
) -> tuple[tuple[str, ...], float, float] | None:
    """The most turning shortest path from ``start`` to one of the candidate seeds, or None."""
    x0, y0 = _centre(start)
    candidates = [
        edge_id
        for edge_id in seeds
        if edge_id not in used
        and ROUTE_SPAN_M[0] <= math.dist((x0, y0), _centre(net.getEdge(edge_id))) <= ROUTE_SPAN_M[1]
    ][:CANDIDATES_PER_ROUTE]
    best = None
    for end_id in candidates:
        path, _cost = net.getShortestPath(start, net.getEdge(end_id), vClass="truck")
        if not path or not all(_allows_fleet(edge) for edge in path):
            continue
        edges = tuple(edge.getID() for edge in path)
        turning_deg = sum(turning.get(edge_id, 0.0) for edge_id in edges)
        if best is None or turning_deg > best[2]:
            best = (edges, sum(edge.getLength() for edge in path), turning_deg)
    return best


def _route_file(routes: Sequence[FleetRoute], vehicles: int) -> str:
    """The route file: vehicle types, routes and ``vehicles`` departures spread over routes and types."""
    lines = ['<?xml version="1.0" encoding="UTF-8"?>', "<!-- Built from OpenStreetMap data (ODbL 1.0). -->", "<routes>"]
    for type_id, (vclass, length_m, speed_mps, category, _share) in VEHICLE_TYPES.items():
        lines += [
            f'    <vType id="{type_id}" vClass="{vclass}" length="{length_m}" maxSpeed="{speed_mps}">',
            f'        <param key="csws.category" value="{category}"/>',
            "    </vType>",
        ]
    for route in routes:
        lines.append(f'    <route id="{route.route_id}" edges={quoteattr(" ".join(route.edges))}/>')
    type_cycle = [type_id for type_id, spec in VEHICLE_TYPES.items() for _ in range(spec[4])]
    for number in range(vehicles):
        route = routes[number % len(routes)]
        type_id = type_cycle[number % len(type_cycle)]
        lines.append(
            f'    <vehicle id="{type_id}_{number}" type="{type_id}" route="{route.route_id}" '
            f'depart="{number * DEPARTURE_GAP_S:.1f}" departLane="best" departSpeed="max"/>'
        )
    lines.append("</routes>")
    return "\n".join(lines) + "\n"


def _config_file(net_name: str, route_name: str, end_s: float) -> str:
    """A ``.sumocfg`` running the network and routes (paths relative to the config)."""
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<configuration>
    <input>
        <net-file value="{net_name}"/>
        <route-files value="{route_name}"/>
    </input>
    <time>
        <begin value="0"/>
        <end value="{end_s:.0f}"/>
        <step-length value="0.1"/>
    </time>
    <report>
        <no-step-log value="true"/>
    </report>
</configuration>
"""


def write_fleet_scenario(
    net_path: str | Path,
    prefix: str | Path,
    route_count: int = 8,
    vehicles: int = 48,
    road_types: Sequence[str] = ("highway.primary", "highway.secondary"),
) -> tuple[Path, Path, list[FleetRoute]]:
    """Write ``PREFIX.rou.xml`` and ``PREFIX.sumocfg`` for a fleet on the network's twistiest roads.

    Returns
    -------
    tuple
        The route file, the config file and the routes.

    Raises
    ------
    ValueError
        If the network has no curve on ``road_types`` that a truck, bus and coach may
        all drive between two edges at :data:`ROUTE_SPAN_M`.
    """
    net_path, prefix = Path(net_path), Path(prefix)
    net = read_sumo_net(net_path)
    road_map = RoadMap.from_net(net)
    routes = twisty_routes(net, road_map, route_count, road_types)
    if not routes:
        raise ValueError(f"{net_path} has no route for trucks and buses through curves of {', '.join(road_types)}")
    route_path = prefix.with_name(prefix.name + ".rou.xml")
    config_path = prefix.with_name(prefix.name + ".sumocfg")
    route_path.write_text(_route_file(routes, vehicles), encoding="utf-8")
    last_departure_s = (vehicles - 1) * DEPARTURE_GAP_S
    longest_trip_s = max(route.length_m for route in routes) / 10.0
    net_name = os.path.relpath(net_path.resolve(), config_path.parent.resolve())
    config_path.write_text(_config_file(net_name, route_path.name, last_departure_s + longest_trip_s), "utf-8")
    return route_path, config_path, routes
