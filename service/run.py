"""``csws serve``: check the networks, then run the app with uvicorn."""

from __future__ import annotations

import argparse
import os

from .settings import ServiceSettings, settings_environment

__all__ = ["settings_from_args", "main"]

#: Command-line options and the settings they override.
_OPTIONS = {"net": "nets", "host": "host", "port": "port", "workers": "workers", "state_db": "state_db",
            "session_idle_s": "session_idle_s", "update_period_s": "update_period_s"}


def settings_from_args(args: argparse.Namespace) -> ServiceSettings:
    """The environment's settings with the options given on the command line on top."""
    overrides = {setting: getattr(args, option) for option, setting in _OPTIONS.items()
                 if getattr(args, option, None) is not None}
    try:
        return ServiceSettings(**overrides)
    except ValueError as exc:
        first = exc.errors()[0] if hasattr(exc, "errors") else None
        reason = f"{'.'.join(map(str, first['loc']))}: {first['msg']}" if first else str(exc)
        raise ValueError(f"bad service setting {reason}") from None


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

    load_networks(settings.nets, settings.engine_settings())  # fail here, once, with one clear line
    os.environ.update(settings_environment(settings))
    print(f"csws: serving with {settings.workers} workers on http://{settings.host}:{settings.port}"
          f" (OpenAPI docs at /docs)", flush=True)
    uvicorn.run("service.app:create_app", factory=True, host=settings.host, port=settings.port,
                workers=settings.workers, log_level="warning")
    return 0
