"""The ``csws`` command: one subcommand per job, each with its own ``--help``.

Handlers import what they need lazily so that ``csws --help`` is instant. Errors
that come from the user's input (a missing file, a network that cannot be read, a
bad number) end with one line on stderr and exit status 2; a job whose result is a
failure (a verification that does not hold) exits with status 1.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Callable, Sequence
from importlib.metadata import entry_points
from pathlib import Path
from typing import NoReturn

from csws import __version__
from csws.cli.argtypes import positive_float

EXIT_FAILED = 1
EXIT_BAD_INPUT = 2
#: Exit status when the output's reader went away, as for a program that SIGPIPE ends (128 + 13).
EXIT_BROKEN_PIPE = 141


class CommandError(Exception):
    """A user-facing failure: printed as one line, no traceback."""


def _cmd_networks_build(args: argparse.Namespace) -> int:
    from csws.networks.build import build_networks, compare_networks

    if args.check:
        differences = compare_networks(args.dir)
        for line in differences:
            print(line)
        print("networks match their generator" if not differences else f"{len(differences)} difference(s)")
        return EXIT_FAILED if differences else 0
    written = build_networks(args.dir)
    print(f"wrote {len(written)} networks with their truth files to {args.dir}")
    return 0


def _cmd_networks_verify(args: argparse.Namespace) -> int:
    from csws.networks.verify import verify_networks

    report = verify_networks(args.dir, tolerance_m=args.tolerance_m)
    print(report.as_table())
    return 0 if report.passed else EXIT_FAILED


def _cmd_curves(args: argparse.Namespace) -> int:
    """``csws curves``: the curve index of a network in the format asked for (:mod:`csws.road.export`)."""
    from csws.road.export import write_curves
    from csws.road.roadmap import RoadMap

    write_curves(RoadMap.load(args.net, warning_radius_m=args.warning_radius_m), sys.stdout, fmt=args.format)
    return 0


def _default_networks_dir() -> Path:
    from csws.networks import networks_dir

    return networks_dir()


#: The entry-point group of the modules that add subcommands (``pyproject.toml``): each entry is an
#: ``add_commands(subparsers)`` that keeps its heavy imports inside its handlers, so that ``csws --help``
#: stays instant.
COMMANDS_GROUP = "csws.commands"


def deferred(module_name: str, function_name: str = "main") -> Callable[[argparse.Namespace], int]:
    """A subcommand handler that imports ``module_name`` only when the subcommand runs, then calls
    ``function_name(args)``: heavy modules (SUMO, FastAPI) stay out of ``csws --help``."""

    def handler(args: argparse.Namespace) -> int:
        return getattr(importlib.import_module(module_name), function_name)(args)

    return handler


class _Parser(argparse.ArgumentParser):
    """argparse, with a usage error as one line like every other bad input (subcommands inherit it)."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_BAD_INPUT, f"csws: error: {message} (see: {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``csws`` and its subcommands."""
    parser = _Parser(
        prog="csws",
        description="Map-based curve speed warning for commercial vehicles (T/ITS 0091-2018).",
    )
    parser.add_argument("--version", action="version", version=f"csws {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    networks = commands.add_parser("networks", help="build and verify the bundled test-track networks")
    networks_commands = networks.add_subparsers(dest="networks_command", metavar="ACTION", required=True)
    build = networks_commands.add_parser(
        "build", help="write the test tracks of Tables 3, 7, 8 and 9 (plain XML + netconvert) with their truth"
    )
    build.add_argument("--dir", type=Path, default=None, help="output folder (default: the bundled networks)")
    build.add_argument("--check", action="store_true", help="rebuild in a temporary folder and compare with --dir")
    build.set_defaults(handler=_cmd_networks_build)
    verify = networks_commands.add_parser(
        "verify", help="extract the curves of every network and compare them with the generator's truth"
    )
    verify.add_argument("--dir", type=Path, default=None, help="networks folder (default: the bundled networks)")
    verify.add_argument(
        "--tolerance-m", type=positive_float, default=1.0, help="allowed curve start/end error in metres (default 1)"
    )
    verify.set_defaults(handler=_cmd_networks_verify)

    curves = commands.add_parser("curves", help="list the curves (radius <= R_c) of a SUMO network")
    curves.add_argument("net", type=Path, help="a SUMO .net.xml (or .net.xml.gz)")
    curves.add_argument(
        "--warning-radius-m", type=positive_float, default=None, help="warning curvature radius R_c in metres"
    )
    curves.add_argument("--format", choices=("table", "json", "csv"), default="table", help="output format")
    curves.set_defaults(handler=_cmd_curves)
    for entry_point in entry_points(group=COMMANDS_GROUP):
        entry_point.load()(commands)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``csws`` console command."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "dir", "unset") is None:
        args.dir = _default_networks_dir()
    handler: Callable[[argparse.Namespace], int] = args.handler
    try:
        return handler(args)
    except KeyboardInterrupt:
        print("csws: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # The reader of the output went away (``csws curves NET | head``): nothing is wrong, and
        # nothing more may be written to it, not even by the interpreter's last flush.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_BROKEN_PIPE
    except (CommandError, ValueError, OSError) as exc:
        print(f"csws: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
