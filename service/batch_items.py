"""A batch answered per query: each query that cannot be answered gets an error entry of its own.

A fleet backend sends up to 10,000 fixes in one ``POST /v1/warnings``; one bad fix among them
must not cost the others their warnings. A body that is a batch (an object with a list of
``queries`` and nothing else, at most :data:`service.schemas.MAX_BATCH` of them) is answered
with 200: each query the contract refuses (``invalid_query``) or the served networks cannot
answer (``unanswerable_query``) gets, at its own index, a :class:`service.schemas.BatchItemError`,
and its vehicle's session is left as it was; the other queries are answered as usual. A body
that is no batch at all is a 422, as is any bad query with ``?atomic=true``.

The whole batch is first decoded in one go, as before; only a batch that fails is decoded
again query by query, so that a batch of valid queries costs nothing more.
"""

from __future__ import annotations

import json
from collections import defaultdict
from collections.abc import Sequence
from typing import Annotated, Any

import msgspec
import pydantic_core
from fastapi.exceptions import RequestValidationError

from .decoding import DecodedBatch, DecodedQuery, decode
from .problems import clean_problems
from .schemas import BATCH_ADAPTER, MAX_BATCH, QUERY_ADAPTER

__all__ = ["INVALID_QUERY", "UNANSWERABLE_QUERY", "DECODE_ERRORS", "ItemErrors", "decode_items", "item_error"]

#: The query breaks the contract: what ``POST /v1/warning`` answers with a 422.
INVALID_QUERY = "invalid_query"
#: The query is valid, but the served networks cannot answer it (:mod:`service.checks`).
UNANSWERABLE_QUERY = "unanswerable_query"
#: What msgspec raises on a body it cannot decode into the type asked for.
DECODE_ERRORS = (msgspec.MsgspecError, UnicodeDecodeError, RecursionError)
#: Where a batch's queries are: the 422 locations of the problems of query ``i`` go on with ``i``.
QUERIES_LOC = ("body", "queries")


class _RawBatch(msgspec.Struct, forbid_unknown_fields=True):
    """A batch whose queries are kept as their JSON text, to be decoded one by one."""

    queries: Annotated[list[msgspec.Raw], msgspec.Meta(max_length=MAX_BATCH)]


#: The error entries of a batch by the index of their query: ``{"index", "vehicle_id", "error"}`` each.
ItemErrors = dict[int, dict[str, Any]]


def item_error(index: int, vehicle_id: str | None, code: str, problems: list[dict[str, Any]]) -> dict[str, Any]:
    """The error entry (the contract's BatchItemError) of query ``index`` of a batch, from its problems as
    pydantic lists them (their locations within the body)."""
    detail = clean_problems(problems)
    message = "; ".join(f"{'.'.join(map(str, problem['loc']))}: {problem['msg']}" for problem in detail)
    return {"index": index, "vehicle_id": vehicle_id, "error": {"code": code, "message": message, "detail": detail}}


def _vehicle_id(raw: bytes) -> str | None:
    """The vehicle id of a query's JSON where it is a string of at most 128 characters, else None."""
    try:
        query = pydantic_core.from_json(raw, allow_inf_nan=True)
    except ValueError:
        return None
    vehicle_id = query.get("vehicle_id") if isinstance(query, dict) else None
    return vehicle_id if isinstance(vehicle_id, str) and 0 < len(vehicle_id) <= 128 else None


def _loose_items(body: bytes) -> list[bytes] | None:
    """The queries of a batch that msgspec refuses as a whole, each as JSON of its own, where the body is a batch
    with NaN or Infinity among its numbers (pydantic reads them, and names them in the query's error entry);
    None where the body is no batch at all."""
    try:
        parsed = pydantic_core.from_json(body, allow_inf_nan=True)
    except ValueError:
        return None
    if not (isinstance(parsed, dict) and list(parsed) == ["queries"] and isinstance(parsed["queries"], list)):
        return None
    if len(parsed["queries"]) > MAX_BATCH:
        return None
    return [json.dumps(query).encode() for query in parsed["queries"]]


def _decode_item(index: int, raw: bytes) -> DecodedQuery | dict[str, Any]:
    """Query ``index`` of a batch decoded, or its error entry."""
    try:
        decoded: DecodedQuery = decode(raw, DecodedQuery, QUERY_ADAPTER)
    except RequestValidationError as exc:
        problems = [{**problem, "loc": (*QUERIES_LOC, index, *problem["loc"][1:])} for problem in exc.errors()]
        return item_error(index, _vehicle_id(raw), INVALID_QUERY, problems)
    return decoded


def decode_items(body: bytes) -> tuple[Sequence[DecodedQuery | None], ItemErrors]:
    """A batch's queries decoded (None where a query is invalid), and the error entries of the invalid ones.

    Raises
    ------
    fastapi.exceptions.RequestValidationError
        When the body is not a batch at all (not JSON, not an object with ``queries`` alone, too many).
    """
    try:
        return msgspec.json.decode(body, type=DecodedBatch).queries, {}
    except DECODE_ERRORS:
        pass
    try:
        items = [bytes(item) for item in msgspec.json.decode(body, type=_RawBatch).queries]
    except DECODE_ERRORS:
        loose = _loose_items(body)
        if loose is None:
            return decode(body, DecodedBatch, BATCH_ADAPTER).queries, {}  # the 422 naming what is wrong
        items = loose
    queries: list[DecodedQuery | None] = []
    errors: ItemErrors = {}
    for index, item in enumerate(items):
        decoded = _decode_item(index, item)
        if isinstance(decoded, dict):
            errors[index] = decoded
            queries.append(None)
        else:
            queries.append(decoded)
    return queries, errors


def problems_by_query(problems: Sequence[dict[str, Any]]) -> dict[int, list[dict[str, Any]]]:
    """The problems of :class:`service.checks.QueryErrors` (located at ``body.queries.i...``) by query index."""
    by_index: dict[int, list[dict[str, Any]]] = defaultdict(list)
    for problem in problems:
        by_index[problem["loc"][len(QUERIES_LOC)]].append(problem)
    return by_index
