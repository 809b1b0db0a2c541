"""Who asks: the fleet's API key as a FastAPI security dependency (OpenAPI scheme ``fleetKey``).

Keys travel as ``Authorization: Bearer KEY`` (:mod:`service.keys`). On a service with an API key
file every data route depends on :func:`caller`: a missing or unknown key is a 401 with
``WWW-Authenticate``, and the key's :class:`~service.keys.Principal` (its fleet and role) goes to the
route; switching vehicles needs the admin role (:func:`admin`, else a 403). The docs and the
metrics depend on :func:`doc_reader`: a key as well, unless the service was started with
``public_docs``. ``/healthz``, ``/readyz``, the map's page and the packaged files need none.
Without an API key file everyone is :data:`~service.keys.OPEN`.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, HTTPException, Request, Security
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer

from .keys import OPEN, KeyRing, Principal

__all__ = ["BEARER", "caller", "admin", "doc_reader", "CallerDep", "AdminDep"]

#: The scheme: the fleet's key as a bearer token. Our own 401 answers a missing key (``auto_error=False``).
BEARER = HTTPBearer(
    scheme_name="fleetKey",
    description="A fleet's API key (`csws keys add`): `Authorization: Bearer KEY`. Needed on a service "
    "with an API key file.",
    auto_error=False,
)
_CHALLENGE = {"WWW-Authenticate": 'Bearer realm="csws"'}


def _principal(keyring: KeyRing, credentials: HTTPAuthorizationCredentials | None) -> Principal:
    """The principal of the request's key; a 401 with a challenge for a missing or unknown one."""
    found = None if credentials is None else keyring.principal(credentials.credentials.strip())
    if found is None:
        raise HTTPException(401, "an API key is needed: Authorization: Bearer KEY", headers=_CHALLENGE)
    return found


async def caller(
    request: Request, credentials: Annotated[HTTPAuthorizationCredentials | None, Security(BEARER)]
) -> Principal:
    """Who asks: the fleet and role of the request's key, :data:`~service.keys.OPEN` on a service without keys."""
    keyring: KeyRing | None = request.app.state.keyring
    return OPEN if keyring is None else _principal(keyring, credentials)


async def doc_reader(
    request: Request, credentials: Annotated[HTTPAuthorizationCredentials | None, Security(BEARER)]
) -> None:
    """Let the docs and the metrics be read: by anyone without keys or with ``public_docs``, else with a key."""
    keyring: KeyRing | None = request.app.state.keyring
    if keyring is not None and not request.app.state.settings.public_docs:
        _principal(keyring, credentials)


#: The principal of the request (a 401 before anything else when its key is missing or unknown).
CallerDep = Annotated[Principal, Security(caller)]


async def admin(principal: CallerDep) -> Principal:
    """The principal of a request that switches vehicles (5.2): a 403 unless its key has the admin role."""
    if not principal.may_switch:
        raise HTTPException(403, "switching vehicles needs a key with the admin role")
    return principal


#: The principal of a request that needs the admin role.
AdminDep = Annotated[Principal, Depends(admin)]
