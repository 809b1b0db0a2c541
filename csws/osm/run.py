"""``csws import-osm``, ``csws map-report`` and ``csws fleet-scenario``: run the import, the map report or the
scenario writer and print a summary."""

from __future__ import annotations

import argparse
from pathlib import Path

from csws.road.roadmap import RoadMap

from .fleet import write_fleet_scenario
from .importer import FLEET_VCLASSES, ImportSettings, import_osm, map_report_path
from .report import network_items, summary_lines, write_report


def main(args: argparse.Namespace) -> int:
    """Import ``args.osm`` into ``args.output`` and print what was built."""
    settings = ImportSettings(
        lefthand=args.lefthand, keep_vclasses=args.vclasses or FLEET_VCLASSES, type_files=tuple(args.typemap)
    )
    result = import_osm(args.osm, args.output, settings)
    print(f"read {args.osm}: {result.scan.nodes} nodes, {result.scan.ways} ways, {result.scan.motor_ways} motor roads")
    print(f"wrote {result.net_path}: {result.lanes} lanes, {result.lane_km:.1f} lane-km ({result.convert_s:.1f} s)")
    print(f"wrote {result.curves_path}: {result.curves} curves ({result.curves_s:.1f} s)")
    for line in result.dropped.lines():
        print(line)
    print(f"ways dropped or cut by the extract border, with the reason: {result.dropped_path}")
    for line in summary_lines(result.report):
        print(line)
    print(f"what the map shows wrong or doubtful, place by place (GeoJSON): {result.report_path}")
    print(f"netconvert's messages: {result.log_path}")
    print("Data (c) OpenStreetMap contributors, ODbL 1.0: keep this attribution with the network.")
    return 0


def report_main(args: argparse.Namespace) -> int:
    """Write the map report of network ``args.net`` (to ``args.output``, else beside it) and print its summary."""
    road_map = RoadMap.load(args.net)
    items = network_items(road_map)
    path = write_report(
        items, road_map.has_projection, args.output or map_report_path(args.net), source=Path(args.net).name
    )
    for line in summary_lines(items):
        print(line)
    print(f"wrote {path}: {len(items)} item(s)")
    return 0


def fleet_main(args: argparse.Namespace) -> int:
    """Write the fleet scenario of ``args.net`` and print its routes."""
    road_types = tuple(name.strip() for name in args.road_types.split(",") if name.strip())
    route_path, config_path, routes = write_fleet_scenario(
        args.net, args.output, args.routes, args.vehicles, road_types
    )
    for route in routes:
        print(
            f"{route.route_id}: {len(route.edges)} edges, {route.length_m / 1000:.1f} km, "
            f"{route.turning_deg:.0f} deg of curves"
        )
    print(f"wrote {route_path} ({args.vehicles} vehicles on {len(routes)} routes) and {config_path}")
    return 0
