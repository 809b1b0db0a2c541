"""The traffic of the co-simulation benchmark (:mod:`benchmarks.cosim`): SUMO routes of the fleet's mix of
vehicle types, all placed at once on the fleet road or in the city, or departing one by one (sparse traffic).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from csws.networks.fleet import FLEET_TYPES, backward_edges, draw_types, forward_edges, vtype_xml

__all__ = ["start_routes_xml", "sparse_routes_xml", "city_routes_xml"]


def start_routes_xml(count: int, seed: int = 0) -> str:
    """``count`` vehicles of the fleet's mix, each starting at a random section of either direction at t = 0."""
    rng = np.random.default_rng(seed)
    directions = (forward_edges(), backward_edges())
    lines = ["<routes>", *(vtype_xml(t) for t in FLEET_TYPES)]
    for index, fleet_type in enumerate(draw_types(count, rng)):
        edges = directions[index % 2]
        first = int(rng.integers(0, len(edges) - 1))
        type_id = fleet_type.type_id
        lines.append(
            f'<vehicle id="{type_id}{index}" type="{type_id}" depart="0" departPos="random_free" departLane="random" '
            f'departSpeed="max"><route edges="{" ".join(edges[first:])}"/></vehicle>'
        )
    return "\n".join(lines + ["</routes>"]) + "\n"


def sparse_routes_xml(count: int, period_s: float, seed: int = 0) -> str:
    """``count`` vehicles of the fleet's mix departing one every ``period_s`` along the whole road in one
    direction (some 400 m apart at 100 km/h with 15 s): the sparse traffic the FCW's schedule is for."""
    rng = np.random.default_rng(seed)
    lines = ["<routes>", *(vtype_xml(t) for t in FLEET_TYPES)]
    for index, fleet_type in enumerate(draw_types(count, rng)):
        lines.append(
            f'<vehicle id="{fleet_type.type_id}{index}" type="{fleet_type.type_id}" depart="{index * period_s:g}" '
            f'departSpeed="max"><route edges="{" ".join(forward_edges())}"/></vehicle>'
        )
    return "\n".join(lines + ["</routes>"]) + "\n"


def city_routes_xml(net: Path, count: int, seed: int = 0, edges_per_route: int = 40) -> str:
    """``count`` vehicles of the fleet's mix placed at t = 0, each on a random walk of up to
    ``edges_per_route`` edges through the network's roads that every type of the mix may use."""
    import sumolib

    classes = {t.vclass for t in FLEET_TYPES}
    network = sumolib.net.readNet(str(net))
    usable = [e for e in network.getEdges() if e.getFunction() != "internal" and all(map(e.allows, classes))]
    usable_ids = {e.getID() for e in usable}
    starts = [e for e in usable if e.getLength() >= 20.0]
    rng = np.random.default_rng(seed)
    lines = ["<routes>", *(vtype_xml(t) for t in FLEET_TYPES)]
    for index, fleet_type in enumerate(draw_types(count, rng)):
        edge = starts[int(rng.integers(len(starts)))]
        walk = [edge.getID()]
        for _ in range(edges_per_route - 1):
            onward = [e for e in edge.getOutgoing() if e.getID() in usable_ids and e.getToNode() != edge.getFromNode()]
            if not onward:
                break
            edge = onward[int(rng.integers(len(onward)))]
            walk.append(edge.getID())
        lines.append(
            f'<vehicle id="{fleet_type.type_id}{index}" type="{fleet_type.type_id}" depart="0" '
            f'departPos="random_free" departLane="best" departSpeed="max"><route edges="{" ".join(walk)}"/>'
            "</vehicle>"
        )
    return "\n".join(lines + ["</routes>"]) + "\n"
