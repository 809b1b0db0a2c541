"""``POST /v1/traccar``: a position as Traccar's JSON forwarding sends it, answered like ``POST /v1/warning``.

Traccar is pointed at it with ``forward.url``, ``forward.type=json`` and the fleet's key in
``forward.header`` (docs/traccar.md). The payload is read and answered on the work thread, like
every query (:mod:`service.traccar` maps it).
"""

from __future__ import annotations

import time
from typing import Annotated

from fastapi import APIRouter, Query, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import Response
from pydantic import ValidationError

from ..answer_schemas import WarningAnswer
from ..answering import Answering
from ..deps import AnsweringDep, CallerDep
from ..traccar import IdSource, Ignored, TraccarForward, query_of
from .common import BOUNDED, INVALID_BODY, KEYED, STORE, json_body

__all__ = ["router"]

router = APIRouter(tags=["warnings"])


def _answer(answering: Answering, body: bytes, fleet: str, id_source: IdSource, now_s: float) -> tuple[int, bytes]:
    """The status and JSON answer of a forwarded position (on the work thread)."""
    try:
        forward = TraccarForward.model_validate_json(body)
    except ValidationError as exc:
        raise RequestValidationError(
            [{**e, "loc": ("body", *e["loc"])} for e in exc.errors(include_url=False, include_context=False)]
        ) from None
    try:
        query = query_of(forward, id_source, now_s)
    except ValueError as exc:
        raise RequestValidationError(
            [{"loc": ("body", "device", id_source.value), "msg": str(exc), "type": "value_error"}]
        ) from None
    if isinstance(query, Ignored):
        return 202, query.model_dump_json().encode()
    answers = answering.service.answer([query], loc=("body",), fleet=fleet)
    answering.metrics.observe_answers(answers.state, answers.level)
    return 200, answers.json(0)


@router.post(
    "/v1/traccar",
    summary="The warning for a position forwarded by Traccar (forward.type=json)",
    response_model=None,
    responses={
        200: {"model": WarningAnswer},
        202: {"model": Ignored, "description": "not evaluated: Traccar marks the position invalid or outdated"},
        **INVALID_BODY,
        **KEYED,
        **BOUNDED,
        **STORE,
    },
    openapi_extra=json_body(TraccarForward),
)
async def traccar(
    request: Request,
    principal: CallerDep,
    answering: AnsweringDep,
    vehicle_id: Annotated[
        IdSource, Query(description="the device field that is the vehicle id: uniqueId (default) or name")
    ] = IdSource.UNIQUE_ID,
) -> Response:
    """Answer one position of the caller's fleet as Traccar forwards it (docs/traccar.md)."""
    body = await request.body()
    status, content = await answering.work.run(_answer, answering, body, principal.fleet, vehicle_id, time.time())
    return Response(content, status_code=status, media_type="application/json")
