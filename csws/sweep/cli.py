"""The ``csws sweep`` subcommand: its arguments; the work is in ``csws.sweep.run``."""

from __future__ import annotations

import argparse
from pathlib import Path

from csws.cli import deferred
from csws.cli.argtypes import output_folder, positive_int


def add_commands(commands: argparse._SubParsersAction) -> None:
    """Add ``csws sweep``."""
    parser = commands.add_parser(
        "sweep",
        help="run a fleet study (factors x seeds of co-simulations) on Dask and summarise it",
        description="Run every co-simulation of a study file on Dask (a local cluster of one worker process per "
        "core, or --scheduler), writing each run's result to DIR/runs/ as it ends; runs already there are skipped. "
        "Then writes DIR/summary.md, DIR/plots/ and DIR/all_runs.parquet.",
    )
    parser.add_argument("study", type=Path, help="the study, a TOML file (see docs/sweep.md)")
    parser.add_argument("--out", type=output_folder, required=True, help="output folder (made if missing)")
    cluster = parser.add_mutually_exclusive_group()
    cluster.add_argument(
        "--scheduler",
        default=None,
        metavar="tcp://HOST:PORT",
        help="a running Dask scheduler (default: a local cluster)",
    )
    cluster.add_argument(
        "--workers",
        type=positive_int,
        default=None,
        help="worker processes of the local cluster (default: one per core)",
    )
    parser.set_defaults(handler=deferred("csws.sweep.run"))
