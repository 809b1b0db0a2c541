"""The FastAPI application: HTTP in, :mod:`csws` library out.

``create_app(settings)`` builds the app (``uvicorn --factory service.app:create_app``);
``service.app:app`` is the app with the settings of the environment, for a plain
``uvicorn service.app:app``. The networks are read when the app is built, so a map that
cannot be read stops start-up. The routes live in routers by concern (:mod:`service.routes`)
and take what they share from the app's state through dependencies (:mod:`service.deps`,
:mod:`service.security`). The OpenAPI documentation is at ``/docs`` (Swagger UI), ``/redoc``
and ``/openapi.json``.
"""

from __future__ import annotations

import gc
import logging
import sys
import time
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager
from pathlib import Path
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse, Response
from starlette.requests import ClientDisconnect

from csws import __version__

from .answering import Answering
from .answers import QueryErrors, WarningService
from .fcw_settings import FleetFcwSettings
from .headers import ResponseHeaders
from .keys import KeyRing
from .limits import BodyLimit, BodyRefused, refused
from .map import CompressedGets, MapData
from .metrics import Metrics, MetricsMiddleware
from .networks import load_networks
from .problems import MAX_ERRORS_SHOWN, MAX_MESSAGE_CHARS, problem_body
from .push import start_service_push
from .routes import docs, events, map, match, ops, traccar, vehicles, warnings, webhooks
from .settings import ServiceSettings
from .store import StoreUnavailable, open_store
from .vehicles import VehicleRegistry
from .warning_settings import FleetWarningSettings
from .work import WorkThread
from .workers import leave_with_master

__all__ = ["create_app", "MAX_ERRORS_SHOWN", "MAX_MESSAGE_CHARS"]

logger = logging.getLogger("csws.service")


DESCRIPTION = """Map-based curve speed warning (T/ITS 0091-2018) for on-board units and fleet backends.

Positions are `x`, `y` in network metres, or `lon`, `lat` on geo-referenced networks.
Headings are GNSS headings: degrees clockwise from north. Speeds are km/h, distances metres.
"""


async def _invalid_request(_request: Request, exc: Exception) -> JSONResponse:
    """A 422 for a request FastAPI or a route found invalid."""
    assert isinstance(exc, RequestValidationError)
    return JSONResponse(problem_body(list(exc.errors())), status_code=422)


async def _unanswerable(_request: Request, exc: Exception) -> JSONResponse:
    """A 422 for queries the networks cannot answer (:class:`service.answers.QueryErrors`)."""
    assert isinstance(exc, QueryErrors)
    return JSONResponse(problem_body(exc.errors), status_code=422)


async def _store_unavailable(_request: Request, exc: Exception) -> JSONResponse:
    """A 503 to retry when the state store is in trouble."""
    logger.warning("%s", exc)
    return JSONResponse({"detail": f"{exc}; retry"}, status_code=503, headers={"Retry-After": "1"})


async def _client_gone(_request: Request, _exc: Exception) -> Response:
    """The client went away in the middle of its body: nobody reads this answer, nothing is wrong here."""
    return Response(status_code=400)


async def _unexpected(_request: Request, exc: Exception) -> JSONResponse:
    """A 500 naming only the kind of error; the traceback goes to the log."""
    logger.exception("unexpected error")
    return JSONResponse({"detail": f"internal error: {type(exc).__name__}"}, status_code=500)


def _share(
    app: FastAPI,
    settings: ServiceSettings,
    clock: Callable[[], float],
    progress: Callable[[int, int, Path], None] | None = None,
) -> None:
    """Build what the routes share (:mod:`service.deps`) into ``app.state``.

    Raises
    ------
    csws.road.roadmap.NetworkError
        If a network cannot be read.
    OSError
        If the state store cannot be opened, reached or read.
    ValueError
        If the API key file or a settings file (FCW, warning) cannot be read; read before the store opens.
    """
    networks = load_networks(settings.nets, settings.engine_settings(), progress)
    keyring = KeyRing(settings.api_keys_file) if settings.api_keys_file is not None else None
    fcw_settings = FleetFcwSettings(settings.fcw_settings_file)
    warning_settings = FleetWarningSettings(settings.engine_settings().warning, settings.warning_settings_file)
    store = open_store(settings, clock)
    try:
        store.check()
    except OSError:
        store.close()
        raise
    registry = VehicleRegistry([n.name for n in networks], [n.engine for n in networks], store)
    state = app.state
    state.settings, state.store, state.registry = settings, store, registry
    state.service = WarningService(networks, registry, settings.match_settings(), fcw_settings, warning_settings)
    state.metrics, state.map_data = Metrics(), MapData(networks)
    # The work (queries and batches with their round trips to the state store, the curve index,
    # horizons) runs on a thread of its own, in arrival order (service.work).
    state.work = WorkThread()
    # Whole traces (POST /v1/match: thousands of fixes, seconds of work) on a thread of their own, so that the
    # warnings never queue behind one; the two share the interpreter, each getting its turns.
    state.traces = WorkThread("csws-traces", pause_gc=False)
    state.answering = Answering(state.service, state.work, state.metrics)
    state.keyring = keyring


@asynccontextmanager
async def _lifespan(app: FastAPI) -> AsyncIterator[None]:
    """Keep the networks out of the garbage collector and push the events while serving; close the work thread and
    the store after."""
    leave_with_master()
    gc.freeze()  # the networks and engines live as long as the app: keep them out of every collection
    # Every worker starts push; a lease lets one deliver at a time (service.push).
    stop_push = start_service_push(app.state.settings, app.state.store, app.state.metrics)
    yield
    stop_push()
    gc.unfreeze()
    app.state.work.close()
    app.state.traces.close()
    app.state.store.close()


def create_app(
    settings: ServiceSettings | None = None,
    clock: Callable[[], float] = time.time,
    progress: Callable[[int, int, Path], None] | None = None,
) -> FastAPI:
    """Build the service.

    Parameters
    ----------
    settings
        What to serve and how; by default from the ``CSWS_*`` environment.
    clock
        Seconds of the clock that dates sessions in a SQLite state store (Redis keeps its own).
    progress
        Called with the number of each network, their count and its file before it is read.

    Raises
    ------
    csws.road.roadmap.NetworkError
        If a network cannot be read.
    OSError
        If the state store cannot be opened, reached or read (one line naming it).
    ValueError
        If the API key file, the FCW settings file or the warning settings file cannot be read.
    """
    settings = settings if settings is not None else ServiceSettings()
    app = FastAPI(
        title="csws",
        version=__version__,
        description=DESCRIPTION,
        lifespan=_lifespan,
        openapi_url=None,  # served, with the docs, from the package and behind the key (service.routes.docs)
        docs_url=None,
        redoc_url=None,
    )
    _share(app, settings, clock, progress)
    docs.mount_static(app)
    routers = (
        warnings.router,
        traccar.router,
        vehicles.router,
        events.router,
        webhooks.router,
        match.router,
        map.router,
    )
    for router in (*routers, ops.router, docs.router):
        app.include_router(router)
    # Innermost first: security headers (on the page before it is gzipped), answers to GETs gzipped,
    # bodies bounded, then metrics over all.
    app.add_middleware(ResponseHeaders)
    app.add_middleware(CompressedGets)
    app.add_middleware(BodyLimit, max_bytes=settings.max_body_bytes, timeout_s=settings.body_timeout_s)
    app.add_middleware(MetricsMiddleware, metrics=app.state.metrics)
    app.add_exception_handler(RequestValidationError, _invalid_request)
    app.add_exception_handler(QueryErrors, _unanswerable)
    app.add_exception_handler(StoreUnavailable, _store_unavailable)
    app.add_exception_handler(BodyRefused, refused)
    app.add_exception_handler(ClientDisconnect, _client_gone)
    app.add_exception_handler(Exception, _unexpected)
    return app


def __getattr__(name: str) -> Any:
    """``service.app:app``: the app with the environment's settings, built on first use."""
    if name != "app":
        raise AttributeError(name)
    try:
        application = create_app()
    except (ValueError, OSError) as exc:
        print(f"csws: error: {exc}", file=sys.stderr)
        raise SystemExit(2) from None
    globals()["app"] = application
    return application
