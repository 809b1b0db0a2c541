"""A motorway exit for lane-uncertain paths: a three-lane road whose right lane alone leads onto an exit
ramp with a sharp curve soon after the diverge, the two other lanes going on as the road; and a lane split
before such an exit: a one-lane road whose lane splits in two, the right one going straight on onto the exit
ramp alone, the left one going on as the road."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from builders import node_xml

from csws.geometry import arc, sample_pieces, straight
from csws.road.roadmap import RoadMap
from csws.sumo.netbuild import netconvert, shape_text

#: The diverge node D; the main road runs east along y = 0 from x = 0 to 900 m.
DIVERGE_XY = (400.0, 0.0)
#: The ramp leaves the road this many degrees to the right, runs straight this far, then curves.
RAMP_ANGLE_DEG = 25.0
RAMP_STRAIGHT_M = 40.0
#: Radius of the ramp's curve, m: a table radius (Tables 1 and 2: 40 m).
RAMP_RADIUS_M = 40.0


def ramp_shape(straight_m: float = RAMP_STRAIGHT_M) -> np.ndarray:
    """The ramp's authored shape from D: ``straight_m`` straight, a 90 degree right curve of :data:`RAMP_RADIUS_M`,
    straight."""
    pieces = (straight(straight_m), arc(RAMP_RADIUS_M, 90.0, "right"), straight(100.0))
    xy, _ = sample_pieces(pieces, 1.0, DIVERGE_XY, -math.radians(RAMP_ANGLE_DEG))
    return xy


def ramp_curve_start_xy(straight_m: float = RAMP_STRAIGHT_M) -> np.ndarray:
    """Where the ramp's curve starts as authored: ``straight_m`` along the ramp from D."""
    heading_rad = -math.radians(RAMP_ANGLE_DEG)
    return np.array(DIVERGE_XY) + straight_m * np.array([math.cos(heading_rad), math.sin(heading_rad)])


def _edge(
    edge_id: str, from_id: str, to_id: str, xy: np.ndarray, lanes: int, priority: int, name: str, spread: str = "right"
) -> str:
    """A motorway edge of ``lanes`` lanes at 30 m/s, spread to the right of ``xy`` or centred on it."""
    return (
        f'<edge id="{edge_id}" from="{from_id}" to="{to_id}" numLanes="{lanes}" speed="30" priority="{priority}" '
        f'name="{name}" spreadType="{spread}" shape="{shape_text(xy)}"/>'
    )


def write_exit_ramp(
    folder: Path, ramp_lanes: int = 1, straight_m: float = RAMP_STRAIGHT_M, approach_m: float | None = None
) -> Path:
    """Write and netconvert the road W -> D -> E (three lanes, then two) and the ramp D -> R of ``ramp_lanes`` lanes
    (1 or 2) whose curve starts ``straight_m`` from D, with the connections of an exit: the right ``ramp_lanes``
    lanes of WD onto the ramp alone, the others onto DE. With ``approach_m`` the road before the diverge is two
    edges, WA and a last stretch WD of that length, each lane of WA going on as the same lane of WD."""
    ramp = ramp_shape(straight_m)
    nodes = [node_xml("W", (0.0, 0.0)), node_xml("D", DIVERGE_XY), node_xml("E", (900.0, 0.0)), node_xml("R", ramp[-1])]
    edges = [
        _edge("DE", "D", "E", np.array([DIVERGE_XY, (900.0, 0.0)]), 2, 3, "Motorway"),
        _edge("DR", "D", "R", ramp, ramp_lanes, 1, "Exit"),
    ]
    onto = [("DR", lane) for lane in range(ramp_lanes)] + [("DE", lane) for lane in range(3 - ramp_lanes)]
    links = [("WD", edge, from_lane, to_lane) for from_lane, (edge, to_lane) in enumerate(onto)]
    if approach_m is None:
        edges.append(_edge("WD", "W", "D", np.array([(0.0, 0.0), DIVERGE_XY]), 3, 3, "Motorway"))
    else:
        a_xy = (DIVERGE_XY[0] - approach_m, 0.0)
        nodes.append(node_xml("A", a_xy))
        edges.append(_edge("WA", "W", "A", np.array([(0.0, 0.0), a_xy]), 3, 3, "Motorway"))
        edges.append(_edge("WD", "A", "D", np.array([a_xy, DIVERGE_XY]), 3, 3, "Motorway"))
        links += [("WA", "WD", lane, lane) for lane in range(3)]
    return _netconvert_linked(folder, "exit", nodes, edges, links)


#: The lane split's lanes are this wide, m (SUMO's default): the split road's left lane runs this far left of the
#: line the one-lane road and the exit lane run along.
LANE_WIDTH_M = 3.2


def write_lane_split(folder: Path, split_m: float) -> Path:
    """Write and netconvert a lane split ``split_m`` before the diverge D: the one-lane road W -> S runs east along
    y = 0 and splits at S into the two lanes of S -> D; the right one goes straight on along y = 0 and leads onto the
    ramp D -> R alone (the lane a vehicle on the road drives straight into), the left one, a lane width to the left,
    goes on as the road D -> E. Every edge is centred on its shape."""
    split_xy = (DIVERGE_XY[0] - split_m, 0.0)
    left_y = LANE_WIDTH_M
    ramp = ramp_shape()
    nodes = [
        node_xml("W", (0.0, 0.0)),
        node_xml("S", split_xy),
        node_xml("D", DIVERGE_XY),
        node_xml("E", (900.0, left_y)),
        node_xml("R", ramp[-1]),
    ]
    edges = [
        _edge("WS", "W", "S", np.array([(0.0, 0.0), split_xy]), 1, 3, "Motorway", "center"),
        _edge("SD", "S", "D", np.array([split_xy, DIVERGE_XY]) + (0.0, left_y / 2), 2, 3, "Motorway", "center"),
        _edge("DE", "D", "E", np.array([(DIVERGE_XY[0], left_y), (900.0, left_y)]), 1, 3, "Motorway", "center"),
        _edge("DR", "D", "R", ramp, 1, 1, "Exit", "center"),
    ]
    links = [("WS", "SD", 0, 0), ("WS", "SD", 0, 1), ("SD", "DR", 0, 0), ("SD", "DE", 1, 0)]
    return _netconvert_linked(folder, "split", nodes, edges, links)


def _netconvert_linked(
    folder: Path, name: str, nodes: list[str], edges: list[str], links: list[tuple[str, str, int, int]]
) -> Path:
    """Netconvert ``nodes`` and ``edges`` into ``folder/name.net.xml`` with exactly the lane-to-lane ``links``
    (from edge, to edge, from lane, to lane) as its connections."""
    connections = "".join(
        f'<connection from="{from_edge}" to="{edge}" fromLane="{from_lane}" toLane="{to_lane}"/>'
        for from_edge, edge, from_lane, to_lane in links
    )
    connection_file = folder / f"{name}.con.xml"
    connection_file.write_text(f"<connections>{connections}</connections>", encoding="utf-8")
    return netconvert(
        "<nodes>" + "".join(nodes) + "</nodes>",
        "<edges>" + "".join(edges) + "</edges>",
        folder / f"{name}.net.xml",
        options=["--connection-files", str(connection_file)],
    )


def path_starts_s(road_map: RoadMap, lanes: list[str]) -> tuple[tuple[str, ...], np.ndarray]:
    """The lanes a drive takes (internal ones filled in) and where each starts along it, m (lane shapes)."""
    path = road_map.expand_path(lanes)
    lengths = [float(np.hypot(*np.diff(np.asarray(road_map.lane_shape(lane)), axis=0).T).sum()) for lane in path]
    return path, np.concatenate(([0.0], np.cumsum(lengths)))


def ramp_curve_start_s(road_map: RoadMap, path: tuple[str, ...], starts_s: np.ndarray, straight_m: float) -> float:
    """Where the ramp's authored curve starts along a drive onto the ramp, m: its start projected onto the ramp lane."""
    shape = np.asarray(road_map.lane_shape("DR_0"))
    vertex_s = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(shape, axis=0).T))))
    nearest = int(np.argmin(np.hypot(*(shape - ramp_curve_start_xy(straight_m)).T)))
    return float(starts_s[path.index("DR_0")] + vertex_s[nearest])
