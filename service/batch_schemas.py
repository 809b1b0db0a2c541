"""The error entry of a batch's query that was not answered: the contract's part of :mod:`service.batch_items`.

A batch's answers (:class:`service.answer_schemas.Answers`) hold, in order, an answer per query or, for a
query the contract refuses or the served networks cannot answer, a :class:`BatchItemError` naming
its problems as a 422 would.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

__all__ = ["BatchErrorCode", "Problem", "ItemError", "BatchItemError"]

#: Why a query of a batch was not answered (:class:`ItemError`).
BatchErrorCode = Literal["invalid_query", "unanswerable_query"]


class Problem(BaseModel):
    """One problem of a query, as a 422 names it: where, what, and its kind."""

    loc: list[str | int] = Field(description="where: body, queries, the query's index, then the field")
    msg: str = Field(description="what is wrong, for people")
    type: str = Field(description="the kind of problem (pydantic's error type, or value_error)")


class ItemError(BaseModel):
    """Why one query of a batch was not answered."""

    code: BatchErrorCode = Field(
        description="invalid_query: the query breaks the contract (what /v1/warning answers with a 422); "
        "unanswerable_query: valid, but the served networks cannot answer it (unknown lane, edge or network, a "
        "lane position beyond its lane, lon/lat on networks without a projection, no category)"
    )
    message: str = Field(description="the problems in one line, for people")
    detail: list[Problem] = Field(description="each problem, as a 422 would list it")


class BatchItemError(BaseModel):
    """The entry of a batch's answers for a query that was not answered: its vehicle's session is left as it was."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "index": 1,
                    "vehicle_id": "car-2",
                    "error": {
                        "code": "invalid_query",
                        "message": "body.queries.1.speed_kmh: Input should be greater than or equal to 0",
                        "detail": [
                            {
                                "loc": ["body", "queries", 1, "speed_kmh"],
                                "msg": "Input should be greater than or equal to 0",
                                "type": "greater_than_equal",
                            }
                        ],
                    },
                }
            ]
        }
    )

    index: int = Field(description="the query's index in the batch (the entry's own index)")
    vehicle_id: str | None = Field(description="the query's vehicle_id where it is a string, else null")
    error: ItemError = Field(description="why the query was not answered")
