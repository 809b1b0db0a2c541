"""The ``csws cosim`` subcommand: its arguments; the work is in ``csws.cosim.run``."""

from __future__ import annotations

import argparse


def _run(args: argparse.Namespace) -> int:
    from csws.cosim import run as job

    return job.main(args)


def add_commands(commands: argparse._SubParsersAction) -> None:
    """Add ``csws cosim``."""
    parser = commands.add_parser("cosim", help="co-simulate a fleet in SUMO and record who was warned where")
    parser.set_defaults(handler=_run)
