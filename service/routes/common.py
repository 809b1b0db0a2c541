"""What the routes share: the responses they document, their request bodies, plain JSON answers."""

from __future__ import annotations

from typing import Any

import msgspec
from fastapi.responses import Response
from pydantic import BaseModel

from ..schemas import Message

__all__ = ["KEYED", "STORE", "BOUNDED", "INVALID_BODY", "json_body", "json_response"]

#: What any route of the API may answer on a service with API keys (:mod:`service.security`).
KEYED: dict[int | str, dict[str, Any]] = {
    401: {"model": Message, "description": "no API key, or one not in the key file (services with keys)"}
}
#: What a route that reads or writes vehicles may answer when the state store is in trouble (:mod:`service.store`).
STORE: dict[int | str, dict[str, Any]] = {
    503: {"model": Message, "description": "the state store cannot be read or written now; retry"}
}
#: What a route with a JSON body may answer before it reads it (:mod:`service.limits`).
BOUNDED: dict[int | str, dict[str, Any]] = {
    408: {"model": Message, "description": "the client paused in its body for longer than the body timeout"},
    413: {"model": Message, "description": "the body is larger than the body limit"},
    415: {"model": Message, "description": "the body is not declared Content-Type: application/json"},
}
#: The 422 of routes that read their bodies themselves, as FastAPI documents its own.
INVALID_BODY: dict[int | str, dict[str, Any]] = {
    422: {
        "description": "Validation Error",
        "content": {"application/json": {"schema": {"$ref": "#/components/schemas/HTTPValidationError"}}},
    }
}


def _inlined(schema: Any, definitions: dict[str, Any]) -> Any:
    """``schema`` with every ``{"$ref": "#/$defs/NAME"}`` replaced by the definition it names (they nest, never
    recurse), so that the schema stands on its own inside an operation."""
    if isinstance(schema, list):
        return [_inlined(item, definitions) for item in schema]
    if not isinstance(schema, dict):
        return schema
    if "$ref" in schema:
        named = definitions[schema["$ref"].rsplit("/", 1)[-1]]
        return _inlined({**named, **{k: v for k, v in schema.items() if k != "$ref"}}, definitions)
    return {key: _inlined(value, definitions) for key, value in schema.items()}


def json_body(model: type[BaseModel]) -> dict[str, Any]:
    """The ``openapi_extra`` of a route that reads its body itself (msgspec, :mod:`service.decoding`): the body
    is JSON of ``model``, its schema (examples, constraints) written out in the operation."""
    schema = model.model_json_schema()
    definitions = schema.pop("$defs", {})
    return {
        "requestBody": {
            "required": True,
            "content": {"application/json": {"schema": _inlined(schema, definitions)}},
        }
    }


def json_response(content: Any) -> Response:
    """A JSON response of plain data, floats written in full (no rounding, no re-validation)."""
    return Response(msgspec.json.encode(content), media_type="application/json")
