"""The ``csws import-osm`` subcommand: its arguments; the work is in ``csws.osm.run``."""

from __future__ import annotations

import argparse


def _run(args: argparse.Namespace) -> int:
    from csws.osm import run as job

    return job.main(args)


def add_commands(commands: argparse._SubParsersAction) -> None:
    """Add ``csws import-osm``."""
    parser = commands.add_parser("import-osm", help="import an OpenStreetMap extract into a SUMO network with its curve index")
    parser.set_defaults(handler=_run)
