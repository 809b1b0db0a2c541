"""The ``csws conformance`` subcommand: its arguments; the work is in ``csws.conformance.run``."""

from __future__ import annotations

import argparse


def _run(args: argparse.Namespace) -> int:
    from csws.conformance import run as job

    return job.main(args)


def add_commands(commands: argparse._SubParsersAction) -> None:
    """Add ``csws conformance``."""
    parser = commands.add_parser("conformance", help="run the standard's test procedure (7.5) on the test tracks and judge it (7.6)")
    parser.set_defaults(handler=_run)
