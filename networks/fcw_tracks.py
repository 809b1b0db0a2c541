"""Generator of the test tracks of the forward collision warning suite (GB/T 33577-2017 5.4-5.5).

Two-lane roads, one edge each, lanes 3.5 m wide (the adjacent-lane tests want the two
vehicles' axes 3.5 m +- 0.25 m apart, 5.5.3.1):

* ``fcw_straight``: 3000 m straight, for the longitudinal tests (5.4, 5.5.2), the
  straight adjacent-lane test (5.5.3.1) and IVISTA's FCW scenarios;
* ``fcw_curve_r500``, ``fcw_curve_r250``, ``fcw_curve_r125``: a 60 m straight, then a left
  arc whose inner lane (lane 1, where subject and target drive) has the class's radius of
  Table 1 (500, 250, 125 m), then a 200 m straight: the curve tests of 5.5.3.2, the
  adjacent vehicle in the outer lane (lane 0). The arc is 1000 m long, or three quarters of the
  circle where that is shorter.

The edge's shape is the road's centre line between the two lanes (``spreadType="center"``).
SUMO measures a lane position along that line on every lane, so the truth gives each lane's
radius and the factor that turns a stretch of lane position into metres driven on the lane
(``(R_edge -+ W_L/2) / R_edge`` on the arc). The truth is written from the authored pieces,
never measured back from the network.
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path
from xml.etree import ElementTree

from csws.geometry import arc, piece_starts_s, sample_pieces, straight
from csws.sumo.netbuild import netconvert, plain_xml_text, shape_text

from .artifacts import json_difference, lane_differences, write_json
from .generate import PRECISION_DIGITS, SAMPLE_SPACING_M, _rounded

__all__ = [
    "FCW_DIR",
    "LANE_WIDTH_M",
    "CURVE_RADII_M",
    "fcw_track_names",
    "fcw_track_truth",
    "build_fcw_tracks",
    "compare_fcw_tracks",
]

#: The folder of the bundled networks that holds the FCW tracks.
FCW_DIR = "fcw"
#: W_L, m.
LANE_WIDTH_M = 3.5
#: The inner lane's radius of each curve track: the classes I, II, III of Table 1, m.
CURVE_RADII_M = (500.0, 250.0, 125.0)
STRAIGHT_M = 3000.0
CURVE_APPROACH_M, CURVE_RUNOUT_M, CURVE_ARC_M, CURVE_ARC_SHARE = 60.0, 200.0, 1000.0, 0.75
LANE_SPEED_MPS = 50.0
TRUTH_FORMAT = "csws-fcw-track-truth/1"


def fcw_track_names() -> list[str]:
    """Every FCW track, the straight first."""
    return ["fcw_straight", *(f"fcw_curve_r{radius_m:g}" for radius_m in CURVE_RADII_M)]


def _pieces(name: str) -> list:
    """The road's centre line: a straight, or approach, arc (inner lane at the class radius) and run-out."""
    if name == "fcw_straight":
        return [straight(STRAIGHT_M)]
    inner_m = float(name.removeprefix("fcw_curve_r"))
    edge_m = inner_m + LANE_WIDTH_M / 2.0
    arc_m = min(CURVE_ARC_M, CURVE_ARC_SHARE * 2.0 * math.pi * inner_m)
    return [
        straight(CURVE_APPROACH_M),
        arc(edge_m, math.degrees(arc_m * edge_m / inner_m / edge_m)),
        straight(CURVE_RUNOUT_M),
    ]


def fcw_track_truth(name: str) -> dict:
    """What a track is, from its pieces: length, the arc's start and end (lane positions, m) and
    each lane's radius and lane-position factor on the arc."""
    pieces = _pieces(name)
    starts = piece_starts_s(pieces)
    truth = {
        "format": TRUTH_FORMAT,
        "name": name,
        "lane_width_m": LANE_WIDTH_M,
        "length_m": _rounded(starts[-1]),
        "edge": "road",
        "curve": None,
    }
    if len(pieces) > 1:
        edge_radius_m = 1.0 / pieces[1].curvature
        lanes = {f"road_{index}": edge_radius_m + side * LANE_WIDTH_M / 2.0 for index, side in ((0, 1.0), (1, -1.0))}
        truth["curve"] = {
            "direction": "left",
            "start_pos_m": _rounded(starts[1]),
            "end_pos_m": _rounded(starts[2]),
            "edge_radius_m": _rounded(edge_radius_m),
            "lane_radius_m": {lane: _rounded(radius_m) for lane, radius_m in lanes.items()},
            "lane_factor": {lane: _rounded(radius_m / edge_radius_m) for lane, radius_m in lanes.items()},
        }
    return truth


def _plain_xml(name: str) -> tuple[str, str]:
    """One two-lane edge ``road`` from ``start`` to ``end`` along the pieces."""
    xy, _ = sample_pieces(_pieces(name), SAMPLE_SPACING_M)
    nodes, edges = ElementTree.Element("nodes"), ElementTree.Element("edges")
    for node_id, (x, y) in (("start", xy[0]), ("end", xy[-1])):
        ElementTree.SubElement(nodes, "node", id=node_id, x=f"{x:.6f}", y=f"{y:.6f}")
    ElementTree.SubElement(
        edges,
        "edge",
        id="road",
        attrib={"from": "start"},
        to="end",
        numLanes="2",
        speed=f"{LANE_SPEED_MPS:g}",
        width=f"{LANE_WIDTH_M:g}",
        spreadType="center",
        shape=shape_text(xy),
    )
    return plain_xml_text(nodes, edges)


def _build(name: str, directory: Path) -> Path:
    directory.mkdir(parents=True, exist_ok=True)
    net_file = directory / f"{name}.net.xml"
    netconvert(*_plain_xml(name), net_file, ["--precision", str(PRECISION_DIGITS)], strict=True)
    write_json(directory / f"{name}.truth.json", fcw_track_truth(name))
    return net_file


def build_fcw_tracks(directory: Path) -> list[Path]:
    """Build every FCW track into ``directory`` with its truth."""
    return [_build(name, Path(directory)) for name in fcw_track_names()]


def compare_fcw_tracks(directory: Path, tolerance_m: float = 0.01) -> list[str]:
    """Rebuild every FCW track and list how ``directory`` differs; empty when it matches."""
    differences = []
    with tempfile.TemporaryDirectory(prefix="csws-check-") as work:
        for name in fcw_track_names():
            committed = Path(directory) / f"{name}.net.xml"
            if not committed.is_file():
                differences.append(f"{FCW_DIR}/{committed.name}: missing")
                continue
            built = _build(name, Path(work))
            differences += lane_differences(name, built, committed, tolerance_m)
            differences += json_difference(Path(work) / f"{name}.truth.json", Path(directory) / f"{name}.truth.json")
    return differences
