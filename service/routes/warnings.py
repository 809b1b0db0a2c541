"""``POST /v1/warning`` and ``POST /v1/warnings``: the warnings for one vehicle, and for a batch answered per
query (:mod:`service.batch_items`; ``?atomic=true``: all or nothing).

Both read their bodies themselves, after the caller's key was checked, and decode them with
msgspec on the work thread (:mod:`service.answering`, :mod:`service.decoding`): a batch of 10,000
queries is never turned into pydantic objects. They take two dependencies, who asks and what
answers: each one FastAPI resolves costs the single query, the hottest route, its share of time.
"""

from __future__ import annotations

import time

from fastapi import APIRouter, Request
from fastapi import Query as QueryParameter
from fastapi.exceptions import RequestValidationError
from fastapi.responses import Response

from ..answer_schemas import Answers, WarningAnswer
from ..deps import AnsweringDep, CallerDep
from ..limits import too_many_queries
from ..schemas import MAX_BATCH, Batch, Query
from ..timing import Stages
from .common import BOUNDED, INVALID_BODY, KEYED, STORE, json_body

__all__ = ["router"]

router = APIRouter(tags=["warnings"])


@router.post(
    "/v1/warning",
    summary="The warning for one vehicle",
    response_model=None,
    responses={200: {"model": WarningAnswer}, **INVALID_BODY, **KEYED, **BOUNDED, **STORE},
    openapi_extra=json_body(Query),
)
async def warning(request: Request, principal: CallerDep, answering: AnsweringDep) -> Response:
    """Answer one query of the caller's fleet."""
    return Response(await answering.one(await request.body(), principal.fleet), media_type="application/json")


def _refuse_oversized(body: bytes) -> None:
    """A 422 for a batch holding more than :data:`MAX_BATCH` queries, before anything is decoded."""
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


#: The ``atomic`` parameter of ``POST /v1/warnings``.
ATOMIC = QueryParameter(
    False,
    description="all or nothing: a 422 naming every problem when any query is bad, as before per-query answers; "
    "by default each bad query gets an error entry at its index and the others are answered",
)


@router.post(
    "/v1/warnings",
    summary=f"The warnings for a batch of up to {MAX_BATCH} queries, in order, each answered or refused alone",
    response_model=None,
    responses={200: {"model": Answers}, **INVALID_BODY, **KEYED, **BOUNDED, **STORE},
    openapi_extra=json_body(Batch),
)
async def warnings(request: Request, principal: CallerDep, answering: AnsweringDep, atomic: bool = ATOMIC) -> Response:
    """Answer a batch of the caller's fleet, in order; the time of each stage is in the Server-Timing header.

    A query the contract refuses or the served networks cannot answer gets an error entry at its index
    (``{"index", "vehicle_id", "error": {"code", "message", "detail"}}``) and its vehicle's session is left
    as it was; the others are answered. A body that is not a batch is a 422, as is any bad query with
    ``atomic=true``.
    """
    body = await request.body()
    started = time.perf_counter()
    _refuse_oversized(body)
    stages = Stages()
    content = await answering.batch(body, principal.fleet, stages, atomic)
    elapsed_ms = (time.perf_counter() - started) * 1000.0
    return Response(content, media_type="application/json", headers={"Server-Timing": stages.header(elapsed_ms)})
