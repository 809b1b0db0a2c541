"""``csws import-osm`` and ``csws fleet-scenario``: run the import or the scenario writer and print a summary."""

from __future__ import annotations

import argparse

from .fleet import write_fleet_scenario
from .importer import FLEET_VCLASSES, ImportSettings, import_osm


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
    print(f"netconvert's messages: {result.log_path}")
    print("Data (c) OpenStreetMap contributors, ODbL 1.0: keep this attribution with the network.")
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
