"""OpenStreetMap extract -> SUMO network that keeps the curves, plus its curve index.

An OSM way is a polyline whose nodes sit 5-30 m apart; netconvert turns it into lanes
that keep those vertices. The options here make sure nothing thins or straightens
them, so the curvature extractor sees the road as mapped:

* no geometry removal (``--geometry.remove false``), no segment splitting or minimum
  vertex distance, no ``--geometry.min-radius.fix`` / ``--geometry.max-angle.fix``;
* coordinates to the centimetre (``--precision 2``): rounding then bends a 5 m chord
  by at most 0.004 rad, far below the heading change of a curve of R_c = 300 m
  over that chord (0.017 rad);
* SUMO's OSM typemap, a type for every ``highway`` value built from a known one
  (``primary_tunnel``: :mod:`csws.osm.typemap`) and the user's own type files; only the
  edges the fleet's vehicle classes may use (``--keep-edges.by-vclass``; by default
  :data:`FLEET_VCLASSES`: trucks, buses, coaches and N1 delivery vans, so a
  ``highway=service`` road, open to delivery in SUMO's type map, is kept), in the largest
  connected part of the road graph, so a fleet can route anywhere on the result. The
  motor roads that did not make it are counted by ``highway`` value and listed way by way
  with the reason, ways cut by the extract's border among them (:mod:`csws.osm.coverage`,
  ``NAME.dropped.csv`` beside the network), and netconvert's warnings are kept in a log
  beside the network;
* roundabouts (from ``junction=roundabout`` and guessed), joined junction clusters,
  signals and ramps guessed as SUMO recommends for OSM, street names kept;
* right-hand traffic, or left-hand with ``lefthand=True``.

PBF is read by osmium (netconvert reads only OSM XML) and converted to a temporary
XML file first. Every input is first scanned with osmium (:mod:`csws.osm.scan`), so a
missing, empty or broken file, or an extract without roads, is reported in one clear line.
"""

from __future__ import annotations

import json
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from xml.etree import ElementTree

from csws.road.export import curves_geojson
from csws.road.roadmap import RoadMap, read_sumo_net
from csws.standard import DEFAULT_POLICY
from csws.sumo.netbuild import NetconvertError, netconvert_osm

from .coverage import DroppedRoads, dropped_roads, write_dropped_ways
from .report import ReportItem, dropped_items, network_items, write_report
from .scan import OSM_SUFFIXES, OsmImportError, OsmScan, osm_format, scan_osm
from .typemap import base_highway, derived_highways, known_highways, sumo_type_file, type_allows, write_derived_types

__all__ = [
    "OSM_ATTRIBUTION",
    "OSM_SUFFIXES",
    "COMMERCIAL_VCLASSES",
    "FLEET_VCLASSES",
    "dropped_ways_path",
    "map_report_path",
    "ImportSettings",
    "ImportResult",
    "OsmImportError",
    "OsmScan",
    "curve_index_path",
    "import_osm",
    "netconvert_log_path",
    "netconvert_options",
    "scan_osm",
    "write_curve_index",
]

#: The vehicle classes of heavy commercial vehicles (categories N2, N3, M2, M3).
COMMERCIAL_VCLASSES = ("truck", "bus", "coach")
#: The vehicle classes an import keeps by default: an edge is kept when it allows one of them. The heavy
#: commercial vehicles and SUMO's ``delivery`` class, the N1 vans of category N the standard covers, which
#: drive the service roads of depots, yards and back streets (``highway=service`` is open to them only).
FLEET_VCLASSES = (*COMMERCIAL_VCLASSES, "delivery")

#: Attribution every file built from OpenStreetMap data carries (ODbL 1.0, section 4.3).
OSM_ATTRIBUTION = "Data (c) OpenStreetMap contributors, available under the Open Database License (ODbL 1.0)"


@dataclass(frozen=True)
class ImportSettings:
    """How an OSM extract becomes a network.

    Attributes
    ----------
    lefthand
        Left-hand traffic (UK, Japan, ...); right-hand otherwise.
    keep_vclasses
        Keep the edges that allow at least one of these SUMO vehicle classes (default :data:`FLEET_VCLASSES`).
    precision_digits
        Digits after the point of output coordinates (2: centimetres).
    warning_radius_m
        R_c (3.2) of the curve index, m; None for the standard's default.
    type_files
        SUMO type files read after SUMO's OSM type map (a type of one of them wins).
    """

    lefthand: bool = False
    keep_vclasses: tuple[str, ...] = FLEET_VCLASSES
    precision_digits: int = 2
    warning_radius_m: float | None = None
    type_files: tuple[Path, ...] = ()


@dataclass(frozen=True)
class ImportResult:
    """An imported network.

    Attributes
    ----------
    net_path, curves_path
        The network and its curve index (GeoJSON, WGS84).
    scan
        What the OSM file held.
    lanes, lane_km, curves
        Lanes (internal lanes included), their total length in km, and curves in the index.
    convert_s, curves_s
        Seconds spent in netconvert (PBF conversion included) and in loading the
        network and extracting its curves and map report.
    dropped
        The motor roads of the extract whose type lets a kept vehicle class drive, but
        that are not in the network, and every way dropped or cut by the border with its reason.
    log_path
        netconvert's messages, warnings included.
    dropped_path
        The ways listed in ``dropped``, as CSV (:func:`csws.osm.coverage.write_dropped_ways`).
    report, report_path
        The map report (:mod:`csws.osm.report`): what the network shows wrong or doubtful, and the ways
        dropped or cut by the border, place by place; and its GeoJSON file.
    """

    net_path: Path
    curves_path: Path
    scan: OsmScan
    lanes: int
    lane_km: float
    curves: int
    convert_s: float
    curves_s: float
    dropped: DroppedRoads
    log_path: Path
    dropped_path: Path
    report: tuple[ReportItem, ...]
    report_path: Path


def netconvert_options(
    settings: ImportSettings = ImportSettings(), type_files: tuple[Path, ...] | None = None
) -> list[str]:
    """The netconvert options of an OSM import (see the module docstring for the why).

    ``type_files`` are all the type files in the order read; by default SUMO's OSM type
    map and the settings' own.
    """
    type_files = (sumo_type_file(), *settings.type_files) if type_files is None else type_files
    options = [
        "--type-files",
        ",".join(str(path) for path in type_files),
        "--keep-edges.by-vclass",
        ",".join(settings.keep_vclasses),
        "--keep-edges.components",
        "1",
        "--geometry.remove",
        "false",
        "--precision",
        str(settings.precision_digits),
        "--output.street-names",
        "true",
        "--roundabouts.guess",
        "true",
        "--junctions.join",
        "true",
        "--tls.guess-signals",
        "true",
        "--tls.discard-simple",
        "true",
        "--tls.join",
        "true",
        "--ramps.guess",
        "true",
    ]
    if settings.lefthand:
        options += ["--lefthand", "true"]
    return options


def _pbf_to_xml(pbf_path: Path, xml_path: Path) -> Path:
    """Copy every object of a PBF file into an OSM XML file with osmium (netconvert reads no PBF)."""
    import osmium

    with osmium.SimpleWriter(str(xml_path)) as writer:
        for item in osmium.FileProcessor(str(pbf_path)):
            writer.add(item)
    return xml_path


def _beside(net_path: Path, suffix: str) -> Path:
    """``NAME`` + ``suffix`` beside the network ``NAME.net.xml[.gz]``."""
    name = net_path.name
    for ending in (".net.xml.gz", ".net.xml", ".xml.gz", ".xml"):
        if name.endswith(ending):
            return net_path.with_name(name[: -len(ending)] + suffix)
    return net_path.with_name(name + suffix)


def curve_index_path(net_path: Path) -> Path:
    """Where the curve index of a network goes: ``NAME.curves.geojson`` beside ``NAME.net.xml[.gz]``."""
    return _beside(net_path, ".curves.geojson")


def dropped_ways_path(net_path: Path) -> Path:
    """Where the ways an import dropped go: ``NAME.dropped.csv`` beside the network."""
    return _beside(net_path, ".dropped.csv")


def map_report_path(net_path: Path) -> Path:
    """Where the map report of a network goes: ``NAME.report.geojson`` beside the network."""
    return _beside(net_path, ".report.geojson")


def netconvert_log_path(net_path: Path) -> Path:
    """Where netconvert's messages of an import go: ``NAME.netconvert.log`` beside the network."""
    return _beside(net_path, ".netconvert.log")


def _netconvert_reason(messages: str) -> str:
    """The first error line of netconvert's output."""
    errors = [line for line in messages.splitlines() if line.startswith("Error")]
    return (errors or messages.splitlines() or ["netconvert failed"])[0]


def _type_files(scan: OsmScan, settings: ImportSettings, work: Path) -> tuple[Path, ...]:
    """SUMO's type map, a type file for the extract's highway values built from known ones,
    and the user's type files, in the order netconvert reads them."""
    for path in settings.type_files:
        if not Path(path).is_file():
            raise OsmImportError(f"no type file at {path}")
    given = (sumo_type_file(), *settings.type_files)
    try:
        known = known_highways(given)
    except ElementTree.ParseError as exc:
        raise OsmImportError(f"a type file is not readable XML ({exc})") from None
    derived = derived_highways(scan.highway_values, known)
    if not derived:
        return given
    return (sumo_type_file(), write_derived_types(derived, known, work / "derived.typ.xml"), *settings.type_files)


def _drivable_ways(scan: OsmScan, settings: ImportSettings) -> dict[int, tuple[str, float]]:
    """The motor ways whose road type lets a kept vehicle class drive (a ``service`` way, for
    one, is for delivery vans only in SUMO's type map): those the network should hold; the
    others are closed to the fleet by their type."""
    known = known_highways((sumo_type_file(), *settings.type_files))
    allowed = {}
    for value in {value for value, _ in scan.motor_way_lengths.values()}:
        base = value if value in known else base_highway(value, known)
        allowed[value] = base is not None and type_allows(known[base], settings.keep_vclasses)
    return {way: entry for way, entry in scan.motor_way_lengths.items() if allowed[entry[0]]}


def _convert(osm_path: Path, fmt: str, net_path: Path, settings: ImportSettings, scan: OsmScan) -> None:
    """netconvert the OSM file (converting PBF first) into ``net_path``, its messages into the log."""
    with tempfile.TemporaryDirectory(prefix="csws-osm-") as work:
        source = _pbf_to_xml(osm_path, Path(work) / "extract.osm") if fmt == "pbf" else osm_path
        options = [
            *netconvert_options(settings, _type_files(scan, settings, Path(work))),
            "--log",
            str(netconvert_log_path(net_path)),
        ]
        try:
            netconvert_osm([source], net_path, options)
        except NetconvertError as exc:
            reason = _netconvert_reason(str(exc).split("\n", 1)[-1])
            if "No edges loaded" in reason or "No nodes loaded" in reason:
                raise _no_roads_error(osm_path, settings) from None
            raise OsmImportError(f"netconvert could not import {osm_path}: {reason}") from None


def _no_roads_error(osm_path: Path, settings: ImportSettings) -> OsmImportError:
    vclasses = ", ".join(settings.keep_vclasses)
    return OsmImportError(f"{osm_path} has no drivable roads for {vclasses}: the network would be empty")


def import_osm(osm_path: str | Path, net_path: str | Path, settings: ImportSettings = ImportSettings()) -> ImportResult:
    """Import an OSM extract into a SUMO network and write its curve index beside it.

    Parameters
    ----------
    osm_path
        ``.osm``, ``.osm.xml`` (optionally ``.gz``) or ``.osm.pbf``.
    net_path
        The network to write (``.net.xml``, or ``.net.xml.gz`` to gzip it).
    settings
        Traffic side, kept vehicle classes, precision, R_c.

    Raises
    ------
    OsmImportError
        For a missing, empty or broken file, and for an extract without roads that
        commercial vehicles may drive.
    """
    osm_path, net_path = Path(osm_path), Path(net_path)
    scan = scan_osm(osm_path)
    if scan.motor_ways == 0:
        raise OsmImportError(f"{osm_path} has no drivable roads: none of its {scan.ways} ways is a motor road")
    net_path.parent.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    _convert(osm_path, osm_format(osm_path), net_path, settings, scan)
    converted = time.perf_counter()
    try:
        net = read_sumo_net(net_path)
        road_map = RoadMap.from_net(net, settings.warning_radius_m)
    except ValueError:
        net_path.unlink(missing_ok=True)
        raise _no_roads_error(osm_path, settings) from None
    drivable = _drivable_ways(scan, settings)
    closed = {way: entry for way, entry in scan.motor_way_lengths.items() if way not in drivable}
    dropped = dropped_roads(drivable, (edge.getID() for edge in net.getEdges()), closed, scan.cut_ways)
    dropped_path = write_dropped_ways(dropped, dropped_ways_path(net_path))
    curves_path = curve_index_path(net_path)
    write_curve_index(road_map, curves_path, osm_path)
    report = network_items(road_map) + dropped_items(dropped, scan.way_lonlat)
    report_path = write_report(
        report, road_map.has_projection, map_report_path(net_path), source=osm_path.name, attribution=OSM_ATTRIBUTION
    )
    indexed = time.perf_counter()
    return ImportResult(
        net_path=net_path,
        curves_path=curves_path,
        scan=scan,
        lanes=len(road_map.lane_ids),
        lane_km=road_map.total_length_m / 1000.0,
        curves=len(road_map.curves()),
        convert_s=converted - started,
        curves_s=indexed - converted,
        dropped=dropped,
        log_path=netconvert_log_path(net_path),
        dropped_path=dropped_path,
        report=tuple(report),
        report_path=report_path,
    )


def write_curve_index(road_map: RoadMap, path: Path, source: Path) -> Path:
    """Write the curve index of a geo-referenced road map as GeoJSON (WGS84, :func:`csws.road.export.curves_geojson`,
    V_w under the standard's policy) with the OSM attribution."""
    collection = curves_geojson(road_map, DEFAULT_POLICY)
    document = {
        "type": collection["type"],
        "attribution": OSM_ATTRIBUTION,
        "source": source.name,
        "warning_radius_m": road_map.warning_radius_m,
        "coordinates": collection["coordinates"],
        "features": collection["features"],
    }
    with open(path, "w", encoding="utf-8") as stream:
        json.dump(document, stream, separators=(",", ":"))
        stream.write("\n")
    return path
