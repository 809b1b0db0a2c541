"""Generator of the real-road test tracks and of their ground truth.

The standard's tracks (:mod:`csws.networks.generate`) are straights and circular arcs
meeting at a point. Real roads are not: their curves are entered and left through
clothoids (spirals), compound curves step from one radius to the next through spirals,
S-bends turn through an inflection, and map data puts nodes inside curves (a way split,
a side road joining). These tracks are such roads, each authored exactly with
:mod:`csws.geometry`:

* ``rr_spiral_r40``, ``rr_spiral_r120``, ``rr_spiral_r200``: an arc of R 40, 120 and 200 m
  between clothoids of 30, 60 and 80 m;
* ``rr_compound``: R 250 -> 90 -> 35 m, every step and both ends a clothoid;
* ``rr_s_bend``: two R 100 m curves turning opposite ways, each entered by a clothoid and
  joined through one clothoid across the inflection;
* ``rr_node_in_curve``: a 25.7 m arc of R 71 m with a node 9.5 m after its start, where
  netconvert builds its own junction;
* ``rr_side_road``: an R 150 m curve between clothoids with a side road joining at a node
  in its middle.

A track is a straight approach, the curves and a straight run-out, cut into edges at
``ENTRY_M`` before the curves, at the nodes inside them and at ``EXIT_M`` after them.
Nodes on the straights get a junction shape across the road (netconvert trims nothing
there); nodes inside curves are left to netconvert, as an imported map's are.

The truth (``NAME.truth.json`` in ``networks/real_roads/``) is written from the authored
pieces, never measured back: the pieces themselves (length, curvature at start and end),
so that the curvature at every point of the route is known exactly, and the curves they
make for the warning curvature radius R_c = 300 m (3.3-3.5).
"""

from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from csws.geometry import Piece, arc, clothoid, curvature_at, piece_starts_s, pose_at, straight
from csws.standard import DEFAULT_WARNING_RADIUS_M
from csws.sumo.netbuild import netconvert, plain_xml_text, shape_text

from .artifacts import json_difference, lane_differences, write_json
from .generate import (
    APPROACH_M,
    ENTRY_M,
    EXIT_M,
    LANE_SPEED_MPS,
    PRECISION_DIGITS,
    RUNOUT_M,
    SAMPLE_SPACING_M,
    _junction_shape,
    _rounded,
)

__all__ = [
    "REAL_ROADS_DIR",
    "TRUTH_FORMAT",
    "INDEX_FORMAT",
    "RealRoadSpec",
    "real_road_specs",
    "real_road_pieces",
    "real_road_truth",
    "build_real_roads",
    "compare_real_roads",
    "true_curves",
]

#: The folder of the bundled networks that holds the real-road tracks.
REAL_ROADS_DIR = "real_roads"

TRUTH_FORMAT = "csws-real-road-truth/1"
INDEX_FORMAT = "csws-real-road-index/1"
#: The side road joins from this far away, m.
SIDE_ROAD_M = 120.0
#: Sampling of the exact curvature when the truth's curves are found, m.
CURVE_SAMPLING_M = 0.001


@dataclass(frozen=True)
class RealRoadSpec:
    """One real-road track.

    Attributes
    ----------
    name
        Network name.
    description
        What the track is, in a line.
    curve_pieces
        The pieces between the approach and the run-out.
    nodes_at_m
        Where nodes split the road inside its curves, m from the start of ``curve_pieces``.
    side_road_at
        Index into ``nodes_at_m`` of the node a side road joins at, else None.
    """

    name: str
    description: str
    curve_pieces: tuple[Piece, ...]
    nodes_at_m: tuple[float, ...] = ()
    side_road_at: int | None = None


def _spiral_curve(radius_m: float, spiral_m: float, angle_deg: float, direction: str = "left") -> tuple[Piece, ...]:
    return (
        clothoid(spiral_m, math.inf, radius_m, direction),
        arc(radius_m, angle_deg, direction),
        clothoid(spiral_m, radius_m, math.inf, direction),
    )


def real_road_specs() -> list[RealRoadSpec]:
    """Every real-road track."""
    node_arc = arc(71.0, math.degrees(25.7 / 71.0), "right")
    side = _spiral_curve(150.0, 40.0, 30.0, "right")
    return [
        RealRoadSpec("rr_spiral_r40", "R 40 m arc between 30 m clothoids", _spiral_curve(40.0, 30.0, 50.0)),
        RealRoadSpec("rr_spiral_r120", "R 120 m arc between 60 m clothoids", _spiral_curve(120.0, 60.0, 25.0, "right")),
        RealRoadSpec("rr_spiral_r200", "R 200 m arc between 80 m clothoids", _spiral_curve(200.0, 80.0, 20.0)),
        RealRoadSpec(
            "rr_compound",
            "compound curve R 250 -> 90 -> 35 m, clothoids at both ends and between the arcs",
            (
                clothoid(50.0, math.inf, 250.0),
                arc(250.0, 12.0),
                clothoid(40.0, 250.0, 90.0),
                arc(90.0, 20.0),
                clothoid(40.0, 90.0, 35.0),
                arc(35.0, 40.0),
                clothoid(40.0, 35.0, math.inf),
            ),
        ),
        RealRoadSpec(
            "rr_s_bend",
            "S-bend: two R 100 m curves turning opposite ways, joined through one clothoid",
            (
                clothoid(40.0, math.inf, 100.0),
                arc(100.0, 20.0),
                Piece(60.0, 1.0 / 100.0, -1.0 / 100.0),
                arc(100.0, 20.0, "right"),
                clothoid(40.0, 100.0, math.inf, "right"),
            ),
        ),
        RealRoadSpec(
            "rr_node_in_curve", "25.7 m arc of R 71 m with a node 9.5 m after its start", (node_arc,), nodes_at_m=(9.5,)
        ),
        RealRoadSpec(
            "rr_side_road",
            "R 150 m curve between 40 m clothoids, a side road joining in its middle",
            side,
            nodes_at_m=(40.0 + side[1].length_m / 2.0,),
            side_road_at=0,
        ),
    ]


def real_road_pieces(spec: RealRoadSpec) -> list[Piece]:
    """The whole road: approach, the curve pieces, run-out."""
    return [straight(APPROACH_M), *spec.curve_pieces, straight(RUNOUT_M)]


def true_curves(
    pieces: list[Piece], warning_radius_m: float = DEFAULT_WARNING_RADIUS_M, sampling_m: float = CURVE_SAMPLING_M
) -> list[dict]:
    """The curves (3.3-3.5) of the exact road: maximal stretches turning one way with radius
    at most R_c, from its curvature sampled every ``sampling_m``: start and end (m), smallest
    radius (m), angle (degrees) and direction."""
    s = np.arange(0.0, piece_starts_s(pieces)[-1], sampling_m)
    curvature = curvature_at(pieces, s)
    side = np.where(curvature >= 1.0 / warning_radius_m, 1, np.where(curvature <= -1.0 / warning_radius_m, -1, 0))
    edges = np.flatnonzero(np.diff(np.concatenate(([0], side, [0]))) != 0)
    curves = []
    for first, stop in zip(edges[:-1], edges[1:], strict=False):
        if side[first] == 0:
            continue
        magnitude = np.abs(curvature[first:stop])
        curves.append(
            {
                "start_s": _rounded(s[first]),
                "end_s": _rounded(s[stop - 1]),
                "min_radius_m": _rounded(1.0 / magnitude.max()),
                "angle_deg": _rounded(math.degrees(magnitude.sum() * sampling_m)),
                "direction": "left" if side[first] > 0 else "right",
            }
        )
    return curves


def _edge_bounds_s(spec: RealRoadSpec) -> list[float]:
    """Route positions of the edges' ends: start, entry, the nodes inside the curves, exit, end."""
    curves_m = sum(piece.length_m for piece in spec.curve_pieces)
    inside = [APPROACH_M + at_m for at_m in spec.nodes_at_m]
    return [0.0, APPROACH_M - ENTRY_M, *inside, APPROACH_M + curves_m + EXIT_M, APPROACH_M + curves_m + RUNOUT_M]


def _edge_ids(spec: RealRoadSpec) -> list[str]:
    middle = ["curve"] if not spec.nodes_at_m else [f"curve{i}" for i in range(1, len(spec.nodes_at_m) + 2)]
    return ["approach", *middle, "runout"]


def _shape(pieces: list[Piece], start_s: float, end_s: float) -> np.ndarray:
    """The exact road from ``start_s`` to ``end_s``, sampled every ``SAMPLE_SPACING_M``."""
    s = np.append(np.arange(start_s, end_s - 1e-9, SAMPLE_SPACING_M), end_s)
    x, y, _ = pose_at(pieces, s)
    return np.column_stack((x, y))


def _plain_xml(spec: RealRoadSpec) -> tuple[str, str]:
    """Plain-XML nodes and edges: the route's edges, and a side road where the track has one."""
    pieces = real_road_pieces(spec)
    bounds = _edge_bounds_s(spec)
    x, y, heading = pose_at(pieces, np.array(bounds))
    inside = set(range(2, 2 + len(spec.nodes_at_m)))
    nodes, edges = ElementTree.Element("nodes"), ElementTree.Element("edges")
    for number in range(len(bounds)):
        node = ElementTree.SubElement(
            nodes, "node", id=f"n{number}", x=f"{x[number]:.6f}", y=f"{y[number]:.6f}", type="priority"
        )
        if 0 < number < len(bounds) - 1 and number not in inside:
            node.set("shape", shape_text(_junction_shape(x[number], y[number], heading[number])))
    for number, edge_id in enumerate(_edge_ids(spec)):
        ElementTree.SubElement(
            edges,
            "edge",
            id=edge_id,
            attrib={"from": f"n{number}"},
            to=f"n{number + 1}",
            numLanes="1",
            speed=f"{LANE_SPEED_MPS:g}",
            priority="2",
            spreadType="center",
            shape=shape_text(_shape(pieces, bounds[number], bounds[number + 1])),
        )
    if spec.side_road_at is not None:
        joint = 2 + spec.side_road_at
        outward = heading[joint] + (
            math.pi / 2 if curvature_at(pieces, np.array([bounds[joint]]))[0] < 0 else -math.pi / 2
        )
        side_xy = (x[joint] + SIDE_ROAD_M * math.cos(outward), y[joint] + SIDE_ROAD_M * math.sin(outward))
        ElementTree.SubElement(nodes, "node", id="side", x=f"{side_xy[0]:.6f}", y=f"{side_xy[1]:.6f}", type="priority")
        ElementTree.SubElement(
            edges,
            "edge",
            id="side",
            attrib={"from": "side"},
            to=f"n{joint}",
            numLanes="1",
            speed="13.89",
            priority="1",
            spreadType="center",
        )
    return plain_xml_text(nodes, edges)


def real_road_truth(spec: RealRoadSpec) -> dict:
    """The ground truth of a track, from its authored pieces."""
    pieces = real_road_pieces(spec)
    bounds = _edge_bounds_s(spec)
    return {
        "format": TRUTH_FORMAT,
        "name": spec.name,
        "description": spec.description,
        "units": {"length": "m", "curvature": "1/m", "angle": "deg"},
        "start_xy": [0.0, 0.0],
        "start_heading_deg": 0.0,
        "pieces": [
            {"length_m": _rounded(p.length_m), "curvature": p.curvature, "end_curvature": p.final_curvature}
            for p in pieces
        ],
        "route": {"edges": _edge_ids(spec), "length_m": _rounded(bounds[-1])},
        "edge_start_s": {edge: _rounded(s) for edge, s in zip(_edge_ids(spec), bounds, strict=False)},
        "nodes_in_curves_s": [_rounded(APPROACH_M + at_m) for at_m in spec.nodes_at_m],
        "side_road": None
        if spec.side_road_at is None
        else {"edge": "side", "joins_at_s": _rounded(bounds[2 + spec.side_road_at])},
        "warning_radius_m": DEFAULT_WARNING_RADIUS_M,
        "curves": true_curves(pieces),
    }


def _build(spec: RealRoadSpec, directory: Path) -> Path:
    """Write ``NAME.net.xml`` and ``NAME.truth.json`` of one track into ``directory``."""
    directory.mkdir(parents=True, exist_ok=True)
    net_file = directory / f"{spec.name}.net.xml"
    netconvert(*_plain_xml(spec), net_file, ["--precision", str(PRECISION_DIGITS)])
    write_json(directory / f"{spec.name}.truth.json", real_road_truth(spec))
    return net_file


def _index(specs: list[RealRoadSpec]) -> dict:
    return {
        "format": INDEX_FORMAT,
        "tracks": [
            {
                "name": spec.name,
                "description": spec.description,
                "net_file": f"{spec.name}.net.xml",
                "truth_file": f"{spec.name}.truth.json",
                "min_radius_m": min(c["min_radius_m"] for c in true_curves(real_road_pieces(spec))),
            }
            for spec in specs
        ],
    }


def build_real_roads(directory: Path) -> list[Path]:
    """Build every real-road track into ``directory`` with its truth and ``index.json``."""
    specs = real_road_specs()
    written = [_build(spec, Path(directory)) for spec in specs]
    write_json(Path(directory) / "index.json", _index(specs))
    return written


def compare_real_roads(directory: Path, tolerance_m: float = 0.01) -> list[str]:
    """Rebuild every real-road track and list how ``directory`` differs; empty when it matches."""
    directory = Path(directory)
    differences = []
    with tempfile.TemporaryDirectory(prefix="csws-check-") as work:
        for spec in real_road_specs():
            committed = directory / f"{spec.name}.net.xml"
            if not committed.is_file():
                differences.append(f"real_roads/{committed.name}: missing")
                continue
            built = _build(spec, Path(work))
            differences += lane_differences(spec.name, built, committed, tolerance_m)
            differences += json_difference(
                Path(work) / f"{spec.name}.truth.json", directory / f"{spec.name}.truth.json"
            )
        write_json(Path(work) / "index.json", _index(real_road_specs()))
        differences += json_difference(Path(work) / "index.json", directory / "index.json")
    return differences
