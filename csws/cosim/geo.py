"""Where a co-simulation's vehicles are on Earth: lon/lat of SUMO's x, y on a geo-referenced network.

A network imported from OpenStreetMap keeps its projection and offset in its ``<location>``
element; the outputs then carry ``lon`` and ``lat`` (degrees, WGS84) beside ``x_m`` and
``y_m``. A network without a projection (``projParameter="!"``, the test tracks and the
fleet road) gets no such columns. Only the ``<location>`` element is read, so a run over
HTTP or without evaluation does not load the road map for it.
"""

from __future__ import annotations

import gzip
import io
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
import sumolib

from csws.road.georef import GeoReferenced
from csws.road.network import projection_net

__all__ = ["NetworkLocation", "network_location"]


class NetworkLocation(GeoReferenced):
    """A network's geo-reference, read from its ``<location>`` element alone.

    Parameters
    ----------
    geo
        A sumolib net holding only that location.
    """

    def __init__(self, geo: sumolib.net.Net) -> None:
        self.geo = geo
        self.has_projection = bool(geo.hasGeoProj())

    def lonlat(self, x_m: np.ndarray, y_m: np.ndarray) -> tuple[list[float | None], list[float | None]]:
        """Longitudes and latitudes, degrees, of network positions; None where a position is not finite
        (a step read without positions)."""
        xy = np.column_stack([np.asarray(x_m, dtype=float), np.asarray(y_m, dtype=float)])
        lon: list[float | None] = [None] * len(xy)
        lat: list[float | None] = [None] * len(xy)
        finite = np.flatnonzero(np.isfinite(xy).all(axis=1))
        if finite.size:
            converted = self.xy_to_lonlat_many(xy[finite]).tolist()
            for row, (row_lon, row_lat) in zip(finite.tolist(), converted, strict=True):
                lon[row], lat[row] = row_lon, row_lat
        return lon, lat


def _open(net: Path) -> gzip.GzipFile | io.BufferedReader:
    """The network file for reading, unpacked when it is gzipped (``.net.xml.gz``)."""
    return gzip.open(net, "rb") if net.suffix == ".gz" else open(net, "rb")


def network_location(net: Path) -> NetworkLocation | None:
    """The geo-reference of the SUMO network ``net``; None when it has no projection.

    Raises
    ------
    ValueError
        When the file is not a SUMO network.
    """
    try:
        with _open(net) as stream:
            for _, element in ElementTree.iterparse(stream, events=("start",)):
                if element.tag == "location":
                    location = dict(element.attrib)
                    break
                if element.tag in ("edge", "junction"):  # SUMO writes the location before them
                    return None
            else:
                return None
    except (ElementTree.ParseError, OSError, EOFError) as exc:
        raise ValueError(f"{net} is not a readable SUMO network: {exc}") from None
    found = NetworkLocation(projection_net(location))
    return found if found.has_projection else None
