"""The real network end to end: import, curve extraction, service start-up and answer latency,
and the tightest curves checked against the road as mapped.

Needs the OSM extract (not shipped with csws): ``python -m benchmarks.osm EXTRACT.osm.xml.gz``
(the Bad Hersfeld extract of ``networks/badhersfeld.md``).

* import: ``csws.osm.importer.import_osm`` (netconvert, then the curve index: every road
  chain fitted, into a profile cache folder of the run's own);
* curves: ``RoadMap.load`` of the result (parse, arrays, the fit read from that cache,
  curves of every chain), peak memory of the process;
* service: ``service.app.create_app`` on the network alone, then ``POST /v1/warning``
  with lon/lat fixes on the fleet routes' lanes through FastAPI's in-process client;
* the mapped road: for the tightest curves on primary roads, a least-squares circle
  through the OSM nodes of the way within the curve (an estimate independent of the
  extractor) beside the extracted radius.
"""

from __future__ import annotations

import argparse
import re
import resource
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import shapely

from benchmarks.command import arguments
from benchmarks.roadmap import profile_cache_in
from csws.osm.importer import import_osm
from csws.road.roadmap import LaneCurve, RoadMap

#: Targets: what a user waits for at most. Import and load are those for a city of about
#: 500 lane-km (the Bad Hersfeld extract imports to 508): import (netconvert and the fit of
#: every road chain) 10 s; load, with the fit the import left in the profile cache, 5 s.
TARGETS = {"import_s": 10.0, "load_s": 5.0, "startup_s": 30.0, "latency_ms_p50": 20.0, "max_rss_mb": 2000.0}


def _way_id(edge_id: str) -> int:
    """The OSM way an imported edge comes from: netconvert names edges ``[-]WAY[#PART]``."""
    way = re.match(r"-?(\d+)", edge_id)
    if way is None:
        raise ValueError(f"not an edge of an imported way: {edge_id}")
    return int(way.group(1))


def _circle_radius_m(xy: np.ndarray) -> float:
    """Radius of the least-squares (Kasa) circle through points, m; inf for fewer than 3."""
    if len(xy) < 3:
        return float("inf")
    centred = xy - xy.mean(axis=0)
    design = np.column_stack((centred, np.ones(len(xy))))
    (a, b, c), *_ = np.linalg.lstsq(design, (centred**2).sum(axis=1), rcond=None)
    return float(np.sqrt(c + (a * a + b * b) / 4.0))


def _way_nodes_lonlat(osm_path: Path, way_ids: set[int]) -> dict[int, np.ndarray]:
    """Lon/lat of the nodes of some ways of an OSM file."""
    import osmium

    ways = {}
    for item in osmium.FileProcessor(str(osm_path), osmium.osm.NODE | osmium.osm.WAY).with_locations():
        if isinstance(item, osmium.osm.Way) and item.id in way_ids:
            ways[item.id] = np.array([(node.lon, node.lat) for node in item.nodes])
    return ways


def mapped_curve_table(road_map: RoadMap, osm_path: Path, count: int = 12) -> list[dict]:
    """The ``count`` tightest curves on primary roads, with the circle through the mapped way's nodes."""
    primary = [
        c
        for c in road_map.curves()
        if road_map.lane(c.lane_id).road_type == "highway.primary" and c.curve.angle_deg >= 20.0
    ]
    tightest: list[LaneCurve] = []
    for lane_curve in sorted(primary, key=lambda c: c.curve.min_radius_m):
        edge_id = road_map.lane(lane_curve.lane_id).edge_id
        if all(road_map.lane(c.lane_id).edge_id.lstrip("-") != edge_id.lstrip("-") for c in tightest):
            tightest.append(lane_curve)  # one direction of each road
        if len(tightest) == count:
            break
    ways = _way_nodes_lonlat(osm_path, {_way_id(road_map.lane(c.lane_id).edge_id) for c in tightest})
    rows = []
    for lane_curve in tightest:
        lane = road_map.lane(lane_curve.lane_id)
        shape = road_map.lane_shape(lane.lane_id)
        nodes_xy = road_map.lonlat_to_xy_many(ways[_way_id(lane.edge_id)])
        along_m = shapely.line_locate_point(shapely.linestrings(shape), shapely.points(nodes_xy))
        inside = nodes_xy[(along_m >= lane_curve.curve.start_s) & (along_m <= lane_curve.curve.end_s)]
        start_xy = shape[
            np.searchsorted(
                np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(shape, axis=0).T)))), lane_curve.curve.start_s
            ).clip(0, len(shape) - 1)
        ]
        lon, lat = road_map.xy_to_lonlat(*start_xy)
        rows.append(
            {
                "street": lane.street_name or "(unnamed)",
                "lane": lane.lane_id,
                "lon": round(lon, 5),
                "lat": round(lat, 5),
                "angle_deg": round(lane_curve.curve.angle_deg, 1),
                "radius_m": round(lane_curve.curve.min_radius_m, 1),
                "mapped_nodes": len(inside),
                "mapped_radius_m": round(_circle_radius_m(inside), 1),
            }
        )
    return rows


def _fixes_on_routes(road_map: RoadMap, count: int) -> list[dict]:
    """Warning queries at lon/lat on the rightmost lanes of primary roads, heading along the lane."""
    rng = np.random.default_rng(5)
    lanes = [
        i for i in road_map.lane_ids if road_map.lane(i).road_type == "highway.primary" and road_map.lane(i).index == 0
    ]
    queries = []
    for number, lane_id in enumerate(rng.choice(lanes, count)):
        shape = road_map.lane_shape(lane_id)
        segment = int(rng.integers(0, len(shape) - 1))
        (x0, y0), (x1, y1) = shape[segment], shape[segment + 1]
        lon, lat = road_map.xy_to_lonlat((x0 + x1) / 2, (y0 + y1) / 2)
        heading_deg = (90.0 - np.degrees(np.arctan2(y1 - y0, x1 - x0))) % 360.0
        queries.append(
            {
                "vehicle_id": f"truck-{number}",
                "category": "N",
                "speed_kmh": 70.0,
                "position": {"lon": lon, "lat": lat},
                "heading_deg": float(heading_deg),
            }
        )
    return queries


def _service_figures(net_path: Path, road_map: RoadMap, query_count: int) -> dict:
    """Start-up time of the service on the network and the latency of lon/lat warning queries."""
    from fastapi.testclient import TestClient

    from service.app import create_app
    from service.settings import ServiceSettings

    started = time.perf_counter()
    app = create_app(ServiceSettings(nets=[net_path], state_db=":memory:"))
    startup_s = time.perf_counter() - started
    latencies_ms, warned, matched = [], 0, 0
    with TestClient(app) as client:
        for query in _fixes_on_routes(road_map, query_count):
            sent = time.perf_counter()
            response = client.post("/v1/warning", json=query)
            latencies_ms.append((time.perf_counter() - sent) * 1000.0)
            response.raise_for_status()
            answer = response.json()
            warned += answer.get("level", 0) > 0
            matched += answer.get("matched") is not None
    return {
        "startup_s": round(startup_s, 2),
        "queries": query_count,
        "matched": matched,
        "warned": warned,
        "latency_ms_p50": round(float(np.percentile(latencies_ms, 50)), 2),
        "latency_ms_p95": round(float(np.percentile(latencies_ms, 95)), 2),
    }


def run(osm_path: Path, query_count: int = 300) -> dict:
    """Import ``osm_path``, load the result, serve it; return the figures and the curve table."""
    with tempfile.TemporaryDirectory(prefix="csws-bench-osm-") as folder, profile_cache_in(str(Path(folder) / "cache")):
        net_path = Path(folder) / "bench.net.xml.gz"
        started = time.perf_counter()
        result = import_osm(osm_path, net_path)
        imported = time.perf_counter()
        road_map = RoadMap.load(net_path)
        loaded = time.perf_counter()
        figures: dict[str, Any] = {
            "import_s": round(imported - started, 2),
            "netconvert_s": round(result.convert_s, 2),
            "load_s": round(loaded - imported, 2),
            "lanes": len(road_map.lane_ids),
            "lane_km": round(road_map.total_length_m / 1000.0, 1),
            "vertices": road_map.vertex_count,
            "curves": len(road_map.curves()),
            "junction_curves_left_out": len(road_map.curves(include_junctions=True)) - len(road_map.curves()),
            "stored_mb": round(road_map.nbytes / 1e6, 1),
        }
        figures.update(_service_figures(net_path, road_map, query_count))
        figures["max_rss_mb"] = round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0, 1)
        figures["curve_table"] = mapped_curve_table(road_map, osm_path)
    return figures


def _add_arguments(parser: argparse.ArgumentParser) -> None:
    """The one argument: the extract to import."""
    parser.add_argument("extract", type=Path, help="an OpenStreetMap extract (.osm, .osm.gz, .osm.xml.gz)")


def main() -> None:
    """Print the figures beside their targets, then the curve table."""
    extract = arguments("benchmarks.osm", __doc__, _add_arguments).extract
    if not extract.is_file():
        sys.exit(f"python -m benchmarks.osm: no OSM file at {extract}")
    figures = run(extract)
    table = figures.pop("curve_table")
    for name, value in figures.items():
        target = TARGETS.get(name)
        beside = f"   target <= {target}  ({value / target:.2f} of it)" if target else ""
        print(f"{name:>26}: {value}{beside}")
    columns = list(table[0])
    print()
    print(" | ".join(columns))
    for row in table:
        print(" | ".join(str(row[column]) for column in columns))


if __name__ == "__main__":
    main()
