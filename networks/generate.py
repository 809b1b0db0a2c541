"""Generator of the bundled test tracks of T/ITS 0091-2018 and of their ground truth.

Every track is one road authored with :mod:`csws.geometry` (exact straights and circular
arcs) and turned into a SUMO network by writing plain XML (nodes, edges) and calling
netconvert. The tracks are

* the single curves of 7.4.1, Table 3 (``single_r40_left``, ...),
* the multi curves of 7.4.2, Table 4, with the curve lengths of the tests of 7.5.3:
  Table 7 (one track for every category: ``t7_left``), Table 8 and Table 9 (one track
  per category column and test: ``t8_m1_test1_left``, ``t9_m3_n_o_test2_right``, ...),
  and one S-curve variant (``t9_m1_test1_s``: curve 1 left, curve 2 right).

Each track is laid out the same way (see :func:`track_pieces`): a straight approach on
which the vehicle reaches and holds the test speed (7.5.1), the curve or curves, and a
straight run-out. It is cut into three single-lane edges, ``approach``, ``curve`` and
``runout``, whose boundaries lie on the straights, so that netconvert trims nothing and a
lane position is the authored arc length from the start of its edge.

The ground truth of each network (``NAME.truth.json``) is written from the authored
pieces, never measured back from the built network: where each curve starts and ends
along the route and on its lane, its radius, angle and direction. ``index.json`` lists
every network with the table row it implements and its route.
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from xml.etree import ElementTree

import numpy as np

from csws.data import standard_tables
from csws.geometry import Piece, arc, piece_starts_s, pose_at, sample_pieces, straight
from csws.sumo.netbuild import netconvert, plain_xml_text, shape_text

from .artifacts import json_difference, lane_differences, write_json

__all__ = [
    "APPROACH_M",
    "ENTRY_M",
    "RUNOUT_M",
    "EXIT_M",
    "SAMPLE_SPACING_M",
    "PRECISION_DIGITS",
    "LANE_SPEED_MPS",
    "ANGLE_MARGIN",
    "JUNCTION_WIDTH_M",
    "ROUTE_EDGES",
    "S_CURVE_TEST",
    "TRUTH_FORMAT",
    "CurveSpec",
    "TrackSpec",
    "track_specs",
    "track_pieces",
    "track_truth",
    "networks_index",
    "build_network",
    "build_tracks",
    "compare_network",
    "compare_tracks",
]

#: Straight before the first curve, m. With 1000 m a vehicle starting from rest at a
#: modest 1 m/s^2 reaches the highest test speed (136 km/h, Table 6) after 714 m and holds
#: it for 3 s (113 m) before the largest warning distance of the single curves (57 m); the
#: multi-curve tests (<= 130 km/h, S_w <= 144 m to curve 2, which lies L1 after curve 1)
#: need less (7.5.1).
APPROACH_M = 1000.0
#: The approach edge ends this far before the first curve, m, so the road a vehicle looks
#: ahead on spans two edges: the longest warning distances (up to 144 m, Tables 8-9) begin
#: on the approach edge.
ENTRY_M = 100.0
#: Straight after the last curve, m.
RUNOUT_M = 300.0
#: The run-out edge starts this far after the last curve, m.
EXIT_M = 100.0
#: Vertex spacing of the authored lane shapes, m (every curve start and end is a vertex).
SAMPLE_SPACING_M = 0.5
#: Digits after the decimal point netconvert writes (``--precision``): 1 mm, so the
#: rounding of the coordinates changes neither a curve's position nor its radius measurably.
PRECISION_DIGITS = 3
#: Lane speed limit, m/s (180 km/h): above every test speed of Tables 5-9.
LANE_SPEED_MPS = 50.0
#: A curve whose angle the standard leaves open (the single curves of Table 3, curve 2 of
#: Table 4) turns this many times the standard's minimum angle, so a vehicle is well inside
#: the curve before it leaves it.
ANGLE_MARGIN = 2.0
#: Width of the custom shape of a node between two edges, m: SUMO's default lane width.
JUNCTION_WIDTH_M = 3.2
#: Edge ids of every track in driving order; the route of every network.
ROUTE_EDGES = ("approach", "curve", "runout")
#: Node ids at the start of each edge and at the end of the last.
_NODES = ("start", "entry", "exit", "end")
#: Format tag of the truth files.
TRUTH_FORMAT = "csws-track-truth/1"
#: The folder of the real-road tracks, beside the standard's.
#: Decimal places of the lengths and coordinates in the truth files (1 um): the truth is
#: reproducible to the byte and far finer than any tolerance that uses it.
_TRUTH_DECIMALS = 6

_STANDARD = "T/ITS 0091-2018"


@dataclass(frozen=True)
class CurveSpec:
    """One curve of a track: a circular arc (3.3-3.6).

    Attributes
    ----------
    name
        The standard's name: ``"curve"`` on a single-curve track, else ``"curve 1"``, ``"curve 2"``.
    radius_m
        Radius R, m.
    angle_deg
        Curve angle theta (3.6), degrees.
    direction
        ``"left"`` or ``"right"``.
    """

    name: str
    radius_m: float
    angle_deg: float
    direction: str

    @property
    def length_m(self) -> float:
        """Arc length L, m."""
        return self.radius_m * math.radians(self.angle_deg)


@dataclass(frozen=True)
class TrackSpec:
    """One test track: which row of the standard it implements and its curves in driving order.

    Attributes
    ----------
    name
        Network name; the files are ``NAME.net.xml`` and ``NAME.truth.json``.
    table
        The standard's table: 3 (single curve), 7, 8 or 9 (multi curve).
    clause
        The clause that defines the track: ``"7.4.1"`` or ``"7.4.2"``.
    row
        The table row as transcribed in ``csws/data/t_its_0091_2018_tables.json``.
    category
        Category column (``"M1"``, ``"M2"``, ``"M3_N_O"``) where the track depends on it, else None.
    test
        Test number of Tables 8 and 9, else None.
    direction
        ``"left"``, ``"right"``, or ``"s"`` (curve 1 left, curve 2 right).
    curves
        The curves in driving order.
    """

    name: str
    table: int
    clause: str
    row: dict
    category: str | None
    test: int | None
    direction: str
    curves: tuple[CurveSpec, ...]


def _single_curve_specs(tables: dict) -> list[TrackSpec]:
    """The single-curve tracks of 7.4.1, Table 3: every radius, turning left and right."""
    return [
        TrackSpec(
            name=f"single_r{row['radius_m']:g}_{direction}",
            table=3,
            clause="7.4.1",
            row=row,
            category=None,
            test=None,
            direction=direction,
            curves=(CurveSpec("curve", float(row["radius_m"]), ANGLE_MARGIN * row["min_angle_deg"], direction),),
        )
        for row in tables["table3_single_curve_track"]
        for direction in ("left", "right")
    ]


def _table_key(tables: dict, table: int) -> str:
    """Key of the multi-curve test table ``table`` (7, 8 or 9) in the transcription."""
    return next(key for key in tables if key.startswith(f"table{table}_"))


def _table4_row(tables: dict, table_key: str) -> dict:
    """The row of Table 4 whose case the multi-curve test table ``table_key`` is named after."""
    return next(row for row in tables["table4_multi_curve_track_min_angle_deg"] if table_key.endswith(row["case"]))


#: Directions of curve 1 and curve 2 for each direction of a multi-curve track.
_DIRECTIONS = {"left": ("left", "left"), "right": ("right", "right"), "s": ("left", "right")}
#: Table, category column and test of the one S-curve track.
S_CURVE_TEST = (9, "M1", 1)


def _multi_curve_track(tables: dict, table: int, row: dict, category: str | None, direction: str) -> TrackSpec:
    """A multi-curve track of 7.4.2: curve 1 (R1, L1 of the test's row) joined directly to curve 2.

    Curve 2 has the table's R2 and turns ``ANGLE_MARGIN`` times Table 4's minimum.
    ValueError when the row breaks Table 4's minimum angles or the L2 minimum, that is
    when the transcription disagrees with itself.
    """
    key = _table_key(tables, table)
    limits = tables[key].get("track", tables[key])  # Table 7 keeps R2 and L2 with its one track
    minimum_deg = _table4_row(tables, key)
    first, second = _DIRECTIONS[direction]
    curve1 = CurveSpec("curve 1", float(row["R1_m"]), math.degrees(row["L1_m"] / row["R1_m"]), first)
    curve2 = CurveSpec("curve 2", float(limits["R2_m"]), ANGLE_MARGIN * minimum_deg["curve2"], second)
    if curve1.angle_deg < minimum_deg["curve1"] or curve2.length_m < limits["L2_min_m"]:
        raise ValueError(f"Table {table} row {row} breaks Table 4 case {minimum_deg['case']!r}")
    test = row.get("test")
    name = f"t{table}_{direction}" if category is None else f"t{table}_{category.lower()}_test{test}_{direction}"
    return TrackSpec(name, table, "7.4.2", row, category, test, direction, (curve1, curve2))


def _multi_curve_specs(tables: dict) -> list[TrackSpec]:
    """The multi-curve tracks of 7.4.2 for the tests of Tables 7, 8 and 9 (7.5.3), left and right.

    Table 7 has one track for every category; Tables 8 and 9 one per category column and
    test. One S-curve variant is added, for ``S_CURVE_TEST``.
    """
    table7 = tables[_table_key(tables, 7)]
    specs = [_multi_curve_track(tables, 7, table7["track"], None, direction) for direction in ("left", "right")]
    for table in (8, 9):
        for category in tables["categories"]:
            for row in tables[_table_key(tables, table)][category]:
                s_curve = ("s",) if (table, category, row["test"]) == S_CURVE_TEST else ()
                specs += [
                    _multi_curve_track(tables, table, row, category, direction)
                    for direction in ("left", "right", *s_curve)
                ]
    return specs


def track_specs() -> list[TrackSpec]:
    """Every bundled track, built from the standard's tables as transcribed (7.4, Tables 3-4, 7-9)."""
    tables = standard_tables()
    return _single_curve_specs(tables) + _multi_curve_specs(tables)


def track_pieces(spec: TrackSpec) -> list[Piece]:
    """The road of a track from its start: approach, curves joined directly, run-out.

    The approach and run-out straights are each two pieces, split where the edges meet
    (``ENTRY_M`` before the first curve, ``EXIT_M`` after the last), so that every edge
    boundary and every curve start and end is a piece boundary.
    """
    curves = [arc(curve.radius_m, curve.angle_deg, curve.direction) for curve in spec.curves]
    return [straight(APPROACH_M - ENTRY_M), straight(ENTRY_M), *curves, straight(EXIT_M), straight(RUNOUT_M - EXIT_M)]


def _edge_piece_ranges(pieces: Sequence[Piece]) -> list[tuple[int, int]]:
    """``[first, stop)`` piece indices of each edge of ``ROUTE_EDGES``."""
    return [(0, 1), (1, len(pieces) - 1), (len(pieces) - 1, len(pieces))]


def _edge_shapes(pieces: Sequence[Piece]) -> list[np.ndarray]:
    """The authored ``(n, 2)`` shape of each edge: its pieces sampled every ``SAMPLE_SPACING_M``."""
    starts = piece_starts_s(pieces)
    x, y, heading = pose_at(pieces, starts)
    return [
        sample_pieces(pieces[first:stop], SAMPLE_SPACING_M, (x[first], y[first]), heading[first])[0]
        for first, stop in _edge_piece_ranges(pieces)
    ]


def _rounded(value: float) -> float:
    """A length or coordinate rounded for the truth file."""
    return round(float(value), _TRUTH_DECIMALS)


def _lane_id(edge_id: str) -> str:
    """Id of the single lane of ``edge_id``."""
    return f"{edge_id}_0"


def track_truth(spec: TrackSpec) -> dict[str, Any]:
    """The ground truth of a track, from its authored pieces (see ``networks/README.md``).

    Positions ``s`` are arc lengths along the route from its start; lane positions are
    arc lengths from the start of the lane, which equal SUMO's lane positions because
    the edge boundaries lie on straights where netconvert trims nothing.
    """
    pieces = track_pieces(spec)
    starts = piece_starts_s(pieces)
    return {
        "format": TRUTH_FORMAT,
        "name": spec.name,
        "units": {"length": "m", "angle": "deg", "speed": "m/s"},
        "standard": {
            "document": _STANDARD,
            "clause": spec.clause,
            "table": spec.table,
            "category": spec.category,
            "test": spec.test,
            "row": spec.row,
        },
        "generator": _generator_settings(),
        "direction": spec.direction,
        "route": {"edges": list(ROUTE_EDGES), "length_m": _rounded(starts[-1])},
        "lanes": _truth_lanes(pieces, starts),
        "curves": _truth_curves(spec, pieces, starts),
    }


def _generator_settings() -> dict[str, Any]:
    """How the generator laid the tracks out, as the truth files record it."""
    return {
        "approach_m": APPROACH_M,
        "entry_m": ENTRY_M,
        "runout_m": RUNOUT_M,
        "exit_m": EXIT_M,
        "sample_spacing_m": SAMPLE_SPACING_M,
        "precision_digits": PRECISION_DIGITS,
        "lane_speed_mps": LANE_SPEED_MPS,
        "angle_margin": ANGLE_MARGIN,
        "start_xy": [0.0, 0.0],
        "start_heading_deg": 0.0,
    }


def _truth_lanes(pieces: Sequence[Piece], starts: np.ndarray) -> list[dict[str, Any]]:
    """Each route edge's lane with where it starts and ends along the route."""
    return [
        {
            "lane": _lane_id(edge_id),
            "edge": edge_id,
            "start_s": _rounded(starts[first]),
            "end_s": _rounded(starts[stop]),
            "length_m": _rounded(starts[stop] - starts[first]),
        }
        for edge_id, (first, stop) in zip(ROUTE_EDGES, _edge_piece_ranges(pieces), strict=False)
    ]


def _truth_curves(spec: TrackSpec, pieces: Sequence[Piece], starts: np.ndarray) -> list[dict[str, Any]]:
    """Each curve: radius, angle, direction, where it starts and ends along the route, in the plane
    and on the curve edge's lane."""
    x, y, heading = pose_at(pieces, starts)
    curve_edge_first, _ = _edge_piece_ranges(pieces)[ROUTE_EDGES.index("curve")]
    curves = []
    for number, curve in enumerate(spec.curves, start=1):
        index = curve_edge_first + number  # the curve edge opens with the entry straight
        start_s, end_s = starts[index], starts[index + 1]
        curves.append(
            {
                "number": number,
                "name": curve.name,
                "radius_m": _rounded(curve.radius_m),
                "angle_deg": _rounded(curve.angle_deg),
                "length_m": _rounded(end_s - start_s),
                "direction": curve.direction,
                "start_s": _rounded(start_s),
                "end_s": _rounded(end_s),
                "start_xy": [_rounded(x[index]), _rounded(y[index])],
                "end_xy": [_rounded(x[index + 1]), _rounded(y[index + 1])],
                "start_heading_deg": _rounded(math.degrees(heading[index])),
                "end_heading_deg": _rounded(math.degrees(heading[index + 1])),
                "lanes": [
                    {
                        "lane": _lane_id("curve"),
                        "start_pos_m": _rounded(start_s - starts[curve_edge_first]),
                        "end_pos_m": _rounded(end_s - starts[curve_edge_first]),
                    }
                ],
            }
        )
    return curves


def networks_index(specs: Sequence[TrackSpec]) -> dict:
    """The contents of ``index.json``: every network with the table row it implements and its route."""
    return {
        "format": "csws-track-index/1",
        "standard": _STANDARD,
        "networks": [
            {
                "name": spec.name,
                "net_file": f"{spec.name}.net.xml",
                "truth_file": f"{spec.name}.truth.json",
                "table": spec.table,
                "clause": spec.clause,
                "category": spec.category,
                "test": spec.test,
                "radius_m": [curve.radius_m for curve in spec.curves],
                "direction": spec.direction,
                "route": list(ROUTE_EDGES),
            }
            for spec in specs
        ],
    }


def _junction_shape(x_m: float, y_m: float, heading_rad: float) -> np.ndarray:
    """Custom shape of a node between two edges: a line ``JUNCTION_WIDTH_M`` wide across the road.

    Left to itself netconvert trims about 0.15 m off both edges at a node joining two
    collinear edges for most headings; a junction shape that is a line across the road
    through the node makes both lanes end exactly at the node, so the lane positions stay
    the authored arc lengths.
    """
    across = np.array([-math.sin(heading_rad), math.cos(heading_rad)]) * JUNCTION_WIDTH_M / 2
    return np.array([[x_m, y_m] + across, [x_m, y_m] - across])


def _plain_xml(spec: TrackSpec) -> tuple[str, str]:
    """Plain-XML node and edge files of a track.

    Single-lane edges with ``spreadType="center"``: the lane runs on the authored shape
    (the default spread puts a one-lane centreline half a lane width to the right).
    """
    pieces = track_pieces(spec)
    x, y, heading = pose_at(pieces, piece_starts_s(pieces))
    ranges = _edge_piece_ranges(pieces)
    node_pieces = [first for first, _ in ranges] + [len(pieces)]
    nodes = ElementTree.Element("nodes")
    for number, (node_id, index) in enumerate(zip(_NODES, node_pieces, strict=False)):
        node = ElementTree.SubElement(nodes, "node", id=node_id, x=f"{x[index]:.6f}", y=f"{y[index]:.6f}")
        if 0 < number < len(_NODES) - 1:
            node.set("shape", shape_text(_junction_shape(x[index], y[index], heading[index])))
    edges = ElementTree.Element("edges")
    for number, (edge_id, shape) in enumerate(zip(ROUTE_EDGES, _edge_shapes(pieces), strict=False)):
        ElementTree.SubElement(
            edges,
            "edge",
            id=edge_id,
            attrib={"from": _NODES[number]},
            to=_NODES[number + 1],
            numLanes="1",
            speed=f"{LANE_SPEED_MPS:g}",
            spreadType="center",
            shape=shape_text(shape),
        )
    return plain_xml_text(nodes, edges)


def build_network(spec: TrackSpec, directory: Path) -> Path:
    """Write ``NAME.net.xml`` and ``NAME.truth.json`` of one track into ``directory``; the network's path."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    net_file = directory / f"{spec.name}.net.xml"
    node_text, edge_text = _plain_xml(spec)
    netconvert(node_text, edge_text, net_file, ["--precision", str(PRECISION_DIGITS)], strict=True)
    write_json(directory / f"{spec.name}.truth.json", track_truth(spec))
    return net_file


def build_tracks(directory: Path) -> list[Path]:
    """Build every track into ``directory`` with its truth and ``index.json``; the network paths."""
    specs = track_specs()
    written = [build_network(spec, directory) for spec in specs]
    write_json(Path(directory) / "index.json", networks_index(specs))
    return written


def compare_network(spec: TrackSpec, directory: Path, tolerance_m: float = 0.01) -> list[str]:
    """Rebuild one track in a temporary folder and list how ``directory``'s copy differs; empty when it matches.

    The networks are compared lane by lane (ids, speeds, lengths and shape points within
    ``tolerance_m``), not byte by byte: netconvert stamps each file with the time it was
    built. The truth must match exactly.
    """
    committed = Path(directory) / f"{spec.name}.net.xml"
    if not committed.is_file():
        return [f"{committed.name}: missing"]
    with tempfile.TemporaryDirectory(prefix="csws-check-") as work:
        built = build_network(spec, Path(work))
        truth = f"{spec.name}.truth.json"
        return lane_differences(spec.name, built, committed, tolerance_m) + json_difference(
            Path(work) / truth, Path(directory) / truth
        )


def compare_tracks(directory: Path) -> list[str]:
    """Rebuild every track and list how ``directory`` differs from the generator; empty when it matches.

    Networks in ``directory`` that the generator no longer makes are reported too.
    """
    directory = Path(directory)
    specs = track_specs()
    differences = [line for spec in specs for line in compare_network(spec, directory)]
    known = {f"{spec.name}.net.xml" for spec in specs}
    stale = [path.name for path in sorted(directory.glob("*.net.xml")) if path.name not in known]
    differences += [f"{name}: not made by the generator" for name in stale]
    with tempfile.TemporaryDirectory(prefix="csws-check-") as work:
        index = Path(work) / "index.json"
        write_json(index, networks_index(specs))
        differences += json_difference(index, directory / "index.json")
    return differences
