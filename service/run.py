"""``csws serve``: check the networks, then run the app with uvicorn."""

from __future__ import annotations

import argparse
import os

from .guard import connection_limits, serve
from .settings import ServiceSettings
from .workers import bound_socket, listening_socket, serve_forked

__all__ = ["settings_from_args", "served_url", "main"]

#: Command-line options and the settings they override.
_OPTIONS = {
    "net": "nets",
    "test_tracks": "test_tracks",
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
    names = [network.name for network in app.state.service.networks]
    networks = ", ".join(names) if len(names) <= 3 else f"{len(names)} networks"
    limits = connection_limits(settings.head_timeout_s)
    # A port in use is one line, before "serving" (service.workers.bound_socket).
    bound = (
        listening_socket(settings.host, settings.port)
        if settings.workers == 1
        else bound_socket(settings.host, settings.port)
    )
    url = served_url(settings.host, bound.getsockname()[1])
    with_workers = f" with {settings.workers} workers" if settings.workers > 1 else ""
    print(f"csws: serving {networks}{with_workers} on {url} (OpenAPI docs at /docs)", flush=True)
    if settings.workers == 1:
        serve(app, bound, limits)
    else:
        serve_forked(app, bound, settings.workers, limits)
    return 0
