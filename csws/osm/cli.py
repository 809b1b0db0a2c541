"""The ``csws import-osm``, ``csws map-report`` and ``csws fleet-scenario`` subcommands: their arguments; the work is in
``csws.osm.run``."""

from __future__ import annotations

import argparse
from pathlib import Path

from csws.cli import deferred
from csws.cli.argtypes import network_file, positive_int


def _vclasses(text: str) -> tuple[str, ...]:
    """argparse type: a comma-separated list of SUMO vehicle classes."""
    classes = tuple(name.strip() for name in text.split(",") if name.strip())
    if not classes:
        raise argparse.ArgumentTypeError("give at least one vehicle class, e.g. truck,bus,coach")
    return classes


def add_commands(commands: argparse._SubParsersAction) -> None:
    """Add ``csws import-osm``, ``csws map-report`` and ``csws fleet-scenario``."""
    parser = commands.add_parser(
        "import-osm", help="import an OpenStreetMap extract into a SUMO network with its curve index"
    )
    parser.add_argument("osm", type=Path, help="OpenStreetMap file: .osm, .osm.xml, .osm.gz, .osm.xml.gz or .osm.pbf")
    parser.add_argument(
        "-o", "--output", type=network_file, required=True, help="network to write: NAME.net.xml or NAME.net.xml.gz"
    )
    parser.add_argument("--lefthand", action="store_true", help="left-hand traffic (default: right-hand)")
    parser.add_argument(
        "--typemap",
        type=Path,
        action="append",
        default=[],
        metavar="FILE",
        help="a SUMO type file read after SUMO's OSM type map, for highway values it lacks (may be repeated)",
    )
    parser.add_argument(
        "--vclasses",
        type=_vclasses,
        default=None,
        help=(
            "keep the roads that allow one of these SUMO vehicle classes "
            "(default: truck,bus,coach,delivery: delivery is N1 vans, which service roads are open to)"
        ),
    )
    parser.set_defaults(handler=deferred("csws.osm.run"))

    report = commands.add_parser(
        "map-report",
        help="list what a network's map shows wrong or doubtful (artefacts, corners, curves at the radius floor)",
    )
    report.add_argument("net", type=Path, help="a SUMO .net.xml or .net.xml.gz")
    report.add_argument(
        "-o", "--output", type=Path, default=None, help="GeoJSON to write (default: NAME.report.geojson beside NET)"
    )
    report.set_defaults(handler=deferred("csws.osm.run", "report_main"))

    fleet = commands.add_parser(
        "fleet-scenario", help="write a SUMO scenario of trucks and buses on the twistiest roads of a network"
    )
    fleet.add_argument("net", type=Path, help="a SUMO .net.xml or .net.xml.gz")
    fleet.add_argument(
        "-o", "--output", type=Path, required=True, help="scenario prefix: writes PREFIX.rou.xml and PREFIX.sumocfg"
    )
    fleet.add_argument("--routes", type=positive_int, default=8, help="number of distinct routes (default 8)")
    fleet.add_argument("--vehicles", type=positive_int, default=48, help="number of vehicles (default 48)")
    fleet.add_argument(
        "--road-types",
        default="highway.primary,highway.secondary",
        help="road types whose curves the routes seek (default highway.primary,highway.secondary)",
    )
    fleet.set_defaults(handler=deferred("csws.osm.run", "fleet_main"))
