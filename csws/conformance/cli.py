"""The ``csws conformance`` subcommand: its arguments; the work is in ``csws.conformance.run``."""

from __future__ import annotations

import argparse
from pathlib import Path


def _run(args: argparse.Namespace) -> int:
    from csws.conformance import run as job

    return job.main(args)


def _step_lengths(text: str) -> list[float]:
    """argparse type: comma-separated step lengths in seconds, each a positive multiple of 1 ms (SUMO's resolution)."""
    values = []
    for part in text.split(","):
        try:
            value = float(part)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a number: {part!r}") from None
        if not (0 < value <= 1) or abs(value * 1000 - round(value * 1000)) > 1e-9:
            raise argparse.ArgumentTypeError(f"a step length must be a multiple of 0.001 s in (0, 1]: {part!r}")
        values.append(value)
    return values


def _positive_int(text: str) -> int:
    """argparse type: an integer >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1: {text!r}")
    return value


def _csv(text: str) -> list[str]:
    """argparse type: a comma-separated list."""
    return [part.strip() for part in text.split(",") if part.strip()]


def _tables(text: str) -> list[int]:
    """argparse type: tables 5-9, and 0 for the negative rows."""
    try:
        tables = [int(part) for part in _csv(text)]
    except ValueError:
        raise argparse.ArgumentTypeError(f"tables are numbers among 0, 5, 6, 7, 8, 9: {text!r}") from None
    if not set(tables) <= {0, 5, 6, 7, 8, 9}:
        raise argparse.ArgumentTypeError(f"tables are among 0 (negative rows), 5, 6, 7, 8, 9: {text!r}")
    return tables


def _categories(text: str) -> list[str]:
    """argparse type: vehicle categories."""
    categories = [part.upper() for part in _csv(text)]
    if not set(categories) <= {"M1", "M2", "M3", "N", "O"}:
        raise argparse.ArgumentTypeError(f"categories are among M1, M2, M3, N, O: {text!r}")
    return categories


def _directions(text: str) -> list[str]:
    """argparse type: track directions."""
    directions = [part.lower() for part in _csv(text)]
    if not set(directions) <= {"left", "right", "s"}:
        raise argparse.ArgumentTypeError(f"directions are among left, right, s: {text!r}")
    return directions


def add_commands(commands: argparse._SubParsersAction) -> None:
    """Add ``csws conformance``."""
    parser = commands.add_parser(
        "conformance",
        help="run the standard's test procedure (7.5) on the test tracks and judge it (7.6)",
        description="Run Tables 5-9 of T/ITS 0091-2018 (clause 7.5) and our negative rows in SUMO for every "
        "category and step length, judge each row (three consecutive passing runs) and the system (7.6), "
        "and write report.json, report.md and one plot per row. Exit status 1 when a row fails.",
    )
    parser.add_argument("--out", type=Path, default=Path("conformance-report"), help="output folder (default: conformance-report)")
    parser.add_argument("--step-lengths", type=_step_lengths, default=[0.01, 0.05, 0.1, 0.2],
                        help="SUMO step lengths in s, comma-separated (default: 0.01,0.05,0.1,0.2)")  # fmt: skip
    parser.add_argument("--repetitions", type=_positive_int, default=3, help="runs per row, track and step length (>= 3; default 3)")
    parser.add_argument("--jobs", type=_positive_int, default=1, help="worker processes (default 1)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the step phases and the measurement noise (default 0)")
    parser.add_argument("--tables", type=_tables, default=None, help="only these tables, e.g. 5,6 (0: the negative rows)")
    parser.add_argument("--categories", type=_categories, default=None, help="only these categories, e.g. M1,N")
    parser.add_argument("--rows", type=_csv, default=None, help="only rows whose id matches one of these patterns, e.g. 'T7-*,T5-R40-*'")
    parser.add_argument("--directions", type=_directions, default=None, help="only tracks turning this way: left, right, s (default: all)")
    parser.add_argument("--no-plots", action="store_true", help="do not draw the per-row plots")
    parser.set_defaults(handler=_run)
