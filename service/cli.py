"""The ``csws serve`` subcommand: its arguments; the work is in ``service.run``."""

from __future__ import annotations

import argparse


def _run(args: argparse.Namespace) -> int:
    from service import run as job

    return job.main(args)


def add_commands(commands: argparse._SubParsersAction) -> None:
    """Add ``csws serve``."""
    parser = commands.add_parser("serve", help="serve curve speed warnings over HTTP (FastAPI + uvicorn)")
    parser.set_defaults(handler=_run)
