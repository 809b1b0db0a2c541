"""The ``csws conformance`` subcommand: its arguments; the work is in ``csws.conformance.run``."""

from __future__ import annotations

import argparse
from pathlib import Path

from csws.cli import deferred
from csws.cli.argtypes import comma_list, one_of, output_folder, positive_int, step_length

#: Tables 5-9, 0 for our negative rows and 10 for the real-road tracks.
_TABLES = comma_list(lambda text: int(one_of(("0", "5", "6", "7", "8", "9", "10"))(text)), "table")
_CATEGORIES = comma_list(one_of(("M1", "M2", "M3", "N", "O"), str.upper), "category")
_DIRECTIONS = comma_list(one_of(("left", "right", "s"), str.lower), "direction")


def add_commands(commands: argparse._SubParsersAction) -> None:
    """Add ``csws conformance``."""
    parser = commands.add_parser(
        "conformance",
        help="run the standard's test procedure (7.5) on the test tracks and judge it (7.6)",
        description="Run Tables 5-9 of T/ITS 0091-2018 (clause 7.5), our negative rows and the real-road tracks "
        "(clothoids, compound curves, an S-bend, nodes inside curves; judged by formula (1) on the constructed "
        "truth) in SUMO for every category and step length, judge each row (three consecutive passing runs) "
        "and the system (7.6), and write report.json, report.md and one plot per row. "
        "Exit status 1 when a row fails.",
    )
    parser.add_argument(
        "--system",
        choices=("csws", "fcw"),
        default="csws",
        help="csws: T/ITS 0091-2018 (default); fcw: the forward collision warning's tests of GB/T 33577-2017 "
        "5.4-5.5 and IVISTA A.1 (--tables, --categories and --directions do not apply)",
    )
    parser.add_argument(
        "--out",
        type=output_folder,
        default=Path("conformance-report"),
        help="output folder (default: conformance-report)",
    )
    parser.add_argument(
        "--step-lengths",
        type=comma_list(step_length, "step length"),
        default=[0.01, 0.05, 0.1, 0.2],
        help="SUMO step lengths in s, comma-separated (default: 0.01,0.05,0.1,0.2)",
    )
    parser.add_argument(
        "--repetitions", type=positive_int, default=3, help="runs per row, track and step length (>= 3; default 3)"
    )
    parser.add_argument("--jobs", type=positive_int, default=1, help="worker processes (default 1)")
    parser.add_argument(
        "--seed", type=int, default=0, help="seed of the step phases and the measurement noise (default 0)"
    )
    parser.add_argument(
        "--tables",
        type=_TABLES,
        default=None,
        help="only these tables, e.g. 5,6 (0: the negative rows, 10: the real-road tracks)",
    )
    parser.add_argument("--categories", type=_CATEGORIES, default=None, help="only these categories, e.g. M1,N")
    parser.add_argument(
        "--rows",
        type=comma_list(str, "row pattern"),
        default=None,
        help="only rows whose id matches one of these patterns, e.g. 'T7-*,T5-R40-*' (fcw: 'GB-5.5.3*')",
    )
    parser.add_argument(
        "--directions",
        type=_DIRECTIONS,
        default=None,
        help="only the standard's tracks turning this way: left, right, s (default: all)",
    )
    parser.add_argument("--no-plots", action="store_true", help="do not draw the per-row plots")
    parser.set_defaults(handler=deferred("csws.conformance.run"))
