"""The ``csws serve`` subcommand: its arguments; the work is in ``service.run``."""

from __future__ import annotations

import argparse
from pathlib import Path

from csws.cli import deferred


def add_commands(commands: argparse._SubParsersAction) -> None:
    """Add ``csws serve`` and ``csws keys`` (the entry point of the ``csws.commands`` group)."""
    _add_serve(commands)
    _add_keys(commands)


def _add_serve(commands: argparse._SubParsersAction) -> None:
    """Add ``csws serve``."""
    parser = commands.add_parser(
        "serve",
        help="serve curve speed warnings over HTTP (FastAPI + uvicorn)",
        description="Serve curve speed warnings over HTTP. Options override the CSWS_* environment variables; "
        "without --net the bundled city (Bad Hersfeld) is served. OpenAPI docs at /docs.",
    )
    parser.add_argument(
        "--net",
        type=Path,
        action="append",
        default=None,
        metavar="FILE",
        help="a SUMO network to serve (.net.xml or .net.xml.gz); repeat for several (default: the bundled city)",
    )
    parser.add_argument(
        "--test-tracks",
        action="store_true",
        default=None,
        help="also serve the bundled test tracks of T/ITS 0091-2018 (alone without --net); they share their "
        "coordinates, so name the network in a query",
    )
    parser.add_argument("--host", default=None, help="address to listen on (default 127.0.0.1)")
    parser.add_argument("--port", type=int, default=None, help="TCP port (default 8000)")
    parser.add_argument("--workers", type=int, default=None, help="worker processes (default 1)")
    parser.add_argument(
        "--state",
        default=None,
        metavar="URL",
        help="redis://HOST:PORT/DB: keep vehicle switches and sessions in Redis, shared by replicas "
        "on several machines (default: the SQLite file of --state-db)",
    )
    parser.add_argument(
        "--state-db",
        default=None,
        metavar="FILE",
        help="SQLite file keeping vehicle switches and sessions for the workers of this machine "
        "and across restarts (':memory:' for none)",
    )
    parser.add_argument(
        "--session-idle-s", type=float, default=None, help="a vehicle session idle this long expires, s (default 600)"
    )
    parser.add_argument(
        "--update-period-s",
        type=float,
        default=None,
        help="how often a vehicle's fixes arrive, s, until its own period is learnt from its timestamps "
        "(CSWS_LEARN_UPDATE_PERIOD=false: always); the warning comes that much earlier "
        "(default: the warning settings' update period, 0.1 s)",
    )
    parser.add_argument(
        "--api-keys",
        type=Path,
        default=None,
        metavar="FILE",
        help="the fleets' API keys (csws keys add); without them only a loopback address is served",
    )
    parser.add_argument(
        "--fcw-settings",
        type=Path,
        default=None,
        metavar="FILE",
        help="the forward collision warning's settings per fleet (service.fcw_settings); default: by category",
    )
    parser.add_argument(
        "--warning-settings",
        type=Path,
        default=None,
        metavar="FILE",
        help="the curve warning's update period and release rule per fleet (service.warning_settings); "
        "default: the service's for every fleet",
    )
    parser.add_argument(
        "--insecure", action="store_true", default=None, help="serve without API keys on an address other than loopback"
    )
    parser.add_argument(
        "--public-docs",
        action="store_true",
        default=None,
        help="with API keys: /docs, /redoc, /openapi.json and /metrics need no key",
    )
    parser.add_argument(
        "--mqtt", default=None, metavar="URL", help="publish the events to this MQTT broker (mqtt://HOST:PORT)"
    )
    parser.add_argument(
        "--webhooks",
        type=Path,
        default=None,
        metavar="FILE",
        help="the fleets' webhooks (csws webhooks add; default: webhooks.json beside --api-keys)",
    )
    parser.add_argument(
        "--webhook-allow-private",
        action="store_true",
        default=None,
        help="webhooks may reach loopback and private addresses (never link-local or metadata ones)",
    )
    parser.add_argument(
        "--push-db",
        default=None,
        metavar="FILE|URL",
        help="where push keeps its cursors, retries and dead letters: a SQLite file or a Redis URL (default: the "
        "Redis of --state, else beside --state-db)",
    )
    parser.add_argument(
        "--log-level",
        choices=("critical", "error", "warning", "info", "debug"),
        default="warning",
        help="the service's and uvicorn's log on standard error, from this level up (default warning)",
    )
    parser.add_argument(
        "--access-log",
        nargs="?",
        const="text",
        choices=("text", "json"),
        default=None,
        help="a line per request on standard error: time, method, path, status, duration and fleet (never the "
        "key); json writes JSON lines (default: none; the option alone: text)",
    )
    parser.set_defaults(handler=deferred("service.run"))


def _add_keys(commands: argparse._SubParsersAction) -> None:
    """Add ``csws keys add | list | revoke | rotate`` (:mod:`service.keys_commands`)."""
    keys = commands.add_parser(
        "keys",
        help="manage the fleets' API keys of the service",
        description="Manage the fleets' API keys. The key file keeps hashes only; a running service reads it "
        "again when it changes (within a second, in every worker): no restart.",
    )
    keys_commands = keys.add_subparsers(dest="keys_command", metavar="ACTION", required=True)
    add = keys_commands.add_parser(
        "add", help="make a key for a fleet, add its hash to the key file, print the key once"
    )
    add.add_argument("fleet", help="the fleet: 1-64 letters, digits, '_', '.' or '-'")
    add.add_argument(
        "--role",
        choices=("query", "admin"),
        default="query",
        help="query: warnings, horizons, curves, reading vehicles; admin: also switching them (default query)",
    )
    add.add_argument("--label", default=None, help="a name for the key, unique in the file (e.g. the unit or the team)")
    _file_option(add, "; created if missing")
    add.set_defaults(handler=deferred("service.keys_commands", "add_command"))
    listing = keys_commands.add_parser(
        "list", help="the keys of the key file: fingerprint, fleet, role, label, date (never a key)"
    )
    _file_option(listing)
    listing.set_defaults(handler=deferred("service.keys_commands", "list_command"))
    for action, text, handler in (
        ("revoke", "take a key out of the key file", "revoke_command"),
        ("rotate", "replace a key by a new one of the same fleet, role and label, printed once", "rotate_command"),
    ):
        parser = keys_commands.add_parser(action, help=text)
        parser.add_argument("key", metavar="FINGERPRINT|LABEL", help="the key's label, or its fingerprint (6+ digits)")
        _file_option(parser)
        parser.set_defaults(handler=deferred("service.keys_commands", handler))


def _file_option(parser: argparse.ArgumentParser, more: str = "") -> None:
    """The ``--file`` option of the ``csws keys`` commands."""
    parser.add_argument("--file", type=Path, default=None, help=f"the key file (default: $CSWS_API_KEYS_FILE){more}")
