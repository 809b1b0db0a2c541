"""The map report against networks and OSM extracts with faults put in by the test, at places it knows.

* hand-written SUMO networks, geo-referenced in UTM 32N: a straight way (both directions) with a
  0.1 m spike at a known place, which netconvert would clean away; spikes of any length at any place
  on straights of any heading; a right angle drawn by two nodes a metre apart;
* an OSM extract written by the test and imported: a spike, a corner drawn by a single node, a way
  cut by the extract's border and one left out of the network; its report served by ``GET /v1/report``
  and drawn on the live map in a real browser.

Positions are checked in lon/lat against pyproj's own projection of the places the faults were put.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pyproj
import pytest
from browsers import WAIT_MS, Recorded
from builders import TRACK_NET
from fastapi.testclient import TestClient
from hypothesis import given, settings
from hypothesis import strategies as st
from markers import marks_its_tests
from osm_builders import ORIGIN_XY, UTM32, OsmWriter
from servers import Workers

from csws import cli
from csws.curvature import artefacts
from csws.curvature.artefacts import CORNER_MIN_DEG
from csws.curvature.corners import ANGLE_TOLERANCE_DEG
from csws.osm.coverage import CUT_BY_BORDER, NOT_IN_NETWORK
from csws.osm.importer import COMMERCIAL_VCLASSES, ImportResult, ImportSettings, import_osm
from csws.osm.report import (
    BORDER_CUT,
    DROPPED,
    FLOOR_CURVE,
    KINDS,
    SINGLE_NODE_CORNER,
    SINGLE_NODE_CORNER_DEG,
    network_items,
    summary_lines,
)
from csws.road.roadmap import RoadMap
from service.app import create_app
from service.settings import ServiceSettings

#: The OSM way of the hand-written network's edges, as netconvert names edges after ways.
WAY_ID = 25805442
#: The spike: the road runs east to x = SPIKE_X_M, back west SPIKE_M, then east again.
SPIKE_X_M = 100.0
SPIKE_M = 0.1
#: The hand-written network lies this far from the UTM origin, m (network (0, 0) is ORIGIN_XY).
GEODESY = pyproj.Geod(ellps="WGS84")
#: An item is where the test put its fault within this, m.
PLACE_TOLERANCE_M = 0.5


def _distance_m(lonlat: np.ndarray, xy: tuple[float, float]) -> float:
    """Geodesic distance between a lon/lat and the place ``xy`` (m from the test's origin)."""
    lon, lat = UTM32(ORIGIN_XY[0] + xy[0], ORIGIN_XY[1] + xy[1], inverse=True)
    return float(GEODESY.inv(lonlat[0], lonlat[1], lon, lat)[2])


def _shape(xy: np.ndarray) -> str:
    return " ".join(f"{x:.2f},{y:.2f}" for x, y in xy)


def _hand_written_net(path: Path, lanes: list[tuple[str, str, str, np.ndarray]], projection: bool = True) -> Path:
    """A SUMO network of one-lane edges ``(edge id, from node, to node, lane shape)`` between dead ends, written
    without netconvert (which would clean a back-and-forth of 0.1 m away); with ``projection``, network (0, 0)
    lies at the test's origin in UTM 32N."""
    edges = "".join(
        f'<edge id="{edge}" from="{start}" to="{end}" priority="1"><lane id="{edge}_0" index="0" speed="13.89" '
        f'length="{np.hypot(*np.diff(xy, axis=0).T).sum():.2f}" shape="{_shape(xy)}"/></edge>'
        for edge, start, end, xy in lanes
    )
    ends = {start: xy[0] for _, start, _, xy in lanes} | {end: xy[-1] for _, _, end, xy in lanes}
    incoming = {node: " ".join(f"{edge}_0" for edge, _, end, _ in lanes if end == node) for node in ends}
    junctions = "".join(
        f'<junction id="{node}" type="dead_end" x="{x:.2f}" y="{y:.2f}" incLanes="{incoming[node]}" intLanes="" '
        'shape=""/>'
        for node, (x, y) in ends.items()
    )
    offset = f"{-ORIGIN_XY[0]:.2f},{-ORIGIN_XY[1]:.2f}" if projection else "0.00,0.00"
    everything = np.concatenate([xy for _, _, _, xy in lanes])
    low, high = everything.min(axis=0), everything.max(axis=0)
    path.write_text(
        '<?xml version="1.0" encoding="UTF-8"?>\n<net version="1.20">\n'
        f'<location netOffset="{offset}" convBoundary="{low[0]:.2f},{low[1]:.2f},{high[0]:.2f},{high[1]:.2f}" '
        f'origBoundary="0,0,1,1" projParameter="{UTM32.srs if projection else "!"}"/>\n{edges}\n{junctions}\n</net>\n'
    )
    return path


def _spiked_net(folder: Path, projection: bool = True) -> Path:
    """A two-way straight of 200 m, lanes 3.2 m apart, each with the 0.1 m back-and-forth at SPIKE_X_M."""
    east = np.array([[0.0, -1.6], [50.0, -1.6], [SPIKE_X_M, -1.6], [SPIKE_X_M - SPIKE_M, -1.6], [200.0, -1.6]])
    west = np.array([[200.0, 1.6], [SPIKE_X_M - SPIKE_M, 1.6], [SPIKE_X_M, 1.6], [50.0, 1.6], [0.0, 1.6]])
    lanes = [(str(WAY_ID), "A", "B", east), (f"-{WAY_ID}", "B", "A", west)]
    return _hand_written_net(folder / "spiked.net.xml", lanes, projection)


def test_a_tenth_of_a_metre_spike_on_a_straight_gives_no_curve_and_one_artefact_where_it_is(tmp_path: Path) -> None:
    road_map = RoadMap.load(_spiked_net(tmp_path), cache=False)
    assert road_map.curves() == []
    items = network_items(road_map)
    assert [item.kind for item in items] == ["artefact-spike"]  # both directions and the lanes: one item
    (spike,) = items
    assert spike.way_id == WAY_ID and spike.edge_id in (str(WAY_ID), f"-{WAY_ID}")
    assert spike.size == pytest.approx(SPIKE_M, abs=0.01) and spike.unit == "m"
    # Between the two reversals, on the lane of its direction (1.6 m off the axis).
    assert len(spike.points) == 1
    assert _distance_m(spike.points[0], (SPIKE_X_M - SPIKE_M / 2, 0.0)) <= 1.6 + PLACE_TOLERANCE_M


@settings(max_examples=15, deadline=None)
@given(
    # Up to the spike's limit less the shape's centimetre rounding, which may lengthen the written segment.
    spike_m=st.floats(0.02, artefacts.SPIKE_M - 0.02),
    spike_at_m=st.floats(20.0, 180.0),
    heading_deg=st.floats(-180.0, 180.0),
)
def test_any_spike_on_any_straight_is_one_artefact_of_its_length_where_it_is(
    tmp_path_factory, spike_m: float, spike_at_m: float, heading_deg: float
) -> None:
    # A one-way straight of 200 m from the origin at heading_deg, running back spike_m at spike_at_m.
    along = np.array([0.0, spike_at_m, spike_at_m - spike_m, 200.0])
    direction = np.array([math.cos(math.radians(heading_deg)), math.sin(math.radians(heading_deg))])
    shape = along[:, None] * direction
    net = _hand_written_net(tmp_path_factory.mktemp("spike") / "s.net.xml", [(f"{WAY_ID}#2", "A", "B", shape)])
    road_map = RoadMap.load(net, cache=False)
    assert road_map.curves() == []
    (spike,) = network_items(road_map)
    assert spike.kind == "artefact-spike" and spike.way_id == WAY_ID and spike.edge_id == f"{WAY_ID}#2"
    assert spike.size == pytest.approx(spike_m, abs=0.02)  # the shape is written to the centimetre
    middle = (spike_at_m - spike_m / 2) * direction
    assert _distance_m(spike.points[0], (float(middle[0]), float(middle[1]))) <= 0.05


# ------------------------------------------------------------------ an imported extract
#: Where the imported main road turns by a right angle at a single node, m from the origin.
CORNER_XY = (300.0, 0.0)
#: The spike of the imported road: 0.5 m (netconvert cleans away shorter back-and-forths within 0.1 m).
IMPORT_SPIKE_M = 0.5


def _every_10_m(start: tuple[float, float], end: tuple[float, float]) -> list[np.ndarray]:
    """Points every 10 m from ``start`` up to, not including, ``end``."""
    a, b = np.array(start), np.array(end)
    count = int(round(math.dist(start, end) / 10.0))
    return [a + (b - a) * i / count for i in range(count)]


def _faulty_extract(folder: Path) -> tuple[Path, OsmWriter]:
    """Way 1: a one-lane road east with a spike at x = 100 m, a right-angle corner at one node (CORNER_XY), then
    north; way 2: a side road cut by the extract's border; way 3: a road elsewhere, not connected."""
    osm = OsmWriter()
    main = [
        *_every_10_m((0.0, 0.0), (SPIKE_X_M, 0.0)),
        np.array([SPIKE_X_M, 0.0]),
        np.array([SPIKE_X_M - IMPORT_SPIKE_M, 0.0]),
        *_every_10_m((SPIKE_X_M + 10.0, 0.0), CORNER_XY),
        *_every_10_m(CORNER_XY, (300.0, 200.0)),
        np.array([300.0, 200.0]),
    ]
    osm.way(np.array(main), "primary", oneway="yes", lanes="1", name="Main")
    cut = osm.way(np.array([[150.0, 0.0], [150.0, -100.0], [150.0, -200.0]]), "tertiary")
    osm.way(np.array([[0.0, 5000.0], [200.0, 5000.0]]), "secondary")
    path = folder / "faulty.osm"
    path.write_text(osm.text().replace(f'<nd ref="{cut[-1]}"/>', '<nd ref="999999"/>'))
    return path, osm


@pytest.fixture(scope="module")
@marks_its_tests("sumo")
def faulty_import(tmp_path_factory) -> ImportResult:
    folder = tmp_path_factory.mktemp("faulty")
    osm_path, _ = _faulty_extract(folder)
    return import_osm(osm_path, folder / "faulty.net.xml.gz", ImportSettings(keep_vclasses=COMMERCIAL_VCLASSES))


def _features(result: ImportResult) -> list[dict]:
    return json.loads(result.report_path.read_text())["features"]


@pytest.mark.sumo
def test_the_import_reports_each_fault_of_the_extract_once_at_its_place(faulty_import: ImportResult) -> None:
    by_kind: dict[str, list] = {}
    for item in faulty_import.report:
        by_kind.setdefault(item.kind, []).append(item)
    assert sorted(kind for kind in by_kind if kind != FLOOR_CURVE) == sorted(
        ["artefact-spike", SINGLE_NODE_CORNER, BORDER_CUT, DROPPED]
    )
    assert all(len(items) == 1 for kind, items in by_kind.items() if kind != FLOOR_CURVE)
    (spike,) = by_kind["artefact-spike"]
    assert spike.way_id == 1 and spike.size == pytest.approx(IMPORT_SPIKE_M, abs=0.01)
    assert _distance_m(spike.points[0], (SPIKE_X_M - IMPORT_SPIKE_M / 2, 0.0)) <= PLACE_TOLERANCE_M
    (corner,) = by_kind[SINGLE_NODE_CORNER]
    assert corner.way_id == 1 and corner.size == pytest.approx(90.0, abs=0.1) and corner.size >= SINGLE_NODE_CORNER_DEG
    assert _distance_m(corner.points[0], CORNER_XY) <= PLACE_TOLERANCE_M
    # The road really turns there: any curve at the floor is a real corner (90 deg >= CORNER_MIN_DEG at one node).
    assert 90.0 >= CORNER_MIN_DEG and all(item.real_corner for item in by_kind.get(FLOOR_CURVE, []))
    (cut,) = by_kind[BORDER_CUT]
    assert cut.way_id == 2 and CUT_BY_BORDER in cut.reason and len(cut.points) == 2  # its third node is missing
    assert _distance_m(cut.points[0], (150.0, 0.0)) <= PLACE_TOLERANCE_M
    (dropped,) = by_kind[DROPPED]
    assert dropped.way_id == 3 and NOT_IN_NETWORK in dropped.reason
    assert dropped.size == pytest.approx(200.0, rel=0.01)


@pytest.mark.sumo
def test_the_report_is_geojson_in_lonlat_naming_the_ways_of_its_edges(faulty_import: ImportResult) -> None:
    document = json.loads(faulty_import.report_path.read_text())
    assert document["type"] == "FeatureCollection" and document["coordinates"] == "lon/lat (WGS84)"
    assert faulty_import.report_path.name == "faulty.report.geojson"
    features = document["features"]
    assert len(features) == len(faulty_import.report) and len({f["id"] for f in features}) == len(features)
    origin = np.array(UTM32(*ORIGIN_XY, inverse=True))
    for feature in features:
        assert feature["type"] == "Feature"
        geometry = feature["geometry"]
        points = np.array([geometry["coordinates"]] if geometry["type"] == "Point" else geometry["coordinates"])
        assert points.shape[1] == 2 and len(points) == 1 if geometry["type"] == "Point" else len(points) >= 2
        assert geometry["type"] in ("Point", "LineString")
        assert np.all(np.abs(points[:, 0]) <= 180.0) and np.all(np.abs(points[:, 1]) <= 90.0)
        # [lon, lat] order: within a few km of the origin's lon/lat, not its lat/lon.
        assert np.all(np.abs(points - origin) < 0.1)
        properties = feature["properties"]
        assert {"kind", "way_id", "edge_id", "lane_id", "size", "unit", "reason"} <= properties.keys()
        assert properties["kind"] in KINDS and properties["reason"]
        edge = properties["edge_id"]
        if edge:
            assert properties["way_id"] == int(edge.lstrip("-").split("#")[0])
            assert properties["lane_id"].startswith(edge + "_")
    counted = {kind: sum(f["properties"]["kind"] == kind for f in features) for kind in KINDS}
    assert document["summary"] == {kind: count for kind, count in counted.items() if count}


@pytest.mark.sumo
def test_map_report_on_the_imported_network_finds_what_the_import_found_in_it(
    faulty_import: ImportResult, tmp_path: Path, capsys
) -> None:
    output = tmp_path / "again.geojson"
    assert cli.main(["map-report", str(faulty_import.net_path), "-o", str(output)]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert [line.split()[2] for line in printed[: len(KINDS)]] == list(KINDS)
    again = json.loads(output.read_text())["features"]
    from_network = [f for f in _features(faulty_import) if f["properties"]["kind"] not in (BORDER_CUT, DROPPED)]
    assert again == from_network
    assert printed[-1] == f"wrote {output}: {len(again)} item(s)"


@pytest.mark.sumo
def test_import_osm_prints_the_report_summary_a_line_per_kind(tmp_path: Path, capsys) -> None:
    osm_path, _ = _faulty_extract(tmp_path)
    net = tmp_path / "printed.net.xml"
    assert cli.main(["import-osm", str(osm_path), "-o", str(net), "--vclasses", "truck,bus,coach"]) == 0
    printed = capsys.readouterr().out.splitlines()
    summary = [line for line in printed if line.startswith("map report: ")]
    assert [line.split()[2] for line in summary] == list(KINDS)
    assert any(line.startswith(f"map report: {SINGLE_NODE_CORNER}") and line.split()[3] == "1" for line in summary)
    assert (tmp_path / "printed.report.geojson").is_file()


def test_a_right_angle_drawn_by_two_nodes_a_metre_apart_is_a_real_corner_at_the_floor(tmp_path: Path) -> None:
    # East 100 m, two nodes 1 m apart turning 45 degrees each, north 100 m: the road turns 90 degrees net there.
    step = 1.0 / math.sqrt(2.0)
    shape = np.array([[0.0, 0.0], [50.0, 0.0], [100.0, 0.0], [100.0 + step, step], [100.0 + step, 100.0]])
    road_map = RoadMap.load(_hand_written_net(tmp_path / "bend.net.xml", [("7", "A", "B", shape)]), cache=False)
    items = network_items(road_map)
    # Each node turns 45 degrees next to a 1 m segment, no heading of its own: no single-node corner, no artefact.
    (floor,) = items
    assert floor.kind == FLOOR_CURVE and floor.real_corner and floor.way_id == 7
    assert floor.size == pytest.approx(90.0, abs=ANGLE_TOLERANCE_DEG)


def test_summary_lines_count_the_items_of_each_kind(tmp_path: Path) -> None:
    items = network_items(RoadMap.load(_spiked_net(tmp_path), cache=False))
    lines = summary_lines(items)
    assert len(lines) == len(KINDS)
    assert lines[0].split()[2:5] == ["artefact-spike", "1", "(largest"]
    assert all(line.split()[3] == "0" for line in lines[1:])


@pytest.mark.parametrize(
    ("name", "content", "message"),
    [
        ("missing.net.xml", None, "missing.net.xml"),
        ("garbage.net.xml", b"this is no network", "garbage.net.xml"),
    ],
)
def test_map_report_of_a_missing_or_unreadable_network_is_one_error_line(
    tmp_path: Path, capsys, name: str, content: bytes | None, message: str
) -> None:
    source = tmp_path / name
    if content is not None:
        source.write_bytes(content)
    assert cli.main(["map-report", str(source)]) == cli.EXIT_BAD_INPUT
    captured = capsys.readouterr()
    assert captured.err.startswith("csws: error:") and message in captured.err and captured.err.count("\n") == 1
    assert not list(tmp_path.glob("*.report.geojson"))


def test_map_report_of_a_network_without_projection_is_in_network_metres(tmp_path: Path) -> None:
    road_map = RoadMap.load(_spiked_net(tmp_path, projection=False), cache=False)
    assert not road_map.has_projection
    (spike,) = network_items(road_map)
    x, y = spike.points[0]
    assert x == pytest.approx(SPIKE_X_M - SPIKE_M / 2, abs=0.01) and abs(y) == pytest.approx(1.6, abs=0.01)


# ------------------------------------------------------------------ the report on the live map
@pytest.mark.sumo
def test_the_service_serves_the_report_of_a_network_that_has_one(faulty_import: ImportResult) -> None:
    served = ServiceSettings(nets=[faulty_import.net_path, TRACK_NET], state_db=":memory:")
    with TestClient(create_app(served)) as client:
        answer = client.get("/v1/report", params={"network": "faulty"})
        assert answer.status_code == 200 and answer.headers["content-type"] == "application/geo+json"
        assert answer.json() == json.loads(faulty_import.report_path.read_text())
        missing = client.get("/v1/report", params={"network": TRACK_NET.name.removesuffix(".net.xml")})
        assert missing.status_code == 404 and "csws map-report" in missing.json()["detail"]
        assert client.get("/v1/report", params={"network": "elsewhere"}).status_code == 422
        page = client.get("/map").text
        names = json.loads(page.split('type="application/json">', 1)[1].split("</script>", 1)[0])
        assert {n["name"]: n["report"] for n in names} == {"faulty": True, "t7_left": False}


@pytest.fixture(scope="module")
@marks_its_tests("slow")
def report_server(faulty_import: ImportResult, tmp_path_factory):
    running = Workers([faulty_import.net_path], "--state-db", str(tmp_path_factory.mktemp("state") / "s.db"), workers=1)
    yield running
    running.stop()


def test_the_map_shows_the_report_as_a_layer_when_ticked(browser, report_server, faulty_import) -> None:
    recorded = Recorded(browser)
    page = recorded.page
    page.goto(f"{report_server.url}/map?network=faulty")
    page.wait_for_function("() => document.body.dataset.ready === 'true'", timeout=WAIT_MS)
    page.wait_for_function("() => document.body.dataset.reportFeatures !== undefined", timeout=WAIT_MS)
    features = json.loads(faulty_import.report_path.read_text())["features"]
    assert page.evaluate("document.body.dataset.reportFeatures") == str(len(features))
    assert not page.evaluate("cswsMap.map.hasLayer(cswsMap.report)")  # off until ticked
    page.get_by_text(f"map report: {len(features)} item(s)").click()
    assert page.evaluate("cswsMap.map.hasLayer(cswsMap.report)")
    drawn = page.evaluate("cswsMap.report.getLayers().map(layer => layer.feature.properties.kind).sort()")
    assert drawn == sorted(feature["properties"]["kind"] for feature in features)
    recorded.assert_offline()
