"""Networks and shapes that several test modules build: pure functions of their arguments.

* the Table 7 track made geo-referenced (:func:`write_geo_track`);
* the side roads: a two-way main road, a one-way frontage road beside it and a crossing road
  over it (:func:`build_side_roads`);
* the short curve of the road chains' report, cut by a node inside it (:func:`split_curve_map`);
* a SUMO-like dense shape of constructed pieces (:func:`dense_shape`).

Every network is built by netconvert from geometry constructed exactly with csws.geometry.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from csws.geometry import Piece, arc, pose_at, sample_pieces, straight
from csws.networks import networks_dir
from csws.road.roadmap import RoadMap
from csws.sumo.netbuild import netconvert, shape_text

# ------------------------------------------------------------------ the Table 7 track, geo-referenced
#: The bundled track the service tests serve.
TRACK = "t7_left"
TRACK_NET = networks_dir() / f"{TRACK}.net.xml"
UTM32 = "+proj=utm +zone=32 +ellps=WGS84 +datum=WGS84 +units=m +no_defs"

# ------------------------------------------------------------------ the side roads
#: The frontage road runs eastbound this far north of the main road's axis, m.
FRONTAGE_OFFSET_M = 9.0
#: Lane width SUMO gives (the two directions of the main road lie half of it either side of the axis), m.
LANE_WIDTH_M = 3.2
#: The crossing road runs north at this x, m.
CROSSING_X_M = 400.0
#: Where the service tests place the side roads: this far east of the track, m.
SIDE_X_M = 10_000.0

# ------------------------------------------------------------------ the short curve of the road chains' report
#: R 71 m, 25.7 m long, after a 300 m straight.
APPROACH_M = 300.0
CURVE_RADIUS_M = 71.0
CURVE_LENGTH_M = 25.7
PIECES = (
    straight(APPROACH_M),
    arc(CURVE_RADIUS_M, math.degrees(CURVE_LENGTH_M / CURVE_RADIUS_M), "left"),
    straight(200.0),
)


def write_geo_track(folder: Path) -> Path:
    """The track with a projection: network (0, 0) lies at UTM 32N (550000, 5635000), near Bad Hersfeld."""
    text = TRACK_NET.read_text()
    text = text.replace('netOffset="0.000,0.000"', 'netOffset="-550000.00,-5635000.00"')
    text = text.replace('projParameter="!"', f'projParameter="{UTM32}"')
    path = folder / "t7_geo.net.xml"
    path.write_text(text)
    return path


def _side_edge(edge_id: str, from_id: str, to_id: str, xy: np.ndarray, spread: str) -> str:
    """One lane at 25 m/s along ``xy``, spread as given (``right`` for the two-way main road)."""
    return (
        f'<edge id="{edge_id}" from="{from_id}" to="{to_id}" numLanes="1" speed="25.0" '
        f'spreadType="{spread}" shape="{shape_text(xy)}"/>'
    )


def _side_node(node_id: str, x: float, y: float) -> str:
    """A node at (``x``, ``y``), to the millimetre."""
    return f'<node id="{node_id}" x="{x:.3f}" y="{y:.3f}"/>'


def build_side_roads(folder: Path, origin_x_m: float = 0.0) -> Path:
    """Write and netconvert the side roads; ``origin_x_m`` shifts them east.

    * ``main``: two-way road along y = 0 from x = 0 to 800 (``AB`` eastbound, ``BA`` westbound);
    * ``frontage``: one-way eastbound road along y = FRONTAGE_OFFSET_M, not connected to the main road;
    * ``crossing``: one-way northbound road along x = CROSSING_X_M from y = -300 to 300, passing
      over the main road without a junction (a bridge).
    """
    main_xy, _ = sample_pieces((straight(800.0),), 2.0, (origin_x_m, 0.0), 0.0)
    frontage_xy, _ = sample_pieces((straight(800.0),), 2.0, (origin_x_m, FRONTAGE_OFFSET_M), 0.0)
    crossing_xy, _ = sample_pieces((straight(600.0),), 2.0, (origin_x_m + CROSSING_X_M, -300.0), np.pi / 2)
    nodes = [
        _side_node("A", origin_x_m, 0.0),
        _side_node("B", origin_x_m + 800.0, 0.0),
        _side_node("F0", origin_x_m, FRONTAGE_OFFSET_M),
        _side_node("F1", origin_x_m + 800.0, FRONTAGE_OFFSET_M),
        _side_node("C0", origin_x_m + CROSSING_X_M, -300.0),
        _side_node("C1", origin_x_m + CROSSING_X_M, 300.0),
    ]
    edges = [
        _side_edge("AB", "A", "B", main_xy, "right"),
        _side_edge("BA", "B", "A", main_xy[::-1], "right"),
        _side_edge("frontage", "F0", "F1", frontage_xy, "center"),
        _side_edge("crossing", "C0", "C1", crossing_xy, "center"),
    ]
    return netconvert(
        "<nodes>\n" + "\n".join(nodes) + "\n</nodes>\n",
        "<edges>\n" + "\n".join(edges) + "\n</edges>\n",
        folder / "side_roads.net.xml",
    )


def edge_xml(edge_id: str, from_id: str, to_id: str, xy: np.ndarray, priority: int = 1) -> str:
    """One centred lane at 30 m/s along ``xy``, of road priority ``priority``."""
    return (
        f'<edge id="{edge_id}" from="{from_id}" to="{to_id}" numLanes="1" speed="30" priority="{priority}" '
        f'spreadType="center" shape="{shape_text(xy)}"/>'
    )


def node_xml(node_id: str, xy: Sequence[float] | np.ndarray) -> str:
    """A node at ``xy``, to the micrometre."""
    return f'<node id="{node_id}" x="{xy[0]:.6f}" y="{xy[1]:.6f}"/>'


def _split_road(node_s_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The constructed road cut at arc length ``node_s_m``: the shapes before and after, and the cut point."""
    xy, _ = sample_pieces(PIECES, 1.0, (0.0, 0.0), 0.0)
    s = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))))
    x, y, _ = pose_at(PIECES, np.array([node_s_m]))
    cut = np.array([x[0], y[0]])
    return np.vstack([xy[s < node_s_m], cut]), np.vstack([cut, xy[s > node_s_m]]), cut


def split_curve_map(folder: Path, node_after_start_m: float, side_road: bool = False) -> RoadMap:
    """The road with a node ``node_after_start_m`` into its curve (netconvert's own junction there);
    with ``side_road``, a road leaving that node to the outside of the curve."""
    before, after, cut = _split_road(APPROACH_M + node_after_start_m)
    nodes = [node_xml("A", before[0]), node_xml("J", cut), node_xml("B", after[-1])]
    edges = [edge_xml("a", "A", "J", before, priority=3), edge_xml("b", "J", "B", after, priority=3)]
    if side_road:
        _, _, heading = pose_at(PIECES, np.array([APPROACH_M + node_after_start_m]))
        outward = heading[0] - math.pi / 2  # the curve turns left: its outside is to the right
        end = cut + 150.0 * np.array([math.cos(outward), math.sin(outward)])
        nodes.append(node_xml("S", end))
        edges.append(edge_xml("side", "J", "S", np.array([cut, end]), priority=1))
    return RoadMap.load(
        netconvert(
            "<nodes>" + "".join(nodes) + "</nodes>", "<edges>" + "".join(edges) + "</edges>", folder / "split.net.xml"
        )
    )


def dense_shape(
    pieces: Sequence[Piece], spacing_m: float, origin: tuple[float, float], heading_rad: float
) -> np.ndarray:
    """A SUMO-like shape: evenly spaced vertices rounded to the centimetre."""
    xy, _ = sample_pieces(pieces, spacing_m, origin, heading_rad)
    return np.round(xy, 2)
