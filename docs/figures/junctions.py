"""Draw docs/figures/junctions.png: which lanes through a junction continue the road.

Two constructed roads, netconverted and read back with csws, as the rule in
``csws.road.continuations`` classifies them: a crossroads of a major and a minor road, and a left
curve of R 71 m with a side road joining at its outside. Run: ``python docs/figures/junctions.py``.
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import numpy as np
from matplotlib import pyplot

from csws.ahead.lookahead import LookAhead
from csws.geometry import arc, pose_at, sample_pieces, straight
from csws.road.roadmap import RoadMap
from csws.sumo.netbuild import netconvert, shape_text

CURVE = (straight(60.0), arc(71.0, 60.0, "left"), straight(60.0))


def _network(folder: Path, name: str, nodes: dict, edges: list[tuple]) -> RoadMap:
    """netconvert ``nodes`` (id -> xy) and ``edges`` (id, from, to, shape, priority) into a road map."""
    node_xml = "".join(f'<node id="{n}" x="{x:.6f}" y="{y:.6f}"/>' for n, (x, y) in nodes.items())
    edge_xml = "".join(
        f'<edge id="{e}" from="{a}" to="{b}" numLanes="1" speed="20" priority="{p}" spreadType="center" '
        f'shape="{shape_text(shape)}"/>'
        for e, a, b, shape, p in edges
    )
    return RoadMap.load(
        netconvert(f"<nodes>{node_xml}</nodes>", f"<edges>{edge_xml}</edges>", folder / f"{name}.net.xml")
    )


def _crossroads(folder: Path) -> RoadMap:
    arms = {"W": (-60.0, 0.0), "E": (60.0, 0.0), "S": (0.0, -60.0), "N": (0.0, 60.0)}
    edges = []
    for name, xy in arms.items():
        priority = 3 if name in "WE" else 1
        edges += [
            (f"{name}in", name, "C", np.array([xy, (0, 0)]), priority),
            (f"{name}out", "C", name, np.array([(0, 0), xy]), priority),
        ]
    return _network(folder, "crossroads", {"C": (0.0, 0.0), **arms}, edges)


def _curve_with_side_road(folder: Path) -> RoadMap:
    xy, _ = sample_pieces(CURVE, 1.0, (0.0, 0.0), 0.0)
    s = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))))
    node_s = 60.0 + 30.0
    x, y, heading = pose_at(CURVE, np.array([node_s]))
    cut = np.array([x[0], y[0]])
    side_end = cut + 60.0 * np.array([math.cos(heading[0] - math.pi / 2), math.sin(heading[0] - math.pi / 2)])
    nodes = {"A": xy[0], "J": cut, "B": xy[-1], "S": side_end}
    edges = [
        ("a", "A", "J", np.vstack([xy[s < node_s], cut]), 3),
        ("b", "J", "B", np.vstack([cut, xy[s > node_s]]), 3),
        ("side", "J", "S", np.array([cut, side_end]), 1),
    ]
    return _network(folder, "curve", nodes, edges)


def _draw(axes, road_map: RoadMap, title: str, path: list[str] | None = None) -> None:
    """Lanes grey, internal lanes that continue the road green, turns red; the road's curve blue."""
    for lane_id in road_map.lane_ids:
        lane, shape = road_map.lane(lane_id), road_map.lane_shape(lane_id)
        colour, width = (
            ("0.6", 1.0) if not lane.is_internal else (("tab:green", 2.5) if lane.continues_road else ("tab:red", 1.5))
        )
        axes.plot(shape[:, 0], shape[:, 1], color=colour, linewidth=width)
    if path:
        ahead = LookAhead(road_map).horizon(path[0], [lane.rsplit("_", 1)[0] for lane in path], 250.0)
        for start_s, end_s in zip(ahead.part_start_s, ahead.part_end_s, strict=False):
            inside = (ahead.path.profile.s >= start_s) & (ahead.path.profile.s <= end_s)
            axes.plot(*ahead.path.xy[inside].T, color="tab:blue", linewidth=5, alpha=0.4)
    axes.set_title(title, fontsize=9)
    axes.set_aspect("equal")
    axes.set_axis_off()


def main() -> None:
    figure, (left, right) = pyplot.subplots(1, 2, figsize=(9, 4.5))
    with tempfile.TemporaryDirectory() as work:
        _draw(
            left, _crossroads(Path(work)), "crossroads: straight ahead continues (green),\nturns leave the road (red)"
        )
        left.set_xlim(-25.0, 25.0)
        left.set_ylim(-25.0, 25.0)
        _draw(
            right,
            _curve_with_side_road(Path(work)),
            "a side road inside a bend: the bend is\none curve of the road (blue)",
            ["a_0", "b_0"],
        )
    figure.tight_layout()
    figure.savefig(Path(__file__).with_suffix(".png"), dpi=110)


if __name__ == "__main__":
    main()
