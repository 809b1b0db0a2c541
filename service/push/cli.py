"""``csws webhooks add | list | remove | dead-letters``: the fleets' webhooks (:mod:`service.push.targets`).

A fleet's secret is printed once, on stdout and alone on its line, when its first URL is added;
everything else goes to stderr, except the tables of ``list`` and ``dead-letters``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from datetime import UTC, datetime
from pathlib import Path

from csws.cli import deferred

__all__ = ["add_commands"]

ALLOW_PRIVATE_VARIABLE = "CSWS_WEBHOOK_ALLOW_PRIVATE"


def add_commands(commands: argparse._SubParsersAction) -> None:
    """Add ``csws webhooks`` (the entry point of the ``csws.commands`` group)."""
    webhooks = commands.add_parser(
        "webhooks",
        help="manage the fleets' webhooks, which receive their events as signed POSTs",
        description="Manage the fleets' webhooks (docs/push.md). The file sits beside the API key file "
        "(webhooks.json) unless --file or CSWS_WEBHOOKS_FILE names another; a running service reads it again "
        "when it changes.",
    )
    actions = webhooks.add_subparsers(dest="webhooks_command", metavar="ACTION", required=True)
    add = actions.add_parser("add", help="add a URL to a fleet's webhooks (prints the fleet's new secret once)")
    add.add_argument("url", help="an http:// or https:// URL")
    add.add_argument(
        "--allow-private",
        action="store_true",
        help=f"allow a loopback or private address (as does {ALLOW_PRIVATE_VARIABLE}=1)",
    )
    remove = actions.add_parser("remove", help="take a URL out of a fleet's webhooks")
    remove.add_argument("url", help="the URL, as listed")
    listing = actions.add_parser("list", help="the webhooks: fleet and URL (never a secret)")
    dead = actions.add_parser("dead-letters", help="the events a webhook never took, with the last error")
    dead.add_argument(
        "--db",
        default=None,
        help="the push state: a SQLite file or a Redis URL (default: $CSWS_PUSH_DB, else the Redis of $CSWS_STATE, "
        "else beside $CSWS_STATE_DB)",
    )
    dead.add_argument("--json", action="store_true", help="JSON lines, each with the event itself")
    for parser, fleet_help, handler in (
        (add, "the fleet", "add_command"),
        (remove, "the fleet", "remove_command"),
        (listing, "only this fleet's", "list_command"),
        (dead, "only this fleet's", "dead_letters_command"),
    ):
        parser.add_argument("--fleet", required=parser in (add, remove), help=fleet_help)
        parser.add_argument(
            "--file",
            type=Path,
            default=None,
            help="the webhook file (default: $CSWS_WEBHOOKS_FILE, else beside $CSWS_API_KEYS_FILE)",
        )
        parser.set_defaults(handler=deferred("service.push.cli", handler))


def _webhooks_file(args: argparse.Namespace) -> Path:
    """The webhook file of a command: ``--file``, else ``$CSWS_WEBHOOKS_FILE``, else beside the key file."""
    from .targets import default_webhooks_file

    path = args.file or default_webhooks_file(None)
    if path is None:
        raise ValueError("give the webhook file: --file FILE, or set CSWS_WEBHOOKS_FILE or CSWS_API_KEYS_FILE")
    return Path(path)


def add_command(args: argparse.Namespace) -> int:
    """``csws webhooks add``: check the URL, add it; print the fleet's secret if this made it."""
    from .targets import add_webhook

    allow_private = args.allow_private or os.environ.get(ALLOW_PRIVATE_VARIABLE, "").strip().lower() in {"1", "true"}
    path = _webhooks_file(args)
    secret = add_webhook(path, args.fleet, args.url, allow_private)
    if secret is not None:
        print(secret)
        told = "its signing secret is shown only this once"
    else:
        told = "it shares the fleet's signing secret, shown when its first webhook was added"
    print(f"csws: added the webhook {args.url} of fleet {args.fleet!r} to {path}; {told}", file=sys.stderr)
    return 0


def remove_command(args: argparse.Namespace) -> int:
    """``csws webhooks remove``: take a URL out of a fleet's webhooks."""
    from .targets import remove_webhook

    path = _webhooks_file(args)
    remove_webhook(path, args.fleet, args.url)
    print(f"csws: removed the webhook {args.url} of fleet {args.fleet!r} from {path}", file=sys.stderr)
    return 0


def list_command(args: argparse.Namespace) -> int:
    """``csws webhooks list``: fleet and URL of each webhook, one a line."""
    from .targets import list_webhooks

    for webhook in list_webhooks(_webhooks_file(args)):
        if args.fleet in (None, webhook.fleet):
            print(f"{webhook.fleet}  {webhook.url}")
    return 0


def dead_letters_command(args: argparse.Namespace) -> int:
    """``csws webhooks dead-letters``: the events given up, oldest first: when, tries, webhook, vehicle, error."""
    from service.settings import default_state_db

    from .state import REDIS_SCHEMES, open_push_state, push_db_beside

    db = (
        args.db
        or os.environ.get("CSWS_PUSH_DB")
        or os.environ.get("CSWS_STATE")
        or push_db_beside(os.environ.get("CSWS_STATE_DB") or str(default_state_db()))
    )
    if not db.startswith(REDIS_SCHEMES) and db != ":memory:" and not Path(db).exists():
        raise ValueError(f"{db}: no push state there (give --db FILE or set CSWS_PUSH_DB)")
    state = open_push_state(db)
    try:
        letters = state.dead_letters(f"webhook {args.fleet} " if args.fleet else "webhook ")
    finally:
        state.close()
    for letter in letters:
        when = datetime.fromtimestamp(letter.dead_s, UTC).isoformat(timespec="seconds")
        if args.json:
            row = {
                "dead": when,
                "tries": letter.tries,
                "webhook": letter.sink.split(" ", 2)[2],
                "error": letter.error,
                "event": json.loads(letter.body),
            }
            print(json.dumps(row, ensure_ascii=False))
        else:
            print(f"{when}  {letter.tries} tries  {letter.sink.split(' ', 2)[2]}  {letter.vehicle}  {letter.error}")
    return 0
