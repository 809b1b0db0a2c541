"""``csws serve``: check the networks, then run the app with uvicorn."""

from __future__ import annotations

import argparse
import os
import sys

from .settings import ServiceSettings, settings_environment
from .workers import MASTER_PID_VARIABLE, listen_as_tcp

__all__ = ["settings_from_args", "main", "add_key_command"]

#: Command-line options and the settings they override.
_OPTIONS = {"net": "nets", "host": "host", "port": "port", "workers": "workers", "state": "state",
            "state_db": "state_db",
            "session_idle_s": "session_idle_s", "update_period_s": "update_period_s", "api_keys": "api_keys_file",
            "insecure": "insecure", "public_docs": "public_docs"}


def settings_from_args(args: argparse.Namespace) -> ServiceSettings:
    """The environment's settings with the options given on the command line on top."""
    overrides = {setting: getattr(args, option) for option, setting in _OPTIONS.items()
                 if getattr(args, option, None) is not None}
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
    """Serve until interrupted; a network that cannot be read ends start-up with one line (via ``csws.cli``)."""
    import uvicorn

    from .app import create_app

    settings = settings_from_args(args)
    if settings.workers == 1:
        app = create_app(settings)
        print(f"csws: serving {len(app.state.service.networks)} network(s) on http://{settings.host}:{settings.port}"
              f" (OpenAPI docs at /docs)", flush=True)
        uvicorn.run(app, host=settings.host, port=settings.port, log_level="warning")
        return 0
    from .networks import load_networks
    from .store import open_store

    # Fail here, once, with one clear line, rather than in every worker (a respawn loop).
    load_networks(settings.nets, settings.engine_settings())
    store = open_store(settings)
    try:
        store.check()
    finally:
        store.close()
    if settings.api_keys_file is not None:
        from .keys import KeyRing

        KeyRing(settings.api_keys_file)
    os.environ.update(settings_environment(settings))
    os.environ[MASTER_PID_VARIABLE] = str(os.getpid())  # the workers leave when this process is gone
    listen_as_tcp()
    print(f"csws: serving with {settings.workers} workers on http://{settings.host}:{settings.port}"
          f" (OpenAPI docs at /docs)", flush=True)
    uvicorn.run("service.app:create_app", factory=True, host=settings.host, port=settings.port,
                workers=settings.workers, log_level="warning")
    return 0


def add_key_command(args: argparse.Namespace) -> int:
    """``csws keys add``: a new key for a fleet, printed once; its hash goes into the key file."""
    from .keys import KeyRing, add_key

    path = args.file or os.environ.get("CSWS_API_KEYS_FILE")
    if not path:
        raise ValueError("give the key file: --file FILE, or set CSWS_API_KEYS_FILE")
    key = add_key(path, args.fleet, args.role)
    print(key)
    print(f"csws: added a key of fleet {args.fleet!r} with role {args.role} to {path} ({len(KeyRing(path))} keys "
          "in all); the key is shown only this once", file=sys.stderr)
    return 0
