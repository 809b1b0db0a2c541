"""OSM extracts written by the tests: nodes placed in UTM zone 32 metres about a fixed origin, written as OSM XML.

Shared by the tests of the OSM import (tests/test_osm.py) and of the map report (tests/test_map_report.py).
"""

from __future__ import annotations

import numpy as np
import pyproj

#: The projection the tests place nodes in: UTM zone 32N.
UTM32 = pyproj.Proj("+proj=utm +zone=32 +ellps=WGS84 +datum=WGS84 +units=m +no_defs")
#: The origin of the local metres, lon/lat (near Bad Hersfeld), and in UTM metres.
ORIGIN_LONLAT = (9.70, 50.80)
ORIGIN_XY = np.array(UTM32(*ORIGIN_LONLAT))


class OsmWriter:
    """Collects nodes (given in metres from the origin) and ways, writes them as OSM XML."""

    def __init__(self) -> None:
        self.nodes: dict[int, tuple[float, float]] = {}
        self.ways: list[str] = []

    def node(self, xy: np.ndarray) -> int:
        """The id of the node at local ``xy`` (m), reusing a node already there."""
        key = (round(float(xy[0]), 3), round(float(xy[1]), 3))
        for node_id, existing in self.nodes.items():
            if existing == key:
                return node_id
        self.nodes[len(self.nodes) + 1] = key
        return len(self.nodes)

    def way(self, xy: np.ndarray, highway: str, **tags: str) -> list[int]:
        refs = [self.node(point) for point in xy]
        tag_text = "".join(f'<tag k="{k}" v="{v}"/>' for k, v in {"highway": highway, **tags}.items())
        nds = "".join(f'<nd ref="{ref}"/>' for ref in refs)
        self.ways.append(f'<way id="{len(self.ways) + 1}" version="1">{nds}{tag_text}</way>')
        return refs

    def lonlat(self, node_id: int) -> tuple[float, float]:
        x, y = self.nodes[node_id]
        lon, lat = UTM32(ORIGIN_XY[0] + x, ORIGIN_XY[1] + y, inverse=True)
        return float(lon), float(lat)

    def text(self) -> str:
        nodes = [
            f'<node id="{node_id}" version="1" lon="{lon:.9f}" lat="{lat:.9f}"/>'
            for node_id in self.nodes
            for lon, lat in [self.lonlat(node_id)]
        ]
        return (
            '<?xml version="1.0" encoding="UTF-8"?>\n<osm version="0.6">\n'
            + "\n".join(nodes + self.ways)
            + "\n</osm>\n"
        )
