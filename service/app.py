"""The FastAPI application: HTTP in, :mod:`csws` library out.

``create_app(settings)`` builds the app (``uvicorn --factory service.app:create_app``);
``service.app:app`` is the app with the settings of the environment, for a plain
``uvicorn service.app:app``. The networks are read when the app is built, so a map that
cannot be read stops start-up. The OpenAPI documentation is at ``/docs`` (Swagger UI),
``/redoc`` and ``/openapi.json``.
"""

from __future__ import annotations

import gc
import logging
import sys
import time
from collections.abc import Callable
from contextlib import asynccontextmanager
from typing import Any

import msgspec
from fastapi import FastAPI, HTTPException, Path, Request
from fastapi import Query as QueryParam
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse, PlainTextResponse, Response
from pydantic import ValidationError

from csws import __version__
from csws.standard import Category

from .answers import QueryErrors, WarningService
from .curves import BBOX_QUERY, NETWORK_QUERY, choose_networks, curve_features, feature_collection, in_bbox, parse_bbox
from .decoding import DecodedBatch, DecodedQuery, DecodedSwitch, decode
from .docs import add_doc_routes
from .horizon import DEFAULT_HORIZON_M, horizon
from .keys import KeyMiddleware, KeyRing, vehicle_key
from .keys import principal as _principal
from .limits import BodyLimit, too_many_queries
from .map import add_map_routes
from .metrics import Metrics, MetricsMiddleware
from .networks import MAX_HORIZON_M, load_networks
from .schemas import (
    BATCH_ADAPTER,
    MAX_BATCH,
    QUERY_ADAPTER,
    SWITCH_ADAPTER,
    Answers,
    Batch,
    Message,
    Query,
    VehicleState,
    VehicleSwitch,
    WarningAnswer,
)
from .settings import ServiceSettings
from .store import StoreUnavailable, open_store
from .timing import Stages
from .vehicles import LoadedVehicles, VehicleRegistry
from .work import WorkThread
from .workers import leave_with_master

__all__ = ["create_app", "MAX_ERRORS_SHOWN"]

logger = logging.getLogger("csws.service")

#: A 422 lists at most this many problems (a bad batch can have 10,000).
MAX_ERRORS_SHOWN = 100

DESCRIPTION = """Map-based curve speed warning (T/ITS 0091-2018) for on-board units and fleet backends.

Positions are `x`, `y` in network metres, or `lon`, `lat` on geo-referenced networks.
Headings are GNSS headings: degrees clockwise from north. Speeds are km/h, distances metres.
"""


def _clean(errors: list[dict[str, Any]]) -> dict[str, Any]:
    """A 422 body: where and what, without echoing the (possibly huge) input."""
    shown = [{"loc": list(e["loc"]), "msg": e["msg"], "type": e["type"]} for e in errors[:MAX_ERRORS_SHOWN]]
    body: dict[str, Any] = {"detail": shown}
    if len(errors) > MAX_ERRORS_SHOWN:
        body["errors_total"] = len(errors)
    return body


def _json(content: Any) -> Response:
    """A JSON response of plain data, floats written in full (no rounding, no re-validation)."""
    return Response(msgspec.json.encode(content), media_type="application/json")


#: What any route of the API may answer on a service with API keys (:mod:`service.keys`).
_KEYED = {401: {"model": Message, "description": "no API key, or one not in the key file (services with keys)"}}
#: What a route that reads or writes vehicles may answer when the state store is in trouble (:mod:`service.store`).
_STORE = {503: {"model": Message, "description": "the state store cannot be read or written now; retry"}}
#: What a route with a JSON body may answer before it reads it (:mod:`service.limits`).
_BOUNDED = {
    408: {"model": Message, "description": "the client paused in its body for longer than the body timeout"},
    413: {"model": Message, "description": "the body is larger than the body limit"},
    415: {"model": Message, "description": "the body is not declared Content-Type: application/json"},
}

#: The 422 of endpoints that read their bodies themselves, as FastAPI documents its own.
_INVALID_BODY = {
    "description": "Validation Error",
    "content": {"application/json": {"schema": {"$ref": "#/components/schemas/HTTPValidationError"}}},
}


def _json_body(schema: str) -> dict[str, Any]:
    """The OpenAPI request body of an endpoint that reads its body itself (see :func:`_document_bodies`)."""
    return {
        "requestBody": {
            "required": True,
            "content": {"application/json": {"schema": {"$ref": f"#/components/schemas/{schema}"}}},
        }
    }


def create_app(settings: ServiceSettings | None = None, clock: Callable[[], float] = time.time) -> FastAPI:
    """Build the service.

    Parameters
    ----------
    settings
        What to serve and how; by default from the ``CSWS_*`` environment.
    clock
        Seconds of the clock that dates sessions in a SQLite state store (Redis keeps its own).

    Raises
    ------
    csws.road.roadmap.NetworkError
        If a network cannot be read.
    OSError
        If the state store cannot be opened, reached or read (one line naming it).
    """
    settings = settings if settings is not None else ServiceSettings()
    networks = load_networks(settings.nets, settings.engine_settings())
    store = open_store(settings, clock)
    try:
        store.check()
    except OSError:
        store.close()
        raise
    registry = VehicleRegistry([n.name for n in networks], [n.engine for n in networks], store)
    service = WarningService(networks, registry, settings.match_settings())
    metrics = Metrics()
    curve_cache: dict[int, list[dict[str, Any]]] = {}
    # The work (queries and batches with their round trips to the state store, the curve index,
    # horizons) runs on a thread of its own, in arrival order (service.work).
    work = WorkThread()
    off_loop = work.run

    @asynccontextmanager
    async def lifespan(_app: FastAPI):
        leave_with_master()
        gc.freeze()  # the networks and engines live as long as the app: keep them out of every collection
        yield
        gc.unfreeze()
        work.close()
        store.close()

    app = FastAPI(
        title="csws", version=__version__, description=DESCRIPTION, lifespan=lifespan, docs_url=None, redoc_url=None
    )  # served from the package (service.docs)
    add_doc_routes(app)
    add_map_routes(app, networks, registry, store, off_loop, {**_KEYED, **_STORE})
    # Innermost first: bodies bounded, then keys (a 401 before any body is read), then metrics over all.
    app.add_middleware(BodyLimit, max_bytes=settings.max_body_bytes, timeout_s=settings.body_timeout_s)
    if settings.api_keys_file is not None:
        app.add_middleware(KeyMiddleware, keyring=KeyRing(settings.api_keys_file), public_docs=settings.public_docs)
    app.add_middleware(MetricsMiddleware, metrics=metrics)
    app.state.service = service
    app.state.settings = settings

    @app.exception_handler(RequestValidationError)
    async def _invalid_request(_request: Request, exc: RequestValidationError) -> JSONResponse:
        return JSONResponse(_clean(list(exc.errors())), status_code=422)

    @app.exception_handler(QueryErrors)
    async def _unanswerable(_request: Request, exc: QueryErrors) -> JSONResponse:
        return JSONResponse(_clean(exc.errors), status_code=422)

    @app.exception_handler(StoreUnavailable)
    async def _store_unavailable(_request: Request, exc: StoreUnavailable) -> JSONResponse:
        logger.warning("%s", exc)
        return JSONResponse({"detail": f"{exc}; retry"}, status_code=503, headers={"Retry-After": "1"})

    @app.exception_handler(Exception)
    async def _unexpected(_request: Request, exc: Exception) -> JSONResponse:
        logger.exception("unexpected error")
        return JSONResponse({"detail": f"internal error: {type(exc).__name__}"}, status_code=500)

    # ------------------------------------------------------------------ warnings
    @app.post(
        "/v1/warning",
        summary="The warning for one vehicle",
        response_model=None,
        responses={200: {"model": WarningAnswer}, 422: _INVALID_BODY, **_KEYED, **_BOUNDED, **_STORE},
        openapi_extra=_json_body("Query"),
        tags=["warnings"],
    )
    async def warning(request: Request) -> Response:
        body, fleet = await request.body(), _principal(request).fleet
        answers = await off_loop(
            lambda: service.answer([decode(body, DecodedQuery, QUERY_ADAPTER)], loc=("body",), fleet=fleet)
        )
        metrics.observe_answers(answers.state, answers.level)
        return Response(answers.json(0), media_type="application/json")

    @app.post(
        "/v1/warnings",
        summary=f"The warnings for a batch of up to {MAX_BATCH} queries, in order",
        response_model=None,
        responses={200: {"model": Answers}, 422: _INVALID_BODY, **_KEYED, **_BOUNDED, **_STORE},
        openapi_extra=_json_body("Batch"),
        tags=["warnings"],
    )
    async def warnings(request: Request) -> Response:
        body, fleet = await request.body(), _principal(request).fleet
        started = time.perf_counter()
        if count := too_many_queries(body, MAX_BATCH):
            raise RequestValidationError(
                [
                    {
                        "loc": ("body", "queries"),
                        "type": "too_long",
                        "msg": f"List should have at most {MAX_BATCH} items, not {count}",
                    }
                ]
            )

        stages = Stages()

        def answer_batch():
            with stages("decode"):
                queries = decode(body, DecodedBatch, BATCH_ADAPTER).queries
            answers = service.answer(queries, fleet=fleet, stages=stages)
            with stages("encode"):
                return answers, answers.batch_json()

        answers, content = await off_loop(answer_batch)
        metrics.observe_answers(answers.state, answers.level)
        elapsed_ms = (time.perf_counter() - started) * 1000.0
        return Response(content, media_type="application/json", headers={"Server-Timing": stages.header(elapsed_ms)})

    # ------------------------------------------------------------------ map
    @app.get("/v1/curves", summary="The curves of the served networks as GeoJSON", tags=["map"], responses=_KEYED)
    async def curves(
        bbox: str | None = BBOX_QUERY,
        network: str | None = NETWORK_QUERY,
    ) -> Response:
        box, chosen = parse_bbox(bbox), choose_networks(networks, network)

        def collection() -> Response:
            features = []
            for i in chosen:
                if i not in curve_cache:
                    curve_cache[i] = curve_features(networks[i])
                features += [f for f in curve_cache[i] if in_bbox(f, box)]
            return _json(feature_collection(features, [networks[i] for i in chosen]))

        return await off_loop(collection)

    @app.get(
        "/v1/horizon", summary="The road ahead of a position: radius profile and CPOIs", tags=["map"], responses=_KEYED
    )
    async def road_ahead(
        x: float | None = QueryParam(default=None, allow_inf_nan=False, description="network x, m"),
        y: float | None = QueryParam(default=None, allow_inf_nan=False, description="network y, m"),
        lon: float | None = QueryParam(default=None, allow_inf_nan=False, description="longitude, degrees"),
        lat: float | None = QueryParam(default=None, allow_inf_nan=False, description="latitude, degrees"),
        heading_deg: float | None = QueryParam(default=None, allow_inf_nan=False, description="degrees from north"),
        lane_id: str | None = QueryParam(default=None, description="lane id (no map matching)"),
        lane_pos_m: float | None = QueryParam(default=None, allow_inf_nan=False, description="lane position, m"),
        route: str | None = QueryParam(default=None, description="route edge ids, comma-separated"),
        network: str | None = QueryParam(default=None, description="the served network (default: best match)"),
        length_m: float = QueryParam(
            default=DEFAULT_HORIZON_M, gt=0, le=MAX_HORIZON_M, allow_inf_nan=False, description="how far ahead, m"
        ),
    ) -> Response:
        given = {k: v for k, v in {"x": x, "y": y, "lon": lon, "lat": lat}.items() if v is not None}
        try:
            query = Query(
                vehicle_id="horizon",
                category=Category.M1,
                speed_kmh=0.0,
                position=given or None,
                heading_deg=heading_deg,
                lane_id=lane_id,
                lane_pos_m=lane_pos_m,
                route=route.split(",") if route else None,
                network=network,
            )
        except ValidationError as exc:
            raise RequestValidationError(
                [{**e, "loc": ("query", *e["loc"])} for e in exc.errors(include_url=False)]
            ) from None

        decoded = msgspec.convert(query, DecodedQuery, from_attributes=True)

        def road() -> Response:
            with registry.read(()) as nobody:  # a position, not a vehicle: no previous lane
                service.check([decoded], nobody, loc=("query",))
                (placement,) = service.place([decoded], nobody)
            if placement.lane_id is None:
                return _json({"matched": None, "fault": placement.reason, "profile": [], "cpois": []})
            ahead = horizon(
                networks[placement.network_index],
                service.cpoi_positions[placement.network_index],
                placement.lane_id,
                placement.lane_pos_m,
                query.route,
                length_m,
            )
            matched = {
                "lane_id": placement.lane_id,
                "lane_pos_m": placement.lane_pos_m,
                "distance_m": placement.distance_m,
            }
            return _json({"matched": matched, "fault": None, **ahead})

        return await off_loop(road)

    # ------------------------------------------------------------------ vehicles
    def _vehicle_state(vehicles: LoadedVehicles, key: str, vehicle_id: str) -> dict[str, Any]:
        status = vehicles.status(key)
        session = vehicles.session(key)
        return {
            "vehicle_id": vehicle_id,
            "switched_on": status.switched_on,
            "category": vehicles.category(key),
            "state": status.state.value,
            "fault": status.fault.value if status.fault is not None else None,
            "activated": status.activated,
            "last_timestamp_s": status.last_timestamp_s,
            "network": networks[session.network_index].name if session and session.lane_id else None,
            "lane_id": session.lane_id if session else None,
        }

    vehicle_path = Path(min_length=1, max_length=128, description="the vehicle")

    @app.put(
        "/v1/vehicles/{vehicle_id}",
        response_model=VehicleState,
        tags=["vehicles"],
        summary="Switch CSWS on or off for a vehicle (5.2) and set its category",
        responses={
            403: {"model": Message, "description": "the key's role may not switch vehicles"},
            422: _INVALID_BODY,
            **_STORE,
            **_KEYED,
            **_BOUNDED,
        },
        openapi_extra=_json_body("VehicleSwitch"),
    )
    async def put_vehicle(request: Request, vehicle_id: str = vehicle_path) -> dict[str, Any]:
        principal = _principal(request)
        if not principal.may_switch:
            raise HTTPException(403, "switching vehicles needs a key with the admin role")
        setting = decode(await request.body(), DecodedSwitch, SWITCH_ADAPTER)
        key = vehicle_key(principal.fleet, vehicle_id)

        def configure(vehicles: LoadedVehicles, _vehicle_ids: Any) -> dict[str, Any]:
            vehicles.configure(key, setting.switched_on, setting.category)
            return _vehicle_state(vehicles, key, vehicle_id)

        return await off_loop(registry.transact, {key}, configure)

    @app.get(
        "/v1/vehicles/{vehicle_id}",
        response_model=VehicleState,
        tags=["vehicles"],
        summary="A vehicle's switch, category and system state",
        responses={
            404: {"model": Message, "description": "a vehicle never queried or set, or expired"},
            **_STORE,
            **_KEYED,
        },
    )
    async def get_vehicle(request: Request, vehicle_id: str = vehicle_path) -> dict[str, Any]:
        key = vehicle_key(_principal(request).fleet, vehicle_id)

        def state() -> dict[str, Any]:
            with registry.read({key}) as vehicles:
                if not vehicles.known(key):
                    raise HTTPException(
                        404, f"unknown vehicle {vehicle_id!r}: never queried or set, or its session expired"
                    )
                return _vehicle_state(vehicles, key, vehicle_id)

        return await off_loop(state)

    # ------------------------------------------------------------------ operations
    @app.get("/healthz", tags=["operations"], summary="The process is alive")
    async def healthz() -> dict[str, str]:
        return {"status": "ok"}

    @app.get(
        "/readyz", tags=["operations"], summary="The networks are loaded and the state store answers", responses=_STORE
    )
    async def readyz() -> dict[str, Any]:
        return {
            "status": "ready",
            "networks": [
                {"name": n.name, "lanes": len(n.road_map.lane_ids), "geo_referenced": n.road_map.has_projection}
                for n in networks
            ],
            "vehicle_sessions": await off_loop(store.session_count),
        }

    @app.get("/metrics", tags=["operations"], summary="Prometheus metrics", response_class=PlainTextResponse)
    async def prometheus() -> PlainTextResponse:
        return PlainTextResponse(metrics.exposition(), media_type="text/plain; version=0.0.4")

    _document_bodies(app)
    return app


def _document_bodies(app: FastAPI) -> None:
    """Put the bodies' schemas (query, batch, switch) into the OpenAPI components (their endpoints read them)."""
    build = app.openapi

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is None:
            schema = build()
            definitions = Batch.model_json_schema(ref_template="#/components/schemas/{model}")
            components = schema.setdefault("components", {}).setdefault("schemas", {})
            components.update(definitions.pop("$defs", {}))
            components["Batch"] = definitions
            switch = VehicleSwitch.model_json_schema(ref_template="#/components/schemas/{model}")
            components.update(switch.pop("$defs", {}))
            components["VehicleSwitch"] = switch
            app.openapi_schema = schema
        return app.openapi_schema

    app.openapi = openapi


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
