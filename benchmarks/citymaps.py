"""A city map's curves checked against its own road polylines: corners missed, phantom curves, artefacts.

Measured on every road chain of a network (its lanes stitched into one polyline) by
:func:`csws.curvature.artefacts.polyline_turns`, which reads the polyline alone, never the fit:

* vertex corners of 45 degrees or more, and of 30-45 degrees, that no curve of the index
  covers: a curve of the corner's direction reaching within :data:`COVER_M` of the vertex, or
  within half the segment on that side of it where that is longer (a road through the nodes
  turns anywhere on the segments beside a node; the half beyond belongs to the next node, as a
  single-node corner's arc does in :func:`csws.curvature.corners.corner_arc`); those covered
  only so are counted too ("corners reached beyond 2 m"); an artefact's vertices count as one
  turn (its net turn), and a vertex next to a segment of :data:`csws.curvature.artefacts.JOG_M`
  or less is no corner (that segment has no heading);
* curves of 20 degrees or more where the polyline turns less than 5 degrees net over the
  curve's stretch (phantom curves), and curves claiming more than 360 degrees;
* curves at the radius floor of 5 m;
* the artefacts found, by kind;
* the map report's figures (:mod:`csws.osm.report`, one item per place: the lanes and the two
  directions of a way count once): the curves at the radius floor of the roads' own fits, split
  into real corners (a polyline corner reaches into the curve) and artefacts, the artefacts and the
  corners mapped by a single node, and how long the report took.

Junction chains (a turn's internal lanes) carry no curve of the index and are left out.

Run with ``python -m benchmarks.citymaps [--osm FILE]``: Bad Hersfeld
(``networks/badhersfeld.net.xml.gz``), and with ``--osm`` a network imported from that extract.
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

from csws.curvature.artefacts import polyline_turns
from csws.curvature.corners import FLOOR_RADIUS_M
from csws.osm.report import ARTEFACT_KINDS, FLOOR_CURVE, SINGLE_NODE_CORNER, network_items
from csws.road.roadmap import RoadMap

#: The bundled network measured by default.
NETWORK = Path(__file__).resolve().parent.parent / "networks" / "badhersfeld.net.xml.gz"
#: A curve covers a vertex corner reaching within this of it, m.
COVER_M = 2.0


def measure(roadmap: RoadMap) -> dict:
    """The figures of the module for one loaded network."""
    chains = roadmap.chains
    by_chain: dict[int, list] = {}
    for lane_curve in roadmap.curves():
        by_chain.setdefault(lane_curve.chain, []).append(lane_curve.curve)
    figures: Counter = Counter()
    artefacts: Counter = Counter()
    for chain, xy in enumerate(chains.xy):
        if chains.is_junction[chain]:
            continue
        turns = polyline_turns(xy)
        artefacts.update(artefact.kind for artefact in turns.artefacts)
        curves = by_chain.get(chain, [])
        at_corner = np.flatnonzero(turns.corner_vertices(30.0))
        for vertex in at_corner.tolist():
            vertex_s, turn = float(turns.vertex_s[vertex + 1]), float(turns.effective_rad[vertex])
            turn_deg = abs(math.degrees(turn))
            figures["corners >= 45 deg" if turn_deg >= 45.0 else "corners 30-45 deg"] += 1
            reach_m = (max(COVER_M, turns.segment_m[vertex] / 2.0), max(COVER_M, turns.segment_m[vertex + 1] / 2.0))
            direction = [c for c in curves if c.direction == ("left" if turn > 0 else "right")]
            if not any(c.start_s - reach_m[1] <= vertex_s <= c.end_s + reach_m[0] for c in direction):
                figures["missed >= 45 deg" if turn_deg >= 45.0 else "missed 30-45 deg"] += 1
            elif not any(c.start_s - COVER_M <= vertex_s <= c.end_s + COVER_M for c in direction):
                figures["corners reached beyond 2 m"] += 1
        for curve in curves:
            figures["curves"] += 1
            sign = 1.0 if curve.direction == "left" else -1.0
            if curve.angle_deg >= 20.0 and math.degrees(turns.net_turn_rad(curve.start_s, curve.end_s, sign)) < 5.0:
                figures["curves >= 20 deg on < 5 deg net"] += 1
            figures["curves > 360 deg"] += curve.angle_deg > 360.0
            figures["curves at the 5 m floor"] += curve.min_radius_m <= FLOOR_RADIUS_M + 1e-6
    figures.update({f"artefacts: {kind}": count for kind, count in artefacts.items()})
    figures.update(report_figures(roadmap))
    return dict(sorted(figures.items()))


def report_figures(roadmap: RoadMap) -> dict[str, float]:
    """The map report's figures of one loaded network (see the module)."""
    started = time.perf_counter()
    items = network_items(roadmap)
    took_s = time.perf_counter() - started
    floor = [item for item in items if item.kind == FLOOR_CURVE]
    real = sum(bool(item.real_corner) for item in floor)
    return {
        "report: floor curves, real corners": real,
        "report: floor curves, artefacts": len(floor) - real,
        "report: artefacts": sum(item.kind in ARTEFACT_KINDS.values() for item in items),
        "report: single-node corners": sum(item.kind == SINGLE_NODE_CORNER for item in items),
        "report s": round(took_s, 1),
    }


def run(network: Path = NETWORK, osm: Path | None = None) -> dict[str, dict]:
    """The figures for the bundled network and, with ``osm``, for a network imported from it."""
    results = {network.name: _timed(network)}
    if osm is not None:
        from csws.osm.importer import ImportSettings, import_osm

        with tempfile.TemporaryDirectory() as folder:
            net = Path(folder) / "city.net.xml.gz"
            import_osm(osm, net, ImportSettings())
            results[osm.name] = _timed(net)
    return results


def _timed(network: Path) -> dict:
    """:func:`measure` of a network and its load time."""
    started = time.perf_counter()
    roadmap = RoadMap.load(network)
    figures = measure(roadmap)
    figures["load s"] = round(time.perf_counter() - started, 1)
    return figures


def main() -> None:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.citymaps", description=__doc__.splitlines()[0])
    parser.add_argument("--osm", type=Path, help="an OpenStreetMap extract to import and measure too")
    parser.add_argument("--net", type=Path, default=NETWORK, help="the network to measure (default: Bad Hersfeld)")
    args = parser.parse_args()
    for name, figures in run(args.net, args.osm).items():
        print(name)
        for key, value in figures.items():
            print(f"  {key:<36} {value}")


if __name__ == "__main__":
    main()
