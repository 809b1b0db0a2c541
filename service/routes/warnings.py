"""``POST /v1/warning`` and ``POST /v1/warnings``: the warnings for one vehicle, and for a batch.

Both read their bodies themselves and decode them with msgspec on the work thread
(:mod:`service.decoding`): a batch of 10,000 queries is never turned into pydantic objects.
"""

from __future__ import annotations

import time

from fastapi import APIRouter
from fastapi.exceptions import RequestValidationError
from fastapi.responses import Response

from ..answers import EncodedAnswers, WarningService
from ..decoding import DecodedBatch, DecodedQuery, decode
from ..deps import BodyDep, CallerDep, MetricsDep, ServiceDep, WorkDep
from ..limits import too_many_queries
from ..schemas import BATCH_ADAPTER, MAX_BATCH, QUERY_ADAPTER, Answers, Batch, Query, WarningAnswer
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
async def warning(
    principal: CallerDep, body: BodyDep, service: ServiceDep, metrics: MetricsDep, work: WorkDep
) -> Response:
    """Answer one query of the caller's fleet."""
    answers = await work.run(
        lambda: service.answer([decode(body, DecodedQuery, QUERY_ADAPTER)], loc=("body",), fleet=principal.fleet)
    )
    metrics.observe_answers(answers.state, answers.level)
    return Response(answers.json(0), media_type="application/json")


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


def _answer_batch(service: WarningService, body: bytes, fleet: str, stages: Stages) -> tuple[EncodedAnswers, bytes]:
    """Decode, answer and encode a batch, each stage timed in ``stages``."""
    with stages("decode"):
        queries = decode(body, DecodedBatch, BATCH_ADAPTER).queries
    answers = service.answer(queries, fleet=fleet, stages=stages)
    with stages("encode"):
        return answers, answers.batch_json()


@router.post(
    "/v1/warnings",
    summary=f"The warnings for a batch of up to {MAX_BATCH} queries, in order",
    response_model=None,
    responses={200: {"model": Answers}, **INVALID_BODY, **KEYED, **BOUNDED, **STORE},
    openapi_extra=json_body(Batch),
)
async def warnings(
    principal: CallerDep, body: BodyDep, service: ServiceDep, metrics: MetricsDep, work: WorkDep
) -> Response:
    """Answer a batch of the caller's fleet, in order; the time of each stage is in the Server-Timing header."""
    started = time.perf_counter()
    _refuse_oversized(body)
    stages = Stages()
    answers, content = await work.run(_answer_batch, service, body, principal.fleet, stages)
    metrics.observe_answers(answers.state, answers.level)
    elapsed_ms = (time.perf_counter() - started) * 1000.0
    return Response(content, media_type="application/json", headers={"Server-Timing": stages.header(elapsed_ms)})
