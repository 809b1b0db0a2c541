"""The OpenAPI document at ``/openapi.json``, Swagger UI at ``/docs`` and ReDoc at ``/redoc``, served from the package.

FastAPI's own pages load both from a CDN and so stay blank on a host without Internet access
(an on-board unit's backend often is). Here their files come from the npm packages
``swagger-ui-dist`` and ``redoc``, vendored with their licences into ``service/static/``, after
FastAPI's recipe "Self-hosting JavaScript and CSS for docs"; nothing leaves the machine when
the docs open (no fonts, favicon or validator from elsewhere). The app is built with
``openapi_url``, ``docs_url`` and ``redoc_url`` None and these routes instead, so that they need
a key like the data (:data:`service.security.doc_reader`) unless the docs are public.
"""

from __future__ import annotations

from importlib.resources import files

from fastapi import APIRouter, FastAPI, Request, Security
from fastapi.openapi.docs import get_redoc_html, get_swagger_ui_html, get_swagger_ui_oauth2_redirect_html
from fastapi.responses import HTMLResponse, JSONResponse
from fastapi.staticfiles import StaticFiles

from ..security import doc_reader

__all__ = ["STATIC_PATH", "OPENAPI_PATH", "router", "mount_static"]

#: Where the packaged files (docs, the live map and Leaflet) are served, without a key.
STATIC_PATH = "/static"
#: Where the OpenAPI document is served.
OPENAPI_PATH = "/openapi.json"
_OAUTH2_REDIRECT_PATH = "/docs/oauth2-redirect"

router = APIRouter(include_in_schema=False, dependencies=[Security(doc_reader)])


def mount_static(app: FastAPI) -> None:
    """Serve ``service/static`` at :data:`STATIC_PATH`."""
    app.mount(STATIC_PATH, StaticFiles(directory=str(files("service").joinpath("static"))), name="static")


@router.get(OPENAPI_PATH)
async def openapi(request: Request) -> JSONResponse:
    """The OpenAPI document FastAPI generates from the routes."""
    return JSONResponse(request.app.openapi())


@router.get("/docs")
async def swagger_ui(request: Request) -> HTMLResponse:
    """Swagger UI, from the package."""
    return get_swagger_ui_html(
        openapi_url=OPENAPI_PATH,
        title=f"{request.app.title} {request.app.version}: Swagger UI",
        oauth2_redirect_url=_OAUTH2_REDIRECT_PATH,
        swagger_js_url=f"{STATIC_PATH}/swagger-ui/swagger-ui-bundle.js",
        swagger_css_url=f"{STATIC_PATH}/swagger-ui/swagger-ui.css",
        swagger_favicon_url=f"{STATIC_PATH}/swagger-ui/favicon-32x32.png",
        swagger_ui_parameters={"validatorUrl": None},
    )


@router.get(_OAUTH2_REDIRECT_PATH)
async def swagger_ui_redirect() -> HTMLResponse:
    """Swagger UI's OAuth2 redirect page."""
    return get_swagger_ui_oauth2_redirect_html()


@router.get("/redoc")
async def redoc(request: Request) -> HTMLResponse:
    """ReDoc, from the package."""
    return get_redoc_html(
        openapi_url=OPENAPI_PATH,
        title=f"{request.app.title} {request.app.version}: ReDoc",
        redoc_js_url=f"{STATIC_PATH}/redoc/redoc.standalone.js",
        redoc_favicon_url=f"{STATIC_PATH}/swagger-ui/favicon-32x32.png",
        with_google_fonts=False,
    )
