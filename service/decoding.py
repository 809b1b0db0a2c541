"""Request bodies decoded by msgspec, with the constraints of the contract's pydantic models.

The pydantic models of :mod:`service.schemas` are the contract: the OpenAPI schema, and the
422 that names every problem of a body. Validating a batch of 10,000 queries with them
builds a pydantic object per query; msgspec decodes and checks the same JSON into plain
structs in a fraction of the time. :func:`struct_of` makes each struct from its model: the
same fields, types, defaults and constraints (``ge``, ``gt``, ``le``, ``lt``, lengths, patterns), the
model's properties, and the model's own checks (:func:`service.schemas.check_position`,
:func:`service.schemas.check_located`), so there is one definition of what a valid query is.

Like the models, msgspec takes numbers only as JSON numbers (no strings, no booleans), refuses
numbers too large for a float, and refuses unknown fields: every request model forbids them
(``extra="forbid"``), so a misspelt field is a 422 naming it, not a field silently left out.
A body msgspec refuses is validated again by pydantic (:func:`decode`), whose 422 names every
problem; in the rare case that pydantic accepts it, its values are taken as they are.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from types import GenericAlias, UnionType
from typing import TYPE_CHECKING, Annotated, Any, Union, get_args, get_origin

import annotated_types
import msgspec
from fastapi.exceptions import RequestValidationError
from pydantic import BaseModel, TypeAdapter, ValidationError

from .schemas import (
    Batch,
    ForwardTarget,
    Position,
    Query,
    SensorObject,
    VehicleSwitch,
    check_position,
    check_query,
)

__all__ = [
    "struct_of",
    "decode",
    "DecodedPosition",
    "DecodedSensorObject",
    "DecodedQuery",
    "DecodedBatch",
    "DecodedSwitch",
]

#: The pydantic (annotated-types) constraints and the msgspec ``Meta`` argument each becomes.
_CONSTRAINTS = {
    annotated_types.Ge: "ge",
    annotated_types.Gt: "gt",
    annotated_types.Le: "le",
    annotated_types.Lt: "lt",
    annotated_types.MinLen: "min_length",
    annotated_types.MaxLen: "max_length",
}


def _field_type(annotation: Any, metadata: Sequence[Any], structs: dict[type, type]) -> Any:
    """The msgspec type of a model field: nested models as their structs, constraints as ``Meta``."""
    optional = get_origin(annotation) in (Union, UnionType) and type(None) in get_args(annotation)
    inner = next(a for a in get_args(annotation) if a is not type(None)) if optional else annotation
    if get_origin(inner) is list:
        (item,) = get_args(inner)
        inner = GenericAlias(list, (structs.get(item, item),))
    else:
        inner = structs.get(inner, inner)
    meta = {
        name: getattr(item, name) for item in metadata for kind, name in _CONSTRAINTS.items() if isinstance(item, kind)
    }
    for item in metadata:
        if getattr(item, "pattern", None) is not None:  # pydantic's general metadata of Field(pattern=...)
            meta["pattern"] = item.pattern
    if meta:
        inner = Annotated[inner, msgspec.Meta(**meta)]
    return inner | None if optional else inner


def struct_of(
    model: type[BaseModel], structs: dict[type, type] | None = None, checks: Sequence[Callable[[Any], None]] = ()
) -> type[msgspec.Struct]:
    """A msgspec struct that decodes what ``model`` validates.

    Parameters
    ----------
    model
        The pydantic model.
    structs
        The structs of the models nested in it.
    checks
        The model's own checks, run on each decoded struct; each raises ValueError for a bad one.
    """
    structs = structs or {}
    fields = []
    for name, info in model.model_fields.items():
        field_type = _field_type(info.annotation, info.metadata, structs)
        fields.append((name, field_type) if info.is_required() else (name, field_type, info.default))

    def __post_init__(self) -> None:
        for check in checks:
            check(self)

    namespace: dict[str, Any] = {name: value for name, value in vars(model).items() if isinstance(value, property)}
    if checks:  # a struct without checks has no hook: msgspec then calls nothing per decoded item
        namespace["__post_init__"] = __post_init__
    return msgspec.defstruct(
        model.__name__,
        fields,
        namespace=namespace,
        kw_only=True,
        forbid_unknown_fields=model.model_config.get("extra") == "forbid",
        gc=False,
        module=__name__,
    )


if TYPE_CHECKING:
    # To the type checker a decoded struct is its model: it has the same fields, types and properties.
    DecodedPosition = Position
    DecodedForwardTarget = ForwardTarget
    DecodedSensorObject = SensorObject
    DecodedQuery = Query
    DecodedBatch = Batch
    DecodedSwitch = VehicleSwitch
else:
    DecodedPosition = struct_of(Position, checks=(check_position,))
    DecodedForwardTarget = struct_of(ForwardTarget)
    DecodedSensorObject = struct_of(SensorObject)
    DecodedQuery = struct_of(
        Query,
        {Position: DecodedPosition, ForwardTarget: DecodedForwardTarget, SensorObject: DecodedSensorObject},
        checks=(check_query,),
    )
    DecodedBatch = struct_of(Batch, {Query: DecodedQuery})
    DecodedSwitch = struct_of(VehicleSwitch)


def decode(body: bytes, struct: type[Any], adapter: TypeAdapter[Any]) -> Any:
    """A request body decoded into ``struct``; an HTTP 422 naming each bad field otherwise.

    Parameters
    ----------
    body
        The JSON body.
    struct
        What to decode it into (one of the ``Decoded*`` structs).
    adapter
        The pydantic validator of the same model: it names the problems of a body msgspec refuses.

    Raises
    ------
    fastapi.exceptions.RequestValidationError
        When the body is not valid.
    """
    try:
        return msgspec.json.decode(body, type=struct)
    except (msgspec.MsgspecError, UnicodeDecodeError, RecursionError):
        pass  # invalid UTF-8 inside a string, or nesting deeper than the interpreter's stack: pydantic names it
    try:
        model = adapter.validate_json(body)
    except ValidationError as exc:
        raise RequestValidationError(
            [{**e, "loc": ("body", *e["loc"])} for e in exc.errors(include_url=False)]
        ) from None
    try:
        return msgspec.convert(model, struct, from_attributes=True)
    except msgspec.ValidationError as exc:
        raise RequestValidationError([{"loc": ("body",), "msg": str(exc), "type": "value_error"}]) from None
