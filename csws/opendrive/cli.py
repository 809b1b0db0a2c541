"""The ``csws import-opendrive`` subcommand: its arguments; the work is in :mod:`csws.opendrive.run`."""

from __future__ import annotations

import argparse
from pathlib import Path

from csws.cli import deferred
from csws.cli.argtypes import network_file


def add_commands(commands: argparse._SubParsersAction) -> None:
    """Add ``csws import-opendrive``."""
    parser = commands.add_parser(
        "import-opendrive",
        help="import an ASAM OpenDRIVE file into a SUMO network with the exact curvature of its lanes",
    )
    parser.add_argument("xodr", type=Path, help="OpenDRIVE file (.xodr)")
    parser.add_argument(
        "-o", "--output", type=network_file, required=True, help="network to write: NAME.net.xml or NAME.net.xml.gz"
    )
    parser.set_defaults(handler=deferred("csws.opendrive.run"))
