"""The ``csws serve`` subcommand: its arguments; the work is in ``service.run``."""

from __future__ import annotations

import argparse
from pathlib import Path

from csws.cli import deferred


def add_commands(commands: argparse._SubParsersAction) -> None:
    """Add ``csws serve``."""
    parser = commands.add_parser(
        "serve",
        help="serve curve speed warnings over HTTP (FastAPI + uvicorn)",
        description="Serve curve speed warnings over HTTP. Options override the CSWS_* environment variables; "
        "without --net the bundled networks are served. OpenAPI docs at /docs.",
    )
    parser.add_argument("--net", type=Path, action="append", default=None, metavar="FILE",
                        help="a SUMO network to serve (.net.xml or .net.xml.gz); repeat for several")
    parser.add_argument("--host", default=None, help="address to listen on (default 127.0.0.1)")
    parser.add_argument("--port", type=int, default=None, help="TCP port (default 8000)")
    parser.add_argument("--workers", type=int, default=None, help="worker processes (default 1)")
    parser.add_argument("--state-db", default=None, metavar="FILE",
                        help="SQLite file keeping vehicle switches across restarts (':memory:' for none)")
    parser.add_argument("--session-idle-s", type=float, default=None,
                        help="a vehicle session idle this long expires, s (default 600)")
    parser.add_argument("--update-period-s", type=float, default=None,
                        help="how often a vehicle's fixes arrive, s: the warning comes that much earlier (default 0.1)")
    parser.set_defaults(handler=deferred("service.run"))
