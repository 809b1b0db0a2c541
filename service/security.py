"""Who asks: the fleet's API key as a FastAPI security dependency (OpenAPI scheme ``fleetKey``, HTTP bearer).

Keys travel as ``Authorization: Bearer KEY`` (:mod:`service.keys`). On a service with an API key
file every data route depends on :data:`caller`: a missing or unknown key is a 401 with
``WWW-Authenticate``, each with its own message (:data:`MISSING_KEY`, :data:`UNKNOWN_KEY`; neither
names a fleet), and the key's :class:`~service.keys.Principal` (its fleet and role) goes to the
route; switching vehicles needs the admin role (:func:`admin`, else a 403). The docs and the
metrics depend on :data:`doc_reader`: a key as well, unless the service was started with
``public_docs``. ``/healthz``, ``/readyz``, the map's page and the packaged files need none.
Without an API key file everyone is :data:`~service.keys.OPEN`.

:class:`FleetKey` is a security scheme of FastAPI's kind (documented with FastAPI's HTTP bearer
model) that resolves the key to its principal itself, in one dependency: the single query, the
hottest route, pays for one dependency where a bearer scheme and a lookup on top of it would be two.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, HTTPException, Request, Security
from fastapi.openapi.models import HTTPBearer as HTTPBearerModel
from fastapi.security.base import SecurityBase

from .access_log import FLEET_SCOPE_KEY
from .keys import OPEN, KeyRing, Principal

__all__ = ["MISSING_KEY", "UNKNOWN_KEY", "FleetKey", "caller", "doc_reader", "admin", "CallerDep", "AdminDep"]

#: The 401 of a request without a bearer key.
MISSING_KEY = "missing API key: send Authorization: Bearer KEY"
#: The 401 of a request whose bearer key is in no fleet's key file (never made, or revoked).
UNKNOWN_KEY = "unknown or revoked API key"
_CHALLENGE = {"WWW-Authenticate": 'Bearer realm="csws"'}
#: RFC 6750, 3.1: a key that was sent but does not count is an ``invalid_token``.
_INVALID = {"WWW-Authenticate": 'Bearer realm="csws", error="invalid_token"'}


class FleetKey(SecurityBase):
    """The HTTP bearer scheme ``fleetKey``: the principal of the request's key, our own 401 without one.

    Parameters
    ----------
    docs
        For the docs and the metrics: open to all when the service has ``public_docs``.
    """

    def __init__(self, *, docs: bool = False) -> None:
        self.model = HTTPBearerModel(
            description="A fleet's API key (`csws keys add`): `Authorization: Bearer KEY`. Needed on a service "
            "with an API key file."
        )
        self.scheme_name = "fleetKey"
        self.docs = docs

    async def __call__(self, request: Request) -> Principal:
        """The fleet and role of the request's key; :data:`~service.keys.OPEN` on a service without keys
        (and, for the docs, with public docs); a 401 with a challenge for a missing key, another for an unknown
        one."""
        keyring: KeyRing | None = request.app.state.keyring
        if keyring is None or (self.docs and request.app.state.settings.public_docs):
            return OPEN
        scheme, _, token = (request.headers.get("authorization") or "").partition(" ")
        token = token.strip()
        if scheme.lower() != "bearer" or not token:
            raise HTTPException(401, MISSING_KEY, headers=_CHALLENGE)
        found = keyring.principal(token)
        if found is None:
            raise HTTPException(401, UNKNOWN_KEY, headers=_INVALID)
        request.scope[FLEET_SCOPE_KEY] = found.fleet  # for the access log: the fleet, never the key
        return found


#: Who asks a data route (a 401 before anything else when the key is missing or unknown).
caller = FleetKey()
#: Who reads the docs or the metrics.
doc_reader = FleetKey(docs=True)

#: The principal of the request.
CallerDep = Annotated[Principal, Security(caller)]


async def admin(principal: CallerDep) -> Principal:
    """The principal of a request that switches vehicles (5.2): a 403 unless its key has the admin role."""
    if not principal.may_switch:
        raise HTTPException(403, "switching vehicles needs a key with the admin role")
    return principal


#: The principal of a request that needs the admin role.
AdminDep = Annotated[Principal, Depends(admin)]
