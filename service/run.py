"""``csws serve``: check the networks, then run the app with uvicorn."""

from __future__ import annotations

import argparse
import os
import sys

from .guard import connection_limits, serve
from .settings import ServiceSettings
from .workers import bound_socket, listening_socket, serve_forked

__all__ = ["settings_from_args", "served_url", "main", "add_key_command"]

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


def served_url(host: str, port: int) -> str:
    """The URL of the service on ``host:port``, an IPv6 address in brackets (RFC 3986)."""
    return f"http://[{host}]:{port}" if ":" in host else f"http://{host}:{port}"


def main(args: argparse.Namespace) -> int:
    """Serve until interrupted; a network, state store or key file that cannot be read ends start-up
    with one line (via ``csws.cli``).

    With ``--workers N`` everything is loaded here, once, and the workers are forked from this
    process (:func:`service.workers.serve_forked`).
    """
    from .app import create_app

    settings = settings_from_args(args)
    if settings.workers > 1 and not hasattr(os, "fork"):
        raise ValueError(
            f"--workers {settings.workers} needs a platform with fork(): serve with one worker per "
            "process instead, e.g. several csws serve on other ports behind a load balancer"
        )
    app = create_app(settings)
    networks = len(app.state.service.networks)
    limits = connection_limits(settings.head_timeout_s)
    # A port in use is one line, before "serving" (service.workers.bound_socket).
    bound = (
        listening_socket(settings.host, settings.port)
        if settings.workers == 1
        else bound_socket(settings.host, settings.port)
    )
    url = served_url(settings.host, bound.getsockname()[1])
    with_workers = f" with {settings.workers} workers" if settings.workers > 1 else ""
    print(f"csws: serving {networks} network(s){with_workers} on {url} (OpenAPI docs at /docs)", flush=True)
    if settings.workers == 1:
        serve(app, bound, limits)
    else:
        serve_forked(app, bound, settings.workers, limits)
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
