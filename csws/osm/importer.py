"""OpenStreetMap extract -> SUMO network that keeps the curves, plus its curve index.

An OSM way is a polyline whose nodes sit 5-30 m apart; netconvert turns it into lanes
that keep those vertices. The options here make sure nothing thins or straightens
them, so the curvature extractor sees the road as mapped:

* no geometry removal (``--geometry.remove false``), no segment splitting or minimum
  vertex distance, no ``--geometry.min-radius.fix`` / ``--geometry.max-angle.fix``;
* coordinates to the centimetre (``--precision 2``): rounding then bends a 5 m chord
  by at most 0.004 rad, far below the heading change of a curve of R_c = 300 m
  over that chord (0.017 rad);
* SUMO's OSM typemap, and only the edges a truck, bus or coach may use
  (``--keep-edges.by-vclass``), in the largest connected part of the road graph, so
  a fleet can route anywhere on the result;
* roundabouts (from ``junction=roundabout`` and guessed), joined junction clusters,
  signals and ramps guessed as SUMO recommends for OSM, street names kept;
* right-hand traffic, or left-hand with ``lefthand=True``.

PBF is read by osmium (netconvert reads only OSM XML) and converted to a temporary
XML file first. Every input is first scanned with osmium, so a missing, empty or
broken file, or an extract without roads, is reported in one clear line.
"""

from __future__ import annotations

import gzip
import json
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from ..binaries import sumo_home
from ..netbuild import NetconvertError, netconvert_osm
from ..roadmap import RoadMap, read_sumo_net

__all__ = [
    "OSM_ATTRIBUTION",
    "OSM_SUFFIXES",
    "COMMERCIAL_VCLASSES",
    "ImportSettings",
    "ImportResult",
    "OsmImportError",
    "OsmScan",
    "curve_index_path",
    "import_osm",
    "netconvert_options",
    "scan_osm",
    "write_curve_index",
]

#: File name endings read, and the osmium format each is.
OSM_SUFFIXES = {
    ".osm": "osm",
    ".osm.xml": "osm",
    ".osm.gz": "osm.gz",
    ".osm.xml.gz": "osm.gz",
    ".osm.pbf": "pbf",
}

#: The vehicle classes of commercial vehicles: an edge is kept when it allows one of them.
COMMERCIAL_VCLASSES = ("truck", "bus", "coach")

#: Attribution every file built from OpenStreetMap data carries (ODbL 1.0, section 4.3).
OSM_ATTRIBUTION = "Data (c) OpenStreetMap contributors, available under the Open Database License (ODbL 1.0)"

#: ``highway`` values of ways that can carry motor traffic; an extract with none of them
#: has no roads to import (footways, tracks or buildings only).
MOTOR_HIGHWAYS = frozenset(
    {
        "motorway", "trunk", "primary", "secondary", "tertiary", "unclassified", "residential",
        "motorway_link", "trunk_link", "primary_link", "secondary_link", "tertiary_link",
        "living_street", "service", "road", "busway", "bus_guideway",
    }
)  # fmt: skip


class OsmImportError(ValueError):
    """An OSM file that cannot be imported; the message is one line for the user."""


@dataclass(frozen=True)
class ImportSettings:
    """How an OSM extract becomes a network.

    Attributes
    ----------
    lefthand
        Left-hand traffic (UK, Japan, ...); right-hand otherwise.
    keep_vclasses
        Keep the edges that allow at least one of these SUMO vehicle classes.
    precision_digits
        Digits after the point of output coordinates (2: centimetres).
    warning_radius_m
        R_c (3.2) of the curve index, m; None for the standard's default.
    """

    lefthand: bool = False
    keep_vclasses: tuple[str, ...] = COMMERCIAL_VCLASSES
    precision_digits: int = 2
    warning_radius_m: float | None = None


@dataclass(frozen=True)
class OsmScan:
    """What an OSM file holds, counted by osmium.

    Attributes
    ----------
    nodes, ways
        Number of nodes and ways.
    motor_ways
        Ways with a ``highway`` value of :data:`MOTOR_HIGHWAYS`.
    """

    nodes: int
    ways: int
    motor_ways: int


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
        network and extracting its curves.
    """

    net_path: Path
    curves_path: Path
    scan: OsmScan
    lanes: int
    lane_km: float
    curves: int
    convert_s: float
    curves_s: float


def osm_format(path: Path) -> str:
    """The osmium format of an OSM file name (``osm``, ``osm.gz`` or ``pbf``).

    Raises
    ------
    OsmImportError
        If the name does not end with one of :data:`OSM_SUFFIXES`.
    """
    name = path.name.lower()
    for suffix in sorted(OSM_SUFFIXES, key=len, reverse=True):
        if name.endswith(suffix):
            return OSM_SUFFIXES[suffix]
    known = ", ".join(OSM_SUFFIXES)
    raise OsmImportError(f"{path}: not an OpenStreetMap file name (expected one of {known})")


def _check_not_empty(path: Path, fmt: str) -> None:
    """Raise :class:`OsmImportError` if ``path`` is missing or holds no bytes (uncompressed)."""
    if not path.is_file():
        raise OsmImportError(f"no OSM file at {path}: the file does not exist")
    if path.stat().st_size == 0:
        raise OsmImportError(f"{path} is empty")
    if fmt == "osm.gz":
        try:
            with gzip.open(path, "rb") as stream:
                first = stream.read(1)
        except (OSError, EOFError) as exc:
            raise OsmImportError(f"{path} is not a readable gzip file ({exc})") from None
        if not first:
            raise OsmImportError(f"{path} is empty once decompressed")


def scan_osm(path: str | Path) -> OsmScan:
    """Read an OSM file with osmium and count its nodes, ways and motor-road ways.

    Raises
    ------
    OsmImportError
        If the file is missing, empty, of an unknown kind, not readable as OSM data,
        or holds no nodes.
    """
    import osmium

    path = Path(path)
    fmt = osm_format(path)
    _check_not_empty(path, fmt)
    nodes = ways = motor_ways = 0
    try:
        source = osmium.FileProcessor(osmium.io.File(str(path), fmt), osmium.osm.NODE | osmium.osm.WAY)
        for item in source:
            if item.is_node():
                nodes += 1
            else:
                ways += 1
                motor_ways += item.tags.get("highway") in MOTOR_HIGHWAYS
    except RuntimeError as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise OsmImportError(f"{path} is not a readable OSM file ({reason})") from None
    if nodes == 0:
        raise OsmImportError(f"{path} holds no OSM nodes: it is not an OpenStreetMap extract or it is empty")
    return OsmScan(nodes, ways, motor_ways)


def netconvert_options(settings: ImportSettings = ImportSettings()) -> list[str]:
    """The netconvert options of an OSM import (see the module docstring for the why)."""
    options = [
        "--type-files", str(sumo_home() / "data" / "typemap" / "osmNetconvert.typ.xml"),
        "--keep-edges.by-vclass", ",".join(settings.keep_vclasses),
        "--keep-edges.components", "1",
        "--geometry.remove", "false",
        "--precision", str(settings.precision_digits),
        "--output.street-names", "true",
        "--roundabouts.guess", "true",
        "--junctions.join", "true",
        "--tls.guess-signals", "true",
        "--tls.discard-simple", "true",
        "--tls.join", "true",
        "--ramps.guess", "true",
        "--no-warnings", "true",
    ]  # fmt: skip
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


def curve_index_path(net_path: Path) -> Path:
    """Where the curve index of a network goes: ``NAME.curves.geojson`` beside ``NAME.net.xml[.gz]``."""
    name = net_path.name
    for suffix in (".net.xml.gz", ".net.xml", ".xml.gz", ".xml"):
        if name.endswith(suffix):
            return net_path.with_name(name[: -len(suffix)] + ".curves.geojson")
    return net_path.with_name(name + ".curves.geojson")


def _netconvert_reason(messages: str) -> str:
    """The first error line of netconvert's output."""
    errors = [line for line in messages.splitlines() if line.startswith("Error")]
    return (errors or messages.splitlines() or ["netconvert failed"])[0]


def _convert(osm_path: Path, fmt: str, net_path: Path, settings: ImportSettings) -> None:
    """netconvert the OSM file (converting PBF first) into ``net_path``."""
    with tempfile.TemporaryDirectory(prefix="csws-osm-") as work:
        source = _pbf_to_xml(osm_path, Path(work) / "extract.osm") if fmt == "pbf" else osm_path
        try:
            netconvert_osm([source], net_path, netconvert_options(settings))
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
    _convert(osm_path, osm_format(osm_path), net_path, settings)
    converted = time.perf_counter()
    try:
        road_map = RoadMap.from_net(read_sumo_net(net_path), settings.warning_radius_m)
    except ValueError:
        net_path.unlink(missing_ok=True)
        raise _no_roads_error(osm_path, settings) from None
    curves_path = curve_index_path(net_path)
    write_curve_index(road_map, curves_path, osm_path)
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
    )


def write_curve_index(road_map: RoadMap, path: Path, source: Path) -> Path:
    """Write the curve index of a geo-referenced road map as GeoJSON (WGS84) with the OSM attribution."""
    collection = road_map.curves_geojson()
    document = {
        "type": collection["type"],
        "attribution": OSM_ATTRIBUTION,
        "source": source.name,
        "warning_radius_m": road_map.warning_radius_m,
        "features": collection["features"],
    }
    with open(path, "w", encoding="utf-8") as stream:
        json.dump(document, stream, separators=(",", ":"))
        stream.write("\n")
    return path
