"""What a 422 says of each problem of a request: where, what, and its kind, without echoing the input.

One wording for the 422 of a request and for the error entry of a query in a batch
(:mod:`service.batch_items`): an unknown field is named with the known field it most resembles,
and a message is cut, so that a huge or hostile body never makes a huge answer.
"""

from __future__ import annotations

from typing import Any

from .match_schemas import Trace, TraceFix
from .schemas import REQUEST_FIELDS, unknown_field_message

__all__ = ["MAX_ERRORS_SHOWN", "MAX_MESSAGE_CHARS", "KNOWN_FIELDS", "cut", "clean_problems", "problem_body"]

#: A 422 lists at most this many problems (a bad batch can have 10,000).
MAX_ERRORS_SHOWN = 100
#: Each problem's message is cut to this many characters (values it echoes are cut shorter,
#: :data:`service.checks.SHOWN_CHARS`).
MAX_MESSAGE_CHARS = 300
#: Every field name of every request body (an unknown one is named with the closest of these).
KNOWN_FIELDS = REQUEST_FIELDS | frozenset(Trace.model_fields) | frozenset(TraceFix.model_fields)


def cut(text: str) -> str:
    """``text`` cut to :data:`MAX_MESSAGE_CHARS` characters, the cut marked with an ellipsis."""
    return text if len(text) <= MAX_MESSAGE_CHARS else text[:MAX_MESSAGE_CHARS] + "..."


def _message(error: dict[str, Any]) -> str:
    """What a 422 says of one problem: an unknown field named with the known field it resembles."""
    if error["type"] == "extra_forbidden" and error["loc"]:
        return unknown_field_message(str(error["loc"][-1]), KNOWN_FIELDS)
    return cut(error["msg"])


def clean_problems(errors: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The first :data:`MAX_ERRORS_SHOWN` problems as a 422 lists them: ``loc``, ``msg`` and ``type`` alone."""
    return [
        {
            "loc": [cut(str(part)) if isinstance(part, str) else part for part in e["loc"]],
            "msg": _message(e),
            "type": e["type"],
        }
        for e in errors[:MAX_ERRORS_SHOWN]
    ]


def problem_body(errors: list[dict[str, Any]]) -> dict[str, Any]:
    """A 422 body: ``detail`` listing the problems, and ``errors_total`` where there were more than it shows."""
    body: dict[str, Any] = {"detail": clean_problems(errors)}
    if len(errors) > MAX_ERRORS_SHOWN:
        body["errors_total"] = len(errors)
    return body
