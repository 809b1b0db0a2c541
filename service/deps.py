"""The routes' shared objects as FastAPI dependencies, read from the app's state (:func:`service.app.create_app`).

Each alias (``ServiceDep``, ``RegistryDep``, ...) is ``Annotated[type, Depends(reader)]``; a test
replaces one through ``app.dependency_overrides[reader]``. The readers are coroutines that return
what the app built once (FastAPI would run plain functions on its thread pool), so resolving them
costs a call each and builds nothing per request. Who asks comes from :mod:`service.security`.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Request

from .answering import Answering
from .answers import WarningService
from .map import MapData
from .metrics import Metrics
from .networks import ServedNetwork
from .security import AdminDep, CallerDep
from .store import StateStore
from .vehicles import VehicleRegistry
from .work import WorkThread

__all__ = [
    "answering",
    "warning_service",
    "vehicle_registry",
    "metrics",
    "served_networks",
    "state_store",
    "trace_thread",
    "work_thread",
    "raw_body",
    "map_data",
    "AnsweringDep",
    "ServiceDep",
    "RegistryDep",
    "MetricsDep",
    "NetworksDep",
    "StoreDep",
    "TraceWorkDep",
    "WorkDep",
    "BodyDep",
    "MapDataDep",
    "CallerDep",
    "AdminDep",
]


async def answering(request: Request) -> Answering:
    """What answers the warning routes' bodies: the service on the work thread, its answers counted."""
    answers: Answering = request.app.state.answering
    return answers


async def warning_service(request: Request) -> WarningService:
    """The service that answers queries."""
    service: WarningService = request.app.state.service
    return service


async def vehicle_registry(request: Request) -> VehicleRegistry:
    """The vehicles' sessions and settings."""
    registry: VehicleRegistry = request.app.state.registry
    return registry


async def metrics(request: Request) -> Metrics:
    """The Prometheus counters."""
    counters: Metrics = request.app.state.metrics
    return counters


async def served_networks(request: Request) -> list[ServedNetwork]:
    """The served networks, in the order of the settings."""
    networks: list[ServedNetwork] = request.app.state.service.networks
    return networks


async def state_store(request: Request) -> StateStore:
    """The state store keeping the vehicles (SQLite or Redis)."""
    store: StateStore = request.app.state.store
    return store


async def work_thread(request: Request) -> WorkThread:
    """The thread that runs the work of the requests in arrival order (:mod:`service.work`)."""
    work: WorkThread = request.app.state.work
    return work


async def trace_thread(request: Request) -> WorkThread:
    """The thread that matches whole traces (``POST /v1/match``), beside the warnings' (:mod:`service.app`)."""
    traces: WorkThread = request.app.state.traces
    return traces


async def map_data(request: Request) -> MapData:
    """What the map routes draw (the page, the curves' and roads' features)."""
    data: MapData = request.app.state.map_data
    return data


async def raw_body(request: Request) -> bytes:
    """The request's JSON body as bytes, for msgspec to decode (:mod:`service.decoding`) on the work thread."""
    return await request.body()


AnsweringDep = Annotated[Answering, Depends(answering)]
ServiceDep = Annotated[WarningService, Depends(warning_service)]
RegistryDep = Annotated[VehicleRegistry, Depends(vehicle_registry)]
MetricsDep = Annotated[Metrics, Depends(metrics)]
NetworksDep = Annotated[list[ServedNetwork], Depends(served_networks)]
StoreDep = Annotated[StateStore, Depends(state_store)]
WorkDep = Annotated[WorkThread, Depends(work_thread)]
TraceWorkDep = Annotated[WorkThread, Depends(trace_thread)]
BodyDep = Annotated[bytes, Depends(raw_body)]
MapDataDep = Annotated[MapData, Depends(map_data)]
