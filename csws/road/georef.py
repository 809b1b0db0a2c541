"""Converts between a road map's network coordinates and longitude/latitude with the network's own projection.

Networks imported from OpenStreetMap are geo-referenced: SUMO projects them (UTM for an OSM
import) and moves them to the origin, keeping the offset and the projection in the
network's ``<location>`` element; :class:`GeoReferenced` undoes and redoes that as SUMO and
sumolib's ``convertXY2LonLat`` do.
"""

from __future__ import annotations

import math

import numpy as np
import sumolib

__all__ = ["GeoReferenced", "finite_pairs"]


def finite_pairs(values: np.ndarray, what: str) -> np.ndarray:
    """``values`` as a float ``(k, 2)`` array; ValueError when not finite pairs."""
    pairs = np.asarray(values, dtype=float)
    if pairs.ndim != 2 or pairs.shape[1] != 2:
        raise ValueError(f"{what} must be pairs, got an array of shape {np.shape(values)}")
    if not np.isfinite(pairs).all():
        raise ValueError(f"{what} must be finite numbers")
    return pairs


class GeoReferenced:
    """The geo-conversions of a road map whose ``geo`` (a sumolib net holding only its location) says
    where it lies; ``has_projection`` says whether it does."""

    geo: sumolib.net.Net
    has_projection: bool

    def xy_to_lonlat(self, x: float, y: float) -> tuple[float, float]:
        """Longitude and latitude (degrees, WGS84) of network coordinates (see :meth:`xy_to_lonlat_many`), projected
        as plain floats: a tenth of the time of a one-row array."""
        self._require_projection()
        if not (math.isfinite(x) and math.isfinite(y)):
            raise ValueError("network coordinates must be finite numbers")
        offset_x, offset_y = self.geo.getLocationOffset()
        lon, lat = self.geo.getGeoProj()(x - offset_x, y - offset_y, inverse=True)
        return float(lon), float(lat)

    def lonlat_to_xy(self, lon: float, lat: float) -> tuple[float, float]:
        """Network coordinates (m) of a longitude and latitude in degrees (see :meth:`lonlat_to_xy_many`)."""
        x, y = self.lonlat_to_xy_many(np.array([[lon, lat]], dtype=float))[0]
        return float(x), float(y)

    def xy_to_lonlat_many(self, xy: np.ndarray) -> np.ndarray:
        """Longitudes and latitudes (degrees, WGS84) of many network positions, ``(k, 2)`` -> ``(k, 2)``.

        As SUMO and sumolib's ``convertXY2LonLat`` do: the network offset is taken off
        and the network's projection (``projParameter``, UTM for an OSM import) inverted.

        Raises
        ------
        ValueError
            If the network has no geo-projection, or a coordinate is not finite.
        """
        self._require_projection()
        xy = finite_pairs(xy, "network coordinates")
        offset_x, offset_y = self.geo.getLocationOffset()
        lon, lat = self.geo.getGeoProj()(xy[:, 0] - offset_x, xy[:, 1] - offset_y, inverse=True)
        return np.column_stack((lon, lat))

    def lonlat_to_xy_many(self, lonlat: np.ndarray) -> np.ndarray:
        """Network coordinates (m) of many longitude/latitude pairs in degrees, ``(k, 2)`` -> ``(k, 2)``.

        Raises
        ------
        ValueError
            If the network has no geo-projection, or a longitude is outside [-180, 180]
            or a latitude outside [-90, 90] degrees.
        """
        self._require_projection()
        lonlat = finite_pairs(lonlat, "lon/lat")
        bad = (np.abs(lonlat[:, 0]) > 180.0) | (np.abs(lonlat[:, 1]) > 90.0)
        if bad.any():
            lon, lat = lonlat[np.flatnonzero(bad)[0]]
            raise ValueError(f"lon/lat out of range: ({lon}, {lat}); longitude is -180..180, latitude -90..90 degrees")
        offset_x, offset_y = self.geo.getLocationOffset()
        x, y = self.geo.getGeoProj()(lonlat[:, 0], lonlat[:, 1])
        return np.column_stack((np.asarray(x) + offset_x, np.asarray(y) + offset_y))

    def _require_projection(self) -> None:
        if not self.has_projection:
            raise ValueError("the network has no geo-projection: it takes network x/y in metres, not lon/lat")
