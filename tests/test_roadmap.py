"""The road map against networks built exactly with csws.geometry and netconverted here."""

from __future__ import annotations

import csv
import gzip
import io
import json
from pathlib import Path

import numpy as np
import pytest
from markers import marks_its_tests

from csws.geometry import arc, piece_starts_s, pose_at, sample_pieces, straight
from csws.road.export import CURVE_FIELDS, write_curves
from csws.road.roadmap import NetworkError, RoadMap
from csws.sumo.netbuild import netconvert, shape_text

#: A straight, a 60 degree left arc of 200 m cut in two halves, a straight: the node
#: between the two halves puts an edge boundary (and a junction) in the middle of the arc.
ARC_RADIUS_M = 200.0
MID_ARC_PIECES = (straight(100.0), arc(ARC_RADIUS_M, 30.0), arc(ARC_RADIUS_M, 30.0), straight(100.0))
ARC_START_S, MID_ARC_S, ARC_END_S = piece_starts_s(MID_ARC_PIECES)[1:4]
VERTEX_SPACING_M = 2.0


def _netconvert(folder: Path, nodes: list[str], edges: list[str]) -> Path:
    """Netconvert plain XML nodes and edges into ``folder``."""
    return netconvert(
        "<nodes>\n" + "\n".join(nodes) + "\n</nodes>\n",
        "<edges>\n" + "\n".join(edges) + "\n</edges>\n",
        folder / "plain.net.xml",
    )


def _edge(edge_id: str, from_id: str, to_id: str, xy: np.ndarray, extra: str = "", spread: str = "center") -> str:
    """A one-lane plain XML edge; ``spread="right"`` for the two directions of a two-way road."""
    return (
        f'<edge id="{edge_id}" from="{from_id}" to="{to_id}" numLanes="1" speed="25.0" '
        f'spreadType="{spread}" shape="{shape_text(xy)}" {extra}/>'
    )


def _node(node_id: str, xy: np.ndarray) -> str:
    return f'<node id="{node_id}" x="{xy[0]:.3f}" y="{xy[1]:.3f}"/>'


@pytest.fixture(scope="module")
@marks_its_tests("sumo")
def arc_net(tmp_path_factory) -> Path:
    """A -> B -> C along MID_ARC_PIECES, with B in the middle of the arc.

    netconvert makes B a priority junction: it cuts both edges back by about 0.15 m
    and joins them with a straight internal lane ``:B_0_0`` of 0.3 m, so a vehicle
    drives AB_0 -> :B_0_0 -> BC_0 and the arc is cut twice.
    """
    xy, s = sample_pieces(MID_ARC_PIECES, VERTEX_SPACING_M)
    mid = int(np.flatnonzero(np.isclose(s, MID_ARC_S))[0])
    nodes = [_node("A", xy[0]), _node("B", xy[mid]), _node("C", xy[-1])]
    edges = [
        _edge("AB", "A", "B", xy[: mid + 1], 'name="Pass Road" type="rural"'),
        _edge("BC", "B", "C", xy[mid:], 'name="Pass Road" type="rural"'),
    ]
    return _netconvert(tmp_path_factory.mktemp("arc"), nodes, edges)


@pytest.fixture(scope="module")
def arc_map(arc_net: Path) -> RoadMap:
    return RoadMap.load(arc_net)


@pytest.fixture(scope="module")
@marks_its_tests("sumo")
def cross_map(tmp_path_factory) -> RoadMap:
    """Four straight 100 m arms meeting at junction J, one lane each way."""
    ends = {"N": (0.0, 100.0), "E": (100.0, 0.0), "S": (0.0, -100.0), "W": (-100.0, 0.0)}
    nodes = [_node("J", np.zeros(2))] + [_node(name, np.array(xy)) for name, xy in ends.items()]
    edges = []
    for name, xy in ends.items():
        line = np.array([xy, (0.0, 0.0)])
        edges.append(_edge(f"{name}J", name, "J", line, spread="right"))
        edges.append(_edge(f"J{name}", "J", name, line[::-1], spread="right"))
    return RoadMap.load(_netconvert(tmp_path_factory.mktemp("cross"), nodes, edges))


# ------------------------------------------------------------------ loading
def test_lanes_and_internal_lanes_are_loaded(arc_map: RoadMap) -> None:
    internal = [lane_id for lane_id in arc_map.lane_ids if arc_map.lane(lane_id).is_internal]
    assert {"AB_0", "BC_0"} <= set(arc_map.lane_ids)
    assert internal and all(lane_id.startswith(":B_") for lane_id in internal)


def test_lane_attributes_come_from_sumo(arc_map: RoadMap) -> None:
    lane = arc_map.lane("AB_0")
    assert (lane.edge_id, lane.index, lane.function) == ("AB", 0, "normal")
    assert (lane.street_name, lane.road_type) == ("Pass Road", "rural")
    assert lane.speed_limit_mps == pytest.approx(25.0)
    assert lane.length_m == pytest.approx(lane.shape_length_m, abs=0.01)
    assert {"truck", "bus", "passenger"} <= lane.allowed_vclasses
    assert arc_map.lane(arc_map.successors("AB_0")[0]).function == "internal"


def test_successor_chain_runs_through_the_internal_lane(arc_map: RoadMap) -> None:
    (via,) = arc_map.successors("AB_0")
    assert via.startswith(":B_")
    assert arc_map.successors(via) == ("BC_0",)
    assert arc_map.successors("BC_0") == ()
    assert arc_map.expand_path(["AB_0", "BC_0"]) == ("AB_0", via, "BC_0")


def test_junction_lanes_branch_and_fill_in_paths(cross_map: RoadMap) -> None:
    vias = cross_map.successors("WJ_0")
    assert len(vias) == 3  # left, straight, right; no turnaround
    assert {cross_map.successors(via)[-1] for via in vias} == {"JN_0", "JE_0", "JS_0"}
    path = cross_map.expand_path(["WJ_0", "JE_0"])
    assert path[0] == "WJ_0" and path[-1] == "JE_0" and all(cross_map.lane(i).is_internal for i in path[1:-1])
    with pytest.raises(ValueError, match="does not follow"):
        cross_map.expand_path(["WJ_0", "NJ_0"])
    with pytest.raises(KeyError, match="no lane"):
        cross_map.lane("nowhere_0")


def test_gzipped_network_loads_the_same(arc_net: Path, arc_map: RoadMap, tmp_path: Path) -> None:
    gz_path = tmp_path / "arc.net.xml.gz"
    gz_path.write_bytes(gzip.compress(arc_net.read_bytes()))
    assert RoadMap.load(gz_path).lane_ids == arc_map.lane_ids


# ------------------------------------------------------------------ curves
def test_path_profile_joins_a_curve_cut_by_a_junction(arc_map: RoadMap) -> None:
    path = arc_map.path_profile(["AB_0", "BC_0"])
    assert len(path.lane_ids) == 3
    (curve,) = path.curves()
    assert curve.start_s == pytest.approx(ARC_START_S, abs=1.0)
    assert curve.end_s == pytest.approx(ARC_END_S, abs=1.0)
    assert curve.direction == "left"
    assert curve.angle_deg == pytest.approx(60.0, abs=2.0)
    assert curve.min_radius_m == pytest.approx(ARC_RADIUS_M, rel=0.1)


def test_the_index_lists_a_curve_through_a_junction_once_as_the_path_sees_it(arc_map: RoadMap) -> None:
    # One road continues through B: its chain is fitted once, so the index has one curve
    # from AB_0 into BC_0, both lanes know it, and a path reads the same curve.
    (indexed,) = arc_map.curves()
    assert arc_map.lane_curves("AB_0") == arc_map.lane_curves("BC_0") == (indexed,)
    assert (indexed.lane_id, indexed.end_lane_id) == ("AB_0", "BC_0")
    assert indexed.start_pos_m == pytest.approx(ARC_START_S, abs=1.0)
    assert indexed.end_pos_m == pytest.approx(ARC_END_S - MID_ARC_S, abs=1.0)
    assert indexed.curve.angle_deg == pytest.approx(60.0, abs=2.0)
    (seen,) = arc_map.path_profile(["AB_0", "BC_0"]).curves()
    assert seen == indexed.curve
    assert arc_map.road_chain("BC_0")[0] == "AB_0"


def test_path_arc_length_maps_to_lane_positions_and_back(arc_map: RoadMap) -> None:
    path = arc_map.path_profile(["AB_0", "BC_0"])
    s = np.linspace(0.0, path.length_m, 97)
    lanes, positions = path.lane_positions(s)
    assert np.all(np.diff(lanes) >= 0) and lanes[0] == 0 and lanes[-1] == 2
    back = [path.path_s(path.lane_ids[lane], pos) for lane, pos in zip(lanes, positions, strict=False)]
    np.testing.assert_allclose(back, s, atol=1e-6)
    assert path.lane_position(1.0) == ("AB_0", pytest.approx(1.0, abs=1e-3))
    assert path.path_s("BC_0", 0.0) == pytest.approx(MID_ARC_S, abs=0.5)
    with pytest.raises(KeyError):
        path.path_s("nowhere_0", 0.0)


def test_write_curves_in_every_format(arc_map: RoadMap) -> None:
    count = len(arc_map.curves())
    outputs = {}
    for fmt in ("table", "json", "csv"):
        stream = io.StringIO()
        write_curves(arc_map, stream, fmt=fmt)
        outputs[fmt] = stream.getvalue()
    records = json.loads(outputs["json"])
    assert len(records) == count and tuple(records[0]) == CURVE_FIELDS
    rows = list(csv.DictReader(io.StringIO(outputs["csv"])))
    assert [row["lane_id"] for row in rows] == [record["lane_id"] for record in records]
    table = outputs["table"].splitlines()
    assert table[0].split() == list(CURVE_FIELDS) and len(table) == count + 1
    with pytest.raises(ValueError, match="unknown curve format"):
        write_curves(arc_map, io.StringIO(), fmt="xml")


def test_warning_radius_selects_the_curves(arc_net: Path) -> None:
    assert RoadMap.load(arc_net, warning_radius_m=150.0).curves() == []


# ------------------------------------------------------------------ positions
def _offset_points(s: np.ndarray, left_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Points ``left_m`` to the left of the constructed road at arc lengths ``s``, and the headings there."""
    x, y, heading = pose_at(MID_ARC_PIECES, s)
    return np.column_stack((x - left_m * np.sin(heading), y + left_m * np.cos(heading))), heading


def test_nearest_lane_projects_onto_the_constructed_arc_length(arc_map: RoadMap) -> None:
    path = arc_map.path_profile(["AB_0", "BC_0"])
    s = np.array([20.0, ARC_START_S + 30.0, MID_ARC_S - 5.0, MID_ARC_S + 5.0, ARC_END_S - 10.0, ARC_END_S + 50.0])
    points, heading = _offset_points(s, 1.5)
    for point, true_s, true_heading in zip(points, s, heading, strict=False):
        match = arc_map.nearest_lanes(*point, radius_m=3.0)[0]
        assert match.distance_m == pytest.approx(1.5, abs=0.03)
        assert path.path_s(match.lane_id, match.lane_pos_m) == pytest.approx(true_s, abs=0.05)
        assert match.heading_rad == pytest.approx(true_heading, abs=0.01)


def test_batch_matching_agrees_with_single_look_ups(arc_map: RoadMap) -> None:
    s = np.linspace(0.0, ARC_END_S + 90.0, 400)
    points, _ = _offset_points(s, -0.8)
    points = np.vstack((points, [[5000.0, 5000.0]]))  # far from every lane: no row
    matches = arc_map.match_points(points, radius_m=2.0)
    assert set(matches.point_index) == set(range(len(s)))
    for index in (0, 133, 399):
        assert matches.for_point(index) == arc_map.nearest_lanes(*points[index], radius_m=2.0)
    assert arc_map.nearest_lanes(5000.0, 5000.0, radius_m=2.0) == []
    with pytest.raises(ValueError, match="radius"):
        arc_map.nearest_lanes(0.0, 0.0, radius_m=0.0)


def test_network_without_projection_says_so(arc_map: RoadMap) -> None:
    assert arc_map.has_projection is False
    with pytest.raises(ValueError, match="geo-projection"):
        arc_map.xy_to_lonlat(0.0, 0.0)


def test_projection_flag_follows_the_location(arc_net: Path, tmp_path: Path) -> None:
    utm = "+proj=utm +zone=50 +ellps=WGS84 +datum=WGS84 +units=m +no_defs"
    text = arc_net.read_text().replace('projParameter="!"', f'projParameter="{utm}"')
    (tmp_path / "utm.net.xml").write_text(text)
    road_map = RoadMap.load(tmp_path / "utm.net.xml")
    assert road_map.has_projection is True
    assert road_map.geo.hasGeoProj()


# ------------------------------------------------------------------ errors
@pytest.mark.parametrize(
    ("content", "message"),
    [
        (None, "does not exist"),
        (b"", "not a readable SUMO network"),
        (bytes(np.random.default_rng(7).integers(0, 256, 4096, dtype=np.uint8)), "not a readable SUMO network"),
        (b'<?xml version="1.0"?>\n<routes><vehicle id="v" depart="0"/></routes>\n', "not a SUMO network"),
        (b'<?xml version="1.0"?>\n<net version="1.20"></net>\n', "empty SUMO network"),
        (gzip.compress(b"<net version='1.20'><edge id='e'>")[:20], "not a readable SUMO network"),
    ],
    ids=["missing", "empty-file", "garbage", "routes-xml", "no-edges", "truncated-gzip"],
)
def test_unusable_files_raise_one_line_network_errors(tmp_path: Path, content: bytes | None, message: str) -> None:
    path = tmp_path / "bad.net.xml"
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(NetworkError, match=message) as caught:
        RoadMap.load(path)
    assert isinstance(caught.value, ValueError)
    assert "\n" not in str(caught.value)


def test_curves_command_reports_a_bad_network_in_one_line(tmp_path: Path, capsys) -> None:
    from csws.cli import EXIT_BAD_INPUT, main

    (tmp_path / "bad.net.xml").write_bytes(b"\x00\xff not xml")
    assert main(["curves", str(tmp_path / "bad.net.xml")]) == EXIT_BAD_INPUT
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
