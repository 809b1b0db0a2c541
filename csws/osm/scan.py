"""Reads what an OpenStreetMap file holds before it is imported: its nodes, ways and motor roads, counted by osmium.

Every input of an import (:mod:`csws.osm.importer`) is scanned first, so that a missing, empty
or broken file, or an extract without roads, is reported in one clear line, and so that the
import knows the motor ways of the extract: their ``highway`` value and length, their nodes'
lon/lat, and which of them the extract's border cuts (:mod:`csws.osm.coverage`).
"""

from __future__ import annotations

import gzip
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from csws.errors import CswsError

from .typemap import base_highway

if TYPE_CHECKING:
    import osmium

__all__ = [
    "EARTH_RADIUS_M",
    "MOTOR_HIGHWAYS",
    "OSM_SUFFIXES",
    "OsmImportError",
    "OsmScan",
    "osm_format",
    "scan_osm",
]

#: File name endings read, and the osmium format each is.
OSM_SUFFIXES = {
    ".osm": "osm",
    ".osm.xml": "osm",
    ".osm.gz": "osm.gz",
    ".osm.xml.gz": "osm.gz",
    ".osm.pbf": "pbf",
}

#: Mean Earth radius for the lengths of ways, m.
EARTH_RADIUS_M = 6_371_008.8

#: ``highway`` values of ways that can carry motor traffic; an extract with none of them
#: has no roads to import (footways, tracks or buildings only).
MOTOR_HIGHWAYS = frozenset(
    {
        "motorway",
        "trunk",
        "primary",
        "secondary",
        "tertiary",
        "unclassified",
        "residential",
        "motorway_link",
        "trunk_link",
        "primary_link",
        "secondary_link",
        "tertiary_link",
        "living_street",
        "service",
        "road",
        "busway",
        "bus_guideway",
    }
)


class OsmImportError(ValueError, CswsError):
    """An OSM file that cannot be imported; the message is one line for the user."""


@dataclass(frozen=True)
class OsmScan:
    """What an OSM file holds, counted by osmium.

    Attributes
    ----------
    nodes, ways
        Number of nodes and ways.
    motor_ways
        Ways with a ``highway`` value of :data:`MOTOR_HIGHWAYS` or built from one
        (``primary_tunnel``).
    highway_values
        Every ``highway`` value of the file.
    motor_way_lengths
        ``way id -> (highway value, length in m)`` of the motor ways.
    cut_ways
        The motor ways with nodes missing from the extract: cut by its border.
    way_lonlat
        ``way id -> lon/lat (k, 2)`` of the motor ways' nodes in the extract, degrees: where the map report
        places a way the network lacks.
    """

    nodes: int
    ways: int
    motor_ways: int
    highway_values: frozenset[str] = frozenset()
    motor_way_lengths: dict[int, tuple[str, float]] = field(default_factory=dict)
    cut_ways: frozenset[int] = frozenset()
    way_lonlat: dict[int, np.ndarray] = field(default_factory=dict, repr=False)


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
    nodes = ways = 0
    values: set[str] = set()
    motor: dict[int, tuple[str, float]] = {}
    lonlat: dict[int, np.ndarray] = {}
    cut: set[int] = set()
    try:
        source = osmium.FileProcessor(osmium.io.File(str(path), fmt), osmium.osm.NODE | osmium.osm.WAY).with_locations()
        for item in source:
            if not isinstance(item, osmium.osm.Way):
                nodes += 1
                continue
            ways += 1
            value = item.tags.get("highway")
            if value is None:
                continue
            values.add(value)
            if value in MOTOR_HIGHWAYS or base_highway(value, MOTOR_HIGHWAYS) is not None:
                lonlat[item.id] = _way_lonlat(item)
                motor[item.id] = (value, _way_length_m(lonlat[item.id]))
                if not all(node.location.valid() for node in item.nodes):
                    cut.add(item.id)
    except RuntimeError as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise OsmImportError(f"{path} is not a readable OSM file ({reason})") from None
    if nodes == 0:
        raise OsmImportError(f"{path} holds no OSM nodes: it is not an OpenStreetMap extract or it is empty")
    return OsmScan(nodes, ways, len(motor), frozenset(values), motor, frozenset(cut), lonlat)


def _way_lonlat(way: osmium.osm.Way) -> np.ndarray:
    """Lon/lat of the nodes of an osmium way that the extract holds, ``(k, 2)``, degrees."""
    return np.array([(node.lon, node.lat) for node in way.nodes if node.location.valid()], dtype=float).reshape(-1, 2)


def _way_length_m(points: np.ndarray) -> float:
    """Length of a way from its nodes' lon/lat ``(k, 2)`` in degrees, m (0 for fewer than two)."""
    if len(points) < 2:
        return 0.0
    lon, lat = np.radians(points).T
    east = np.diff(lon) * np.cos((lat[1:] + lat[:-1]) / 2.0)
    return float(EARTH_RADIUS_M * np.hypot(east, np.diff(lat)).sum())
