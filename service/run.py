"""``csws serve``: check the networks, then run the app with uvicorn."""

from __future__ import annotations

import argparse
import logging
import os
import sys
import time
from pathlib import Path
from typing import Any, cast

from .access_log import AccessFormat, AccessLog
from .guard import connection_limits, serve
from .settings import ServiceSettings
from .workers import bound_socket, serve_forked, start_listening

__all__ = ["settings_from_args", "served_url", "configure_logging", "main"]

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
    "warning_settings": "warning_settings_file",
    "insecure": "insecure",
    "public_docs": "public_docs",
    "mqtt": "mqtt",
    "webhooks": "webhooks_file",
    "webhook_allow_private": "webhook_allow_private",
    "push_db": "push_db",
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


def configure_logging(level: str) -> None:
    """The service's log (``csws.*``, uvicorn's apart) on standard error at ``level``: one line per record,
    with its time, level and logger."""
    logging.basicConfig(
        stream=sys.stderr,
        level=level.upper(),
        format="%(asctime)s %(levelname)s %(name)s: %(message)s",
    )
    logging.getLogger("csws").setLevel(level.upper())


def _loading(number: int, count: int, path: Path) -> None:
    """A start-up line before each network is read: which, and how far start-up is (on standard output, with
    the line saying where the service serves; standard error keeps an error to its one line)."""
    print(f"csws: loading network {number} of {count}: {path}", flush=True)


def _built(settings: ServiceSettings, access_log: AccessFormat | None) -> Any:
    """The app of ``settings`` (networks read, state store checked), with the start-up lines, and its access log."""
    from .app import create_app

    started = time.perf_counter()
    app = create_app(settings, progress=_loading)
    lanes = sum(len(network.road_map.lane_ids) for network in app.state.service.networks)
    store = f"Redis {settings.state}" if settings.state else f"SQLite {settings.state_db}"
    print(
        f"csws: loaded {len(app.state.service.networks)} network(s), {lanes} lanes, in "
        f"{time.perf_counter() - started:.1f} s; vehicle state in {store}",
        flush=True,
    )
    if access_log is not None:
        app.state.metrics.access_log = AccessLog(access_log)
    return app


def main(args: argparse.Namespace) -> int:
    """Serve until interrupted; a network, state store or key file that cannot be read ends start-up
    with one line (via ``csws.cli``).

    The address is bound first, so that one in use is the only line; then the networks are read, a line
    before each, and the line saying where the service is ready. With ``--workers N`` everything is
    loaded here, once, and the workers are forked from this process (:func:`service.workers.serve_forked`).
    """
    settings = settings_from_args(args)
    if settings.workers > 1 and not hasattr(os, "fork"):
        raise ValueError(
            f"--workers {settings.workers} needs a platform with fork(): serve with one worker per "
            "process instead, e.g. several csws serve on other ports behind a load balancer"
        )
    log_level = getattr(args, "log_level", None) or "warning"
    configure_logging(log_level)
    # A port in use is one line, before anything is read (service.workers.bound_socket).
    bound = bound_socket(settings.host, settings.port)
    try:
        app = _built(settings, cast("AccessFormat | None", getattr(args, "access_log", None)))
    except BaseException:
        bound.close()
        raise
    names = [network.name for network in app.state.service.networks]
    networks = ", ".join(names) if len(names) <= 3 else f"{len(names)} networks"
    limits = connection_limits(settings.head_timeout_s)
    url = served_url(settings.host, bound.getsockname()[1])
    with_workers = f" with {settings.workers} workers" if settings.workers > 1 else ""
    print(f"csws: serving {networks}{with_workers} on {url} (OpenAPI docs at /docs)", flush=True)
    if settings.workers == 1:
        serve(app, start_listening(bound), limits, log_level)
    else:
        serve_forked(app, bound, settings.workers, limits, log_level)
    return 0
