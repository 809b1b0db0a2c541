"""OSM import against OSM files the tests write themselves, with known curves and junctions.

The roads are built exactly with csws.geometry in UTM zone 32 metres, turned into lon/lat
with pyproj, and written as OSM nodes and ways. netconvert projects them back to UTM,
so the imported lanes must show the constructed curve, and lon/lat must come back where
the nodes were put.
"""

from __future__ import annotations

import gzip
import json
import math
import subprocess
from pathlib import Path

import numpy as np
import pyproj
import pytest
import sumolib
from markers import marks_its_tests
from osm_builders import ORIGIN_LONLAT, ORIGIN_XY, UTM32, OsmWriter

from csws import cli
from csws.ahead.lookahead import LookAhead, LookAheadSettings
from csws.geometry import arc, piece_starts_s, sample_pieces, straight
from csws.networks import networks_dir
from csws.osm.coverage import CLOSED_TYPE, CUT_BY_BORDER, NOT_IN_NETWORK
from csws.osm.importer import (
    COMMERCIAL_VCLASSES,
    FLEET_VCLASSES,
    ImportResult,
    ImportSettings,
    OsmImportError,
    import_osm,
)
from csws.road.export import curves_geojson
from csws.road.roadmap import RoadMap
from csws.standard import DEFAULT_POLICY
from csws.sumo.binaries import sumo_binary, sumo_home

#: The curve: 200 m straight, a 90 degree left arc of R = 100 m, 200 m straight; OSM nodes every 10 m.
ARC_RADIUS_M = 100.0
ARC_PIECES = (straight(200.0), arc(ARC_RADIUS_M, 90.0, "left"), straight(200.0))
ARC_START_S, ARC_END_S = piece_starts_s(ARC_PIECES)[1:3]
NODE_SPACING_M = 10.0


def _arc_xy() -> np.ndarray:
    xy, _ = sample_pieces(ARC_PIECES, NODE_SPACING_M, (0.0, 0.0), 0.3)
    return xy


def _arc_osm(folder: Path, side_road: bool) -> tuple[Path, OsmWriter]:
    """One-way secondary road along ARC_PIECES; with ``side_road``, a road meets it in the middle of the arc."""
    osm = OsmWriter()
    xy = _arc_xy()
    osm.way(xy, "secondary", oneway="yes", name="Pass Road")
    if side_road:
        middle = xy[len(xy) // 2]
        osm.way(np.array([middle, middle + (150.0, -150.0)]), "residential", name="Side Road")
    path = folder / "arc.osm"
    path.write_text(osm.text())
    return path, osm


@pytest.fixture(scope="module")
def arc_osm(tmp_path_factory) -> tuple[Path, OsmWriter]:
    return _arc_osm(tmp_path_factory.mktemp("arc"), side_road=False)


@pytest.fixture(scope="module")
@marks_its_tests("sumo")
def arc_import(arc_osm, tmp_path_factory) -> ImportResult:
    return import_osm(arc_osm[0], tmp_path_factory.mktemp("arcnet") / "arc.net.xml.gz")


@pytest.fixture(scope="module")
def arc_map(arc_import) -> RoadMap:
    return RoadMap.load(arc_import.net_path)


@pytest.fixture(scope="module")
@marks_its_tests("sumo")
def side_road_map(tmp_path_factory) -> RoadMap:
    folder = tmp_path_factory.mktemp("side")
    osm_path, _ = _arc_osm(folder, side_road=True)
    return RoadMap.load(import_osm(osm_path, folder / "side.net.xml").net_path)


def _main_lanes(road_map: RoadMap, street: str) -> list[str]:
    return [i for i in road_map.lane_ids if road_map.lane(i).street_name == street and not road_map.lane(i).is_internal]


# ------------------------------------------------------------------ the constructed curve
def test_the_curve_found_on_the_import_is_the_constructed_one(arc_map: RoadMap) -> None:
    (lane,) = _main_lanes(arc_map, "Pass Road")
    path = arc_map.path_profile([lane])
    curves = [curve for curve in path.road_curves() if curve.angle_deg > 5.0]
    assert len(curves) == 1
    curve = curves[0]
    assert curve.direction == "left"
    assert curve.min_radius_m == pytest.approx(ARC_RADIUS_M, rel=0.02)
    assert curve.angle_deg == pytest.approx(90.0, abs=2.0)
    # the road starts at the first node, so path arc length is the constructed arc length
    assert curve.start_s == pytest.approx(ARC_START_S, abs=2.0)
    assert curve.end_s == pytest.approx(ARC_END_S, abs=2.0)


def test_lonlat_round_trips_through_the_imported_network(arc_osm, arc_map: RoadMap) -> None:
    _, osm = arc_osm
    assert arc_map.has_projection
    lonlat = np.array([osm.lonlat(node_id) for node_id in osm.nodes])
    xy = arc_map.lonlat_to_xy_many(lonlat)
    # every node lies on a lane of the network (one-way single lanes run along the way)
    distances = [arc_map.nearest_lanes(x, y, radius_m=5.0)[0].distance_m for x, y in xy]
    assert max(distances) < 0.02
    back = arc_map.xy_to_lonlat_many(xy)
    geod = pyproj.Geod(ellps="WGS84")
    _, _, error_m = geod.inv(lonlat[:, 0], lonlat[:, 1], back[:, 0], back[:, 1])
    assert np.max(np.abs(error_m)) < 1e-6
    # the single-point variants agree with the vectorised ones
    assert arc_map.xy_to_lonlat(*xy[3]) == pytest.approx(tuple(lonlat[3]), abs=1e-9)
    assert arc_map.lonlat_to_xy(*lonlat[3]) == pytest.approx(tuple(xy[3]), abs=1e-6)


def test_network_distances_are_geodesic_distances(arc_map: RoadMap) -> None:
    shape = np.concatenate([arc_map.lane_shape(lane) for lane in _main_lanes(arc_map, "Pass Road")])
    lonlat = arc_map.xy_to_lonlat_many(shape[[0, -1]])
    _, _, geodesic_m = pyproj.Geod(ellps="WGS84").inv(*lonlat[0], *lonlat[1])
    # UTM distorts distances by its scale factor, at most 0.04 % near the central meridian
    assert np.hypot(*(shape[-1] - shape[0])) == pytest.approx(geodesic_m, rel=5e-4)


def test_bad_lonlat_is_rejected(arc_map: RoadMap) -> None:
    with pytest.raises(ValueError, match="out of range"):
        arc_map.lonlat_to_xy(200.0, 50.0)
    with pytest.raises(ValueError, match="finite"):
        arc_map.lonlat_to_xy(float("nan"), 50.0)


def test_curve_index_is_geojson_in_wgs84(arc_map: RoadMap, arc_osm) -> None:
    collection = curves_geojson(arc_map)
    biggest = max(collection["features"], key=lambda f: f["properties"]["angle_deg"])
    assert biggest["properties"]["radius_m"] == pytest.approx(ARC_RADIUS_M, rel=0.02)
    assert biggest["properties"]["street_name"] == "Pass Road"
    lon, lat = np.array(biggest["geometry"]["coordinates"]).T
    # the curve lies within the constructed arc's lon/lat extent (a few hundred metres east/north of the origin)
    assert np.all((lon > ORIGIN_LONLAT[0]) & (lon < ORIGIN_LONLAT[0] + 0.01))
    assert np.all((lat > ORIGIN_LONLAT[1]) & (lat < ORIGIN_LONLAT[1] + 0.01))


def test_the_import_and_the_service_give_a_curve_the_same_properties(arc_import: ImportResult) -> None:
    from fastapi.testclient import TestClient

    from service.app import create_app
    from service.settings import ServiceSettings

    written = json.loads(arc_import.curves_path.read_text())
    with TestClient(create_app(ServiceSettings(nets=[arc_import.net_path], state_db=":memory:"))) as client:
        served = client.get("/v1/curves").json()
    assert written["coordinates"] == served["coordinates"] == "lon/lat (WGS84)"
    by_id = {feature["properties"]["curve_id"]: feature for feature in served["features"]}
    assert written["features"] and len(written["features"]) == len(by_id)
    for feature in written["features"]:
        twin = by_id[feature["properties"]["curve_id"]]
        assert twin["properties"] == {"network": twin["properties"]["network"], **feature["properties"]}
        assert (twin["geometry"], twin["bbox"]) == (feature["geometry"], feature["bbox"])
        assert twin["id"] == f"{twin['properties']['network']}/{feature['id']}"


# ------------------------------------------------------------------ junctions and roundabouts
def _with_nodes_every(corners: list, spacing_m: float) -> np.ndarray:
    """A straight-segment polyline through ``corners`` with a node every ``spacing_m`` or closer."""
    corners = np.asarray(corners, dtype=float)
    pieces = [
        a + np.linspace(0.0, 1.0, max(2, math.ceil(np.hypot(*(b - a)) / spacing_m) + 1))[:-1, None] * (b - a)
        for a, b in zip(corners[:-1], corners[1:], strict=False)
    ]
    return np.concatenate(pieces + [corners[-1:]])


@pytest.fixture(scope="module")
@marks_its_tests("sumo")
def junction_net(tmp_path_factory) -> Path:
    """A straight road W-E with a T-junction side road going south at x = 0 and a roundabout
    of R = 25 m at x = 600 with an exit road going east; nodes every 10 m, as mapped roads
    often have (a 300 m way of two nodes leaves the extractor too little to see a 9 m turn)."""
    osm = OsmWriter()
    ring_centre = np.array([600.0, 0.0])
    ring_radius_m = 25.0
    main_road = [[-300.0, 0.0], [0.0, 0.0], [300.0, 0.0], [ring_centre[0] - ring_radius_m, 0.0]]
    osm.way(_with_nodes_every(main_road, NODE_SPACING_M), "secondary", name="Main")
    osm.way(_with_nodes_every([[0.0, 0.0], [0.0, -300.0]], NODE_SPACING_M), "secondary", name="South")
    angles = np.radians(np.arange(180.0, 180.0 + 360.0 + 1e-9, 15.0))  # counter-clockwise, right-hand traffic
    ring = ring_centre + ring_radius_m * np.column_stack((np.cos(angles), np.sin(angles)))
    ring[-1] = ring[0]
    osm.way(ring, "secondary", junction="roundabout", name="Ring")
    east_road = [ring_centre + (ring_radius_m, 0.0), ring_centre + (400.0, 0.0)]
    osm.way(_with_nodes_every(east_road, NODE_SPACING_M), "secondary", name="East")
    folder = tmp_path_factory.mktemp("junction")
    (folder / "junction.osm").write_text(osm.text())
    return import_osm(folder / "junction.osm", folder / "junction.net.xml").net_path


@pytest.fixture(scope="module")
def junction_map(junction_net: Path) -> RoadMap:
    return RoadMap.load(junction_net)


def _route(net_path: Path, road_map: RoadMap, from_lane: str, to_lane: str) -> list[str]:
    """The shortest route (edge ids) between the edges of two lanes, by sumolib."""
    net = sumolib.net.readNet(str(net_path))
    edges, _ = net.getShortestPath(
        net.getEdge(road_map.lane(from_lane).edge_id), net.getEdge(road_map.lane(to_lane).edge_id)
    )
    return [edge.getID() for edge in edges]


def _lane_heading_to(road_map: RoadMap, xy: tuple[float, float], heading_deg: float) -> str:
    """The lane at local ``xy`` (m from the origin) driven towards ``heading_deg``."""
    x, y = road_map.lonlat_to_xy(*UTM32(ORIGIN_XY[0] + xy[0], ORIGIN_XY[1] + xy[1], inverse=True))
    for match in road_map.nearest_lanes(x, y, radius_m=10.0):
        if abs(math.remainder(math.degrees(match.heading_rad) - heading_deg, 360.0)) < 30.0:
            return match.lane_id
    raise AssertionError(f"no lane heading {heading_deg} deg at {xy}")


def _cpoi_radii(road_map: RoadMap, lane_id: str, route: list[str], warn_at_junctions: bool) -> list[float]:
    lookahead = LookAhead(road_map, LookAheadSettings(fixed_distance_m=600.0, warn_at_junctions=warn_at_junctions))
    ahead = lookahead(lane_id, 0.0, 60.0, "N", route)
    return ahead.cpoi_radius_m.tolist()


def test_a_turn_inside_a_junction_offers_no_cpoi(junction_net: Path, junction_map: RoadMap) -> None:
    start = _lane_heading_to(junction_map, (-250.0, 0.0), 0.0)
    south = _lane_heading_to(junction_map, (0.0, -150.0), -90.0)
    route = _route(junction_net, junction_map, start, south)
    assert len(route) == 2
    turn_radii = _cpoi_radii(junction_map, start, route, warn_at_junctions=True)
    assert turn_radii and min(turn_radii) < 30.0  # the right turn is there, and sharp
    assert _cpoi_radii(junction_map, start, route, warn_at_junctions=False) == []


def test_roundabouts_are_marked_and_offer_no_cpoi(junction_net: Path, junction_map: RoadMap) -> None:
    ring_lanes = [i for i in junction_map.lane_ids if junction_map.lane(i).street_name == "Ring"]
    assert ring_lanes and all(junction_map.lane(i).in_roundabout for i in ring_lanes)
    assert not any(junction_map.lane(i).in_roundabout for i in _main_lanes(junction_map, "Main"))
    assert not any(junction_map.lane(c.lane_id).is_junction for c in junction_map.curves())
    assert any(junction_map.lane(c.lane_id).in_roundabout for c in junction_map.curves(include_junctions=True))
    start = _lane_heading_to(junction_map, (350.0, 0.0), 0.0)
    east = _lane_heading_to(junction_map, (800.0, 0.0), 0.0)
    route = _route(junction_net, junction_map, start, east)
    assert any(junction_map.lane(f"{edge}_0").in_roundabout for edge in route)
    with_junctions = _cpoi_radii(junction_map, start, route, warn_at_junctions=True)
    assert any(radius == pytest.approx(25.0, rel=0.1) for radius in with_junctions)  # the ring
    assert _cpoi_radii(junction_map, start, route, warn_at_junctions=False) == []


def test_a_bend_running_through_a_junction_is_still_a_curve(side_road_map: RoadMap) -> None:
    lanes = _main_lanes(side_road_map, "Pass Road")
    assert len(lanes) == 2  # the side road splits the way in the middle of the arc
    first = min(lanes, key=lambda lane: np.hypot(*side_road_map.lane_shape(lane)[0]))
    second = next(lane for lane in lanes if lane != first)
    path = side_road_map.path_profile([first, second])
    # the road curves keep the mapped radius around the junction, and are not dropped as a turn
    road_parts = [part for curve in path.road_curves() for part in curve.parts]
    assert sum(part.end_s - part.start_s for part in road_parts) > 0.6 * (ARC_END_S - ARC_START_S)
    assert [part.radius_m for part in road_parts] == pytest.approx([ARC_RADIUS_M] * len(road_parts), rel=0.05)
    route = [side_road_map.lane(first).edge_id, side_road_map.lane(second).edge_id]
    radii = _cpoi_radii(side_road_map, first, route, warn_at_junctions=False)
    assert radii and min(radii) == pytest.approx(ARC_RADIUS_M, rel=0.05)


# ------------------------------------------------------------------ the command and its errors
def test_pbf_imports_like_xml(arc_osm, arc_map: RoadMap, tmp_path: Path) -> None:
    import osmium

    pbf = tmp_path / "arc.osm.pbf"
    with osmium.SimpleWriter(str(pbf)) as writer:
        for item in osmium.FileProcessor(str(arc_osm[0])):
            writer.add(item)
    assert cli.main(["import-osm", str(pbf), "-o", str(tmp_path / "pbf.net.xml")]) == 0
    road_map = RoadMap.load(tmp_path / "pbf.net.xml")
    assert road_map.lane_ids == arc_map.lane_ids
    # PBF stores lon/lat in 1e-7 degrees: positions agree to the centimetre
    assert np.allclose(road_map.lane_shape(road_map.lane_ids[0]), arc_map.lane_shape(arc_map.lane_ids[0]), atol=0.02)
    collection = json.loads((tmp_path / "pbf.curves.geojson").read_text())
    assert "OpenStreetMap contributors" in collection["attribution"]
    assert collection["features"]


FOOTWAYS_ONLY = (
    '<?xml version="1.0"?>\n<osm version="0.6">\n'
    '<node id="1" version="1" lat="50.8" lon="9.7"/><node id="2" version="1" lat="50.801" lon="9.7"/>\n'
    '<way id="1" version="1"><nd ref="1"/><nd ref="2"/><tag k="highway" v="footway"/></way>\n</osm>\n'
)


@pytest.mark.parametrize(
    ("name", "content", "message"),
    [
        ("missing.osm", None, "does not exist"),
        ("empty.osm", b"", "is empty"),
        ("empty.osm.gz", gzip.compress(b""), "empty once decompressed"),
        ("broken.osm", b"<osm version='0.6'><node id='1' lat=", "not a readable OSM file"),
        ("broken.osm.pbf", b"\x00\x00\x00\x0dnot a pbf at all", "not a readable OSM file"),
        ("roads.txt", b"hello", "not an OpenStreetMap file name"),
        ("footways.osm", FOOTWAYS_ONLY.encode(), "no drivable roads"),
    ],
    ids=["missing", "empty", "empty-gzip", "broken-xml", "broken-pbf", "unknown-suffix", "no-roads"],
)
def test_bad_files_give_one_line_errors(tmp_path: Path, capsys, name: str, content: bytes | None, message: str) -> None:
    source = tmp_path / name
    if content is not None:
        source.write_bytes(content)
    assert cli.main(["import-osm", str(source), "-o", str(tmp_path / "out.net.xml")]) == cli.EXIT_BAD_INPUT
    error = capsys.readouterr().err
    assert error.startswith("csws: error:") and message in error and error.count("\n") == 1
    assert not (tmp_path / "out.net.xml").exists()


@pytest.mark.sumo
def test_a_service_road_survives_import_with_the_default_fleet_classes(tmp_path: Path) -> None:
    osm = OsmWriter()
    osm.way(np.array([[0.0, 0.0], [100.0, 0.0]]), "service")  # service roads admit delivery vans (N1) only
    (tmp_path / "service.osm").write_text(osm.text())
    assert "delivery" in FLEET_VCLASSES and ImportSettings().keep_vclasses == FLEET_VCLASSES
    result = import_osm(tmp_path / "service.osm", tmp_path / "service.net.xml")
    assert _edge_types(result.net_path) == {"highway.service"}
    assert result.dropped.ways_listed == ()
    # Without the vans, the service road is closed to every class kept.
    with pytest.raises(OsmImportError, match="no drivable roads for truck, bus, coach"):
        import_osm(
            tmp_path / "service.osm", tmp_path / "heavy.net.xml", ImportSettings(keep_vclasses=COMMERCIAL_VCLASSES)
        )


@pytest.mark.sumo
def test_every_dropped_way_and_every_way_cut_by_the_border_is_listed_with_its_reason(tmp_path: Path) -> None:
    osm = OsmWriter()
    osm.way(np.array([[0.0, 0.0], [1000.0, 0.0]]), "primary", name="Main")
    osm.way(np.array([[1000.0, 0.0], [1000.0, 150.0]]), "service")  # closed to heavy vehicles by its type
    osm.way(np.array([[0.0, 5000.0], [200.0, 5000.0]]), "secondary")  # not connected to Main
    # A way leaving the extract: its last node is not in the file.
    refs = osm.way(np.array([[500.0, 0.0], [500.0, -300.0]]), "tertiary")
    text = osm.text().replace(f'<nd ref="{refs[-1]}"/>', '<nd ref="999999"/>')
    (tmp_path / "four.osm").write_text(text)
    settings = ImportSettings(keep_vclasses=COMMERCIAL_VCLASSES)
    result = import_osm(tmp_path / "four.osm", tmp_path / "four.net.xml", settings)
    reasons = {(way.way_id, way.reason) for way in result.dropped.ways_listed}
    assert reasons == {(2, CLOSED_TYPE), (3, NOT_IN_NETWORK), (4, CUT_BY_BORDER)}
    listed = result.dropped_path.read_text().splitlines()
    assert listed[0] == "way_id,highway,length_m,reason" and len(listed) == 4
    assert any(line.startswith(f"{CUT_BY_BORDER}: 1 way(s)") for line in result.dropped.lines())
    # The loss warning counts the roads open to the kept classes only: Main, the tertiary way's part, Elsewhere.
    assert result.dropped.by_highway["secondary"][0] == 1 and "service" not in result.dropped.by_highway


# ------------------------------------------------------------------ the bundled real network
BADHERSFELD_NET = networks_dir() / "badhersfeld.net.xml.gz"


@pytest.fixture(scope="module")
@marks_its_tests("slow")
def badhersfeld() -> RoadMap:
    return RoadMap.load(BADHERSFELD_NET)


def test_real_network_projection_agrees_with_geodesy(badhersfeld: RoadMap) -> None:
    rng = np.random.default_rng(3)
    lanes = [badhersfeld.lane_shape(lane_id) for lane_id in rng.choice(badhersfeld.lane_ids, 50)]
    points = np.array([shape[0] for shape in lanes] + [shape[-1] for shape in lanes])
    lonlat = badhersfeld.xy_to_lonlat_many(points)
    # Bad Hersfeld lies at about 9.7 E, 50.87 N
    assert np.all(np.abs(lonlat[:, 0] - 9.72) < 0.15) and np.all(np.abs(lonlat[:, 1] - 50.85) < 0.1)
    a, b = lonlat[:50], lonlat[50:]
    _, _, geodesic_m = pyproj.Geod(ellps="WGS84").inv(a[:, 0], a[:, 1], b[:, 0], b[:, 1])
    planar_m = np.hypot(*(points[:50] - points[50:]).T)
    assert np.allclose(planar_m, geodesic_m, rtol=5e-4, atol=0.01)
    assert np.allclose(badhersfeld.lonlat_to_xy_many(lonlat), points, atol=1e-6)


def test_real_network_roundabouts_and_curve_index(badhersfeld: RoadMap) -> None:
    roundabout_lanes = [lane for lane in badhersfeld.lane_ids if badhersfeld.lane(lane).in_roundabout]
    assert roundabout_lanes
    curves = badhersfeld.curves()
    assert curves and not any(badhersfeld.lane(curve.lane_id).is_junction for curve in curves)
    index = json.loads((networks_dir() / "badhersfeld.curves.geojson").read_text())
    assert "OpenStreetMap contributors" in index["attribution"]
    indexed_lanes = {feature["properties"]["lane_id"] for feature in index["features"]}
    assert indexed_lanes and not any(badhersfeld.lane(lane).is_junction for lane in indexed_lanes)


def test_the_shipped_curve_index_is_the_one_the_road_model_writes(badhersfeld: RoadMap) -> None:
    """The curve index beside the bundled network is rebuilt with the road model: a user reading it sees the curves
    the service warns for, curve by curve, lane by lane."""
    shipped = json.loads((networks_dir() / "badhersfeld.curves.geojson").read_text())["features"]
    written = curves_geojson(badhersfeld, DEFAULT_POLICY)["features"]

    def curves(features: list[dict]) -> list[tuple[str, str, float, float]]:
        return [
            (
                f["properties"]["curve_id"],
                f["properties"]["lane_id"],
                f["properties"]["radius_m"],
                f["properties"]["angle_deg"],
            )
            for f in features
        ]

    assert curves(shipped) == curves(written)


@pytest.mark.sumo
def test_real_fleet_scenario_runs_in_sumo(tmp_path: Path) -> None:
    config = networks_dir() / "badhersfeld.sumocfg"
    result = subprocess.run(
        [
            str(sumo_binary("sumo")),
            "-c",
            str(config),
            "--end",
            "30",
            "--duration-log.statistics",
            "true",
            "--tripinfo-output",
            str(tmp_path / "trips.xml"),
        ],
        env={"SUMO_HOME": str(sumo_home()), "PROJ_LIB": str(sumo_home() / "data" / "proj"), "PATH": ""},
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr
    assert "Inserted: 3" in result.stdout  # one departure every 10 s: at 0, 10 and 20 s
    routes = (networks_dir() / "badhersfeld.rou.xml").read_text()
    assert all(f'vClass="{vclass}"' in routes for vclass in ("truck", "bus", "coach"))


# ------------------------------------------------------------------ roads netconvert does not know
def _three_ways(tmp_path: Path, middle_highway: str) -> Path:
    """A 900 m road of three ways in a row, the middle one tagged ``middle_highway``."""
    osm = OsmWriter()
    for start_m, highway in ((0.0, "primary"), (300.0, middle_highway), (600.0, "primary")):
        osm.way(np.array([[start_m, 0.0], [start_m + 300.0, 0.0]]), highway, name="Tunnel Road")
    (tmp_path / "road.osm").write_text(osm.text())
    return tmp_path / "road.osm"


def _edge_types(net_path: Path) -> set[str]:
    road_map = RoadMap.load(net_path)
    return {road_map.lane(lane_id).road_type for lane_id in road_map.lane_ids if not road_map.lane(lane_id).is_internal}


@pytest.mark.sumo
@pytest.mark.parametrize("value", ["primary_tunnel", "secondary_bridge", "motorway_link_tunnel"])
def test_a_way_tagged_with_a_tunnel_or_bridge_value_survives_import(tmp_path: Path, value: str) -> None:
    result = import_osm(_three_ways(tmp_path, value), tmp_path / "road.net.xml")
    assert f"highway.{value}" in _edge_types(result.net_path)
    assert result.dropped.ways == 0 and result.dropped.lines() == []
    assert result.dropped.motor_km == pytest.approx(0.9, rel=0.02)


@pytest.mark.sumo
def test_what_an_import_drops_is_counted_by_highway_value_and_warned_of(tmp_path: Path) -> None:
    osm = OsmWriter()
    osm.way(np.array([[0.0, 0.0], [1000.0, 0.0]]), "primary", name="Main")
    osm.way(np.array([[0.0, 5000.0], [200.0, 5000.0]]), "secondary", name="Elsewhere")  # not connected: dropped
    (tmp_path / "two.osm").write_text(osm.text())
    result = import_osm(tmp_path / "two.osm", tmp_path / "two.net.xml")
    ways, km = result.dropped.by_highway["secondary"]
    assert ways == 1 and km == pytest.approx(0.2, rel=0.02)
    assert result.dropped.motor_km == pytest.approx(1.2, rel=0.02)
    assert result.dropped.lines()[-1].startswith("warning: 0.2 of 1.2 km of drivable roads (16.7%)")
    assert result.log_path.is_file() and "Parsing" in result.log_path.read_text()


@pytest.mark.sumo
def test_a_type_file_of_the_user_adds_a_highway_value(tmp_path: Path) -> None:
    type_file = tmp_path / "extra.typ.xml"
    type_file.write_text(
        '<types><type id="highway.corridor" numLanes="1" speed="13.89" priority="3" oneway="false"/></types>'
    )
    osm_path = _three_ways(tmp_path, "corridor")
    without = import_osm(osm_path, tmp_path / "without.net.xml")
    assert without.dropped.by_highway == {} or "corridor" not in _edge_types(without.net_path)
    with_types = import_osm(osm_path, tmp_path / "with.net.xml", ImportSettings(type_files=(type_file,)))
    assert "highway.corridor" in _edge_types(with_types.net_path)


def test_a_missing_type_file_is_one_clear_error(tmp_path: Path) -> None:
    with pytest.raises(OsmImportError, match="no type file at"):
        import_osm(
            _three_ways(tmp_path, "primary"),
            tmp_path / "x.net.xml",
            ImportSettings(type_files=(tmp_path / "none.xml",)),
        )
