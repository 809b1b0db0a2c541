"""``/v1/webhooks``: a fleet's admin configures its own fleet's webhooks, and reads its dead letters.

The routes change the very file ``csws webhooks`` changes (:mod:`service.push.targets`, the same
functions: under the file's lock, written at once, read again by every worker within a second), so
the command line and the API see one list. They need a key with the admin role and reach only its
fleet's webhooks: another fleet's URLs do not exist for it. A service without API keys has no fleet
to name (its events carry the fleet ``""``): there the routes answer 403, and the service's admin
uses ``csws webhooks``.

A URL is checked by the address rules (:mod:`service.push.addresses`) when it is added, a refusal
being a 422 that names the rule, and again at every delivery. Adding one resolves its host: the
file's reads and writes and that lookup run on a thread of the default executor, never on the event
loop, nor on the work thread, where a slow name server would hold up the queries behind it.
"""

from __future__ import annotations

import asyncio
import logging
from datetime import UTC, datetime
from pathlib import Path
from typing import Annotated, Any

import msgspec
from fastapi import APIRouter, Depends, HTTPException, Query, Request, Response
from pydantic import BaseModel, Field, TypeAdapter

from ..decoding import decode
from ..deps import BodyDep
from ..push import push_config
from ..push.addresses import UnsafeTarget
from ..push.state import open_push_state
from ..push.targets import (
    DuplicateWebhook,
    TooManyWebhooks,
    UnknownWebhook,
    add_webhook,
    list_webhooks,
    remove_webhook,
)
from ..schemas import Message
from ..security import CallerDep
from .common import BOUNDED, KEYED, json_body
from .events import EventDocument

__all__ = [
    "router",
    "fleet_admin",
    "FleetAdminDep",
    "WebhookUrl",
    "FleetWebhooks",
    "WebhookAdded",
    "DeadLetterDocument",
    "FleetDeadLetters",
]

router = APIRouter(prefix="/v1/webhooks", tags=["webhooks"])
logger = logging.getLogger("csws.service")

#: The longest URL a webhook may have, characters.
MAX_URL_CHARS = 2048
#: The most webhooks a fleet's admin may give the fleet: each event goes to every one of them.
MAX_FLEET_WEBHOOKS = 16
#: The most dead letters one answer holds.
MAX_DEAD_LETTERS = 1000
#: A key without the admin role, or a service without keys.
FORBIDDEN: dict[int | str, dict[str, Any]] = {
    403: {"model": Message, "description": "the key has no admin role, or the service has no API keys (no fleet)"}
}
#: A URL refused: the body's validation errors, or the address rule that refused it.
REFUSED_URL: dict[int | str, dict[str, Any]] = {
    422: {
        "description": "no http(s) URL, a host that does not resolve, or an address refused: the rule named",
        "content": {
            "application/json": {
                "schema": {
                    "anyOf": [
                        {"$ref": "#/components/schemas/HTTPValidationError"},
                        {"$ref": "#/components/schemas/Message"},
                    ]
                }
            }
        },
    }
}
#: A webhook file that cannot be read: the service's admin must repair it.
BROKEN_FILE = "the webhook file cannot be read; the service's admin must repair it (csws webhooks list)"

Url = Annotated[
    str,
    Field(
        min_length=1,
        max_length=MAX_URL_CHARS,
        description="an http:// or https:// URL whose host resolves only to addresses the service may reach "
        "(docs/push.md: never link-local or cloud metadata; loopback and private only where the service allows)",
        examples=["https://dispatch.example/csws"],  # a reserved name (RFC 2606): the fuzzer relays nothing
    ),
]


class WebhookUrl(BaseModel):
    """A URL to add to the fleet's webhooks."""

    url: Url


class DecodedWebhookUrl(msgspec.Struct, frozen=True):
    """:class:`WebhookUrl` as msgspec decodes it (:func:`service.decoding.decode`)."""

    url: Annotated[str, msgspec.Meta(min_length=1, max_length=MAX_URL_CHARS)]


WEBHOOK_URL_ADAPTER = TypeAdapter(WebhookUrl)


class FleetWebhooks(BaseModel):
    """The fleet's webhooks, in the order they were added (never its secret)."""

    fleet: str = Field(description="the fleet of the key")
    urls: list[str] = Field(description="the URLs that receive the fleet's events")


class WebhookAdded(BaseModel):
    """A webhook added; the fleet's signing secret when it is the fleet's first."""

    url: str = Field(description="the URL added")
    secret: str | None = Field(
        description="the fleet's signing secret (HMAC-SHA256 of X-CSWS-Signature, docs/push.md), given only this "
        "once, when the URL is the fleet's first; null: the URL shares the secret given with the fleet's first"
    )


class DeadLetterDocument(BaseModel):
    """An event a webhook of the fleet never took (docs/push.md: after 8 tries, or 24 h after it was queued)."""

    dead: str = Field(description="when it was given up, ISO 8601 UTC")
    tries: int = Field(ge=0, description="the deliveries tried")
    url: str = Field(description="the webhook")
    vehicle_id: str = Field(description="the event's vehicle")
    error: str = Field(description="the last try's error")
    event: EventDocument = Field(description="the event itself")


class FleetDeadLetters(BaseModel):
    """The fleet's dead letters, oldest first."""

    fleet: str
    dead_letters: list[DeadLetterDocument]


async def fleet_admin(principal: CallerDep) -> str:
    """The fleet whose webhooks a request may see and change: its key's, with the admin role; a 403 for a key
    without it, and on a service without API keys, whose open fleet ``""`` no webhook can name."""
    if not principal.fleet:
        raise HTTPException(403, "webhooks belong to a fleet: this service has no API keys (use csws webhooks)")
    if not principal.may_switch:
        raise HTTPException(403, "the fleet's webhooks need a key with the admin role")
    return principal.fleet


#: The fleet of a request with a fleet's admin key.
FleetAdminDep = Annotated[str, Depends(fleet_admin)]


def _webhooks_file(request: Request) -> Path:
    """The service's webhook file (a service with API keys always has one: beside the key file by default)."""
    path = push_config(request.app.state.settings).webhooks_file
    assert path is not None, "a service with API keys has a webhook file"
    return path


def _broken(error: ValueError) -> HTTPException:
    """The 500 of a webhook file that cannot be read, which names no file; the log says what is wrong with it."""
    logger.error("%s", error)
    return HTTPException(500, BROKEN_FILE)


def _fleet_urls(path: Path, fleet: str) -> list[str]:
    """The URLs of ``fleet`` in the webhook file."""
    try:
        return [webhook.url for webhook in list_webhooks(path) if webhook.fleet == fleet]
    except ValueError as error:
        raise _broken(error) from None


@router.get(
    "",
    response_model=FleetWebhooks,
    summary="The fleet's webhooks",
    responses={**KEYED, **FORBIDDEN},
)
async def get_webhooks(fleet: FleetAdminDep, request: Request) -> FleetWebhooks:
    """The URLs that receive the fleet's events (docs/push.md); never its secret. Needs a key with the admin role."""
    urls = await asyncio.to_thread(_fleet_urls, _webhooks_file(request), fleet)
    return FleetWebhooks(fleet=fleet, urls=urls)


def _add(path: Path, fleet: str, url: str, allow_private: bool) -> str | None:
    """Add the URL by :func:`~service.push.targets.add_webhook`; its refusals as 422, 409 and 500."""
    try:
        return add_webhook(path, fleet, url, allow_private, MAX_FLEET_WEBHOOKS)
    except UnsafeTarget as refusal:
        raise HTTPException(422, str(refusal)) from None
    except DuplicateWebhook:
        raise HTTPException(409, f"the fleet has the webhook {url!r} already") from None
    except TooManyWebhooks:
        raise HTTPException(409, f"the fleet has {MAX_FLEET_WEBHOOKS} webhooks, the most it may have") from None
    except ValueError as error:
        raise _broken(error) from None


@router.post(
    "",
    status_code=201,
    response_model=WebhookAdded,
    summary="Add a webhook to the fleet",
    responses={
        **KEYED,
        **FORBIDDEN,
        **BOUNDED,
        **REFUSED_URL,
        409: {"model": Message, "description": "the fleet has this URL already, or MAX_FLEET_WEBHOOKS (16) URLs"},
    },
    openapi_extra=json_body(WebhookUrl),
)
async def post_webhook(fleet: FleetAdminDep, request: Request, response: Response, body: BodyDep) -> WebhookAdded:
    """Add a URL to the fleet's webhooks: it receives the events written from a second on, signed with the fleet's
    secret, which this answer gives when the URL is the fleet's first (only then). Needs the admin role."""
    url = decode(body, DecodedWebhookUrl, WEBHOOK_URL_ADAPTER).url
    allow_private = request.app.state.settings.webhook_allow_private
    secret = await asyncio.to_thread(_add, _webhooks_file(request), fleet, url, allow_private)
    response.headers["Cache-Control"] = "no-store"  # it may carry the secret
    return WebhookAdded(url=url, secret=secret)


def _remove(path: Path, fleet: str, url: str) -> None:
    """Take the URL out by :func:`~service.push.targets.remove_webhook`; 404 when the fleet has no such webhook."""
    try:
        remove_webhook(path, fleet, url)
    except UnknownWebhook:
        raise HTTPException(404, f"the fleet has no webhook {url!r}") from None
    except ValueError as error:
        raise _broken(error) from None


@router.delete(
    "",
    status_code=204,
    response_class=Response,
    summary="Take a webhook out of the fleet's",
    responses={**KEYED, **FORBIDDEN, 404: {"model": Message, "description": "the fleet has no such webhook"}},
)
async def delete_webhook(
    fleet: FleetAdminDep,
    request: Request,
    url: Annotated[str, Query(min_length=1, max_length=MAX_URL_CHARS, description="the URL, as listed")],
) -> Response:
    """Take a URL out of the fleet's webhooks (the fleet's secret goes with its last). Needs the admin role."""
    await asyncio.to_thread(_remove, _webhooks_file(request), fleet, url)
    return Response(status_code=204)


def _dead_letters(state_db: str, fleet: str, limit: int) -> list[DeadLetterDocument]:
    """The fleet's dead letters in the push state, oldest first."""
    state = open_push_state(state_db)
    try:
        letters = state.dead_letters(f"webhook {fleet} ", limit)
    finally:
        state.close()
    documents = []
    for letter in letters:
        event = EventDocument.model_validate_json(letter.body)
        dead = datetime.fromtimestamp(letter.dead_s, UTC).isoformat(timespec="seconds")
        url = letter.sink.split(" ", 2)[2]
        documents.append(
            DeadLetterDocument(
                dead=dead, tries=letter.tries, url=url, vehicle_id=event.vehicle_id, error=letter.error, event=event
            )
        )
    return documents


@router.get(
    "/dead-letters",
    response_model=FleetDeadLetters,
    summary="The events the fleet's webhooks never took",
    responses={**KEYED, **FORBIDDEN},
)
async def get_dead_letters(
    fleet: FleetAdminDep,
    request: Request,
    limit: Annotated[int, Query(ge=1, le=MAX_DEAD_LETTERS, description="the most dead letters to give")] = 100,
) -> FleetDeadLetters:
    """The events given up (docs/push.md: after 8 tries or 24 h), oldest first: when, tries, webhook, vehicle, the
    last error and the event. Needs the admin role."""
    state_db = push_config(request.app.state.settings).state_db
    letters = await asyncio.to_thread(_dead_letters, state_db, fleet, limit)
    return FleetDeadLetters(fleet=fleet, dead_letters=letters)
