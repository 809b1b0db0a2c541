"""Operations: ``/healthz`` (alive), ``/readyz`` (networks loaded, state store answering), ``/metrics``."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Security
from fastapi.responses import PlainTextResponse

from ..deps import MetricsDep, NetworksDep, StoreDep, WorkDep
from ..security import doc_reader
from .common import KEYED, STORE

__all__ = ["router"]

router = APIRouter(tags=["operations"])

#: The 401 of ``/metrics``: JSON like every other 401 (:data:`KEYED`), which the metrics' text/plain would hide.
_METRICS_KEYED: dict[int | str, dict[str, Any]] = {
    401: {
        "description": KEYED[401]["description"],
        "content": {"application/json": {"schema": {"$ref": "#/components/schemas/Message"}}},
    }
}


@router.get("/healthz", summary="The process is alive")
async def healthz() -> dict[str, str]:
    """Always ok, without a key: for load balancers and orchestrators."""
    return {"status": "ok"}


@router.get("/readyz", summary="The networks are loaded and the state store answers", responses=STORE)
async def readyz(networks: NetworksDep, store: StoreDep, work: WorkDep) -> dict[str, Any]:
    """The served networks and how many vehicle sessions the state store keeps, without a key."""
    return {
        "status": "ready",
        "networks": [
            {"name": n.name, "lanes": len(n.road_map.lane_ids), "geo_referenced": n.road_map.has_projection}
            for n in networks
        ],
        "vehicle_sessions": await work.run(store.session_count),
    }


@router.get(
    "/metrics",
    summary="Prometheus metrics",
    response_class=PlainTextResponse,
    responses=_METRICS_KEYED,
    dependencies=[Security(doc_reader)],
)
async def prometheus(metrics: MetricsDep) -> PlainTextResponse:
    """The counters in Prometheus text format; a key is needed unless the docs are public."""
    return PlainTextResponse(metrics.exposition(), media_type="text/plain; version=0.0.4")
