"""``csws serve``: check the networks, then run the app with uvicorn."""

from __future__ import annotations

import argparse
import os
import sys

from .settings import ServiceSettings
from .workers import bound_socket, listening_socket, serve_forked

__all__ = ["settings_from_args", "main", "add_key_command"]

#: Command-line options and the settings they override.
_OPTIONS = {
    "net": "nets",
    "host": "host",
    "port": "port",
    "workers": "workers",
    "state": "state",
    "state_db": "state_db",
    "session_idle_s": "session_idle_s",
    "update_period_s": "update_period_s",
    "api_keys": "api_keys_file",
    "fcw_settings": "fcw_settings_file",
    "insecure": "insecure",
    "public_docs": "public_docs",
}


def settings_from_args(args: argparse.Namespace) -> ServiceSettings:
    """The environment's settings with the options given on the command line on top."""
    overrides = {
        setting: getattr(args, option)
        for option, setting in _OPTIONS.items()
        if getattr(args, option, None) is not None
    }
    try:
        return ServiceSettings(**overrides)
    except ValueError as exc:
        first = exc.errors()[0] if hasattr(exc, "errors") else None
        if first is None:
            raise ValueError(f"bad service setting: {exc}") from None
        where = ".".join(map(str, first["loc"]))
        message = first["msg"].removeprefix("Value error, ")
        raise ValueError(f"bad service setting {where}: {message}" if where else message) from None


def main(args: argparse.Namespace) -> int:
    """Serve until interrupted; a network, state store or key file that cannot be read ends start-up
    with one line (via ``csws.cli``).

    With ``--workers N`` everything is loaded here, once, and the workers are forked from this
    process (:func:`service.workers.serve_forked`).
    """
    import uvicorn

    from .app import create_app

    settings = settings_from_args(args)
    if settings.workers > 1 and not hasattr(os, "fork"):
        raise ValueError(
            f"--workers {settings.workers} needs a platform with fork(): serve with one worker per "
            "process instead, e.g. several csws serve on other ports behind a load balancer"
        )
    app = create_app(settings)
    networks = len(app.state.service.networks)
    if settings.workers == 1:
        listening = listening_socket(settings.host, settings.port)  # a port in use is one line, before "serving"
        print(
            f"csws: serving {networks} network(s) on http://{settings.host}:{settings.port} (OpenAPI docs at /docs)",
            flush=True,
        )
        uvicorn.Server(uvicorn.Config(app, log_level="warning")).run(sockets=[listening])
        return 0
    master = bound_socket(settings.host, settings.port)
    print(
        f"csws: serving {networks} network(s) with {settings.workers} workers on http://{settings.host}:"
        f"{settings.port} (OpenAPI docs at /docs)",
        flush=True,
    )
    serve_forked(app, master, settings.workers)
    return 0


def add_key_command(args: argparse.Namespace) -> int:
    """``csws keys add``: a new key for a fleet, printed once; its hash goes into the key file."""
    from .keys import KeyRing, add_key

    path = args.file or os.environ.get("CSWS_API_KEYS_FILE")
    if not path:
        raise ValueError("give the key file: --file FILE, or set CSWS_API_KEYS_FILE")
    key = add_key(path, args.fleet, args.role)
    print(key)
    print(
        f"csws: added a key of fleet {args.fleet!r} with role {args.role} to {path} ({len(KeyRing(path))} keys "
        "in all); the key is shown only this once",
        file=sys.stderr,
    )
    return 0
