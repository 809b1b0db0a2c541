"""The OpenAPI documentation, Swagger UI at ``/docs`` and ReDoc at ``/redoc``, served from the package.

FastAPI's own pages load both from a CDN and so stay blank on a host without Internet access
(an on-board unit's backend often is). Here their files come from the npm packages
``swagger-ui-dist`` and ``redoc``, vendored with their licences into ``service/static/``, after
FastAPI's recipe "Self-hosting JavaScript and CSS for docs"; nothing leaves the machine when
the docs open (no fonts, favicon or validator from elsewhere).
"""

from __future__ import annotations

from importlib.resources import files

from fastapi import FastAPI
from fastapi.openapi.docs import get_redoc_html, get_swagger_ui_html, get_swagger_ui_oauth2_redirect_html
from fastapi.responses import HTMLResponse
from fastapi.staticfiles import StaticFiles

__all__ = ["STATIC_PATH", "add_doc_routes"]

#: Where the packaged files (docs, the live map and Leaflet) are served.
STATIC_PATH = "/static"


def add_doc_routes(app: FastAPI) -> None:
    """Serve ``service/static`` at :data:`STATIC_PATH`, and the docs pages from it (build the app with
    ``docs_url=None, redoc_url=None``)."""
    app.mount(STATIC_PATH, StaticFiles(directory=str(files("service").joinpath("static"))), name="static")
    title = f"{app.title} {app.version}"

    @app.get("/docs", include_in_schema=False)
    async def swagger_ui() -> HTMLResponse:
        return get_swagger_ui_html(
            openapi_url=app.openapi_url,
            title=f"{title}: Swagger UI",
            oauth2_redirect_url=app.swagger_ui_oauth2_redirect_url,
            swagger_js_url=f"{STATIC_PATH}/swagger-ui/swagger-ui-bundle.js",
            swagger_css_url=f"{STATIC_PATH}/swagger-ui/swagger-ui.css",
            swagger_favicon_url=f"{STATIC_PATH}/swagger-ui/favicon-32x32.png",
            swagger_ui_parameters={"validatorUrl": None},
        )

    @app.get(app.swagger_ui_oauth2_redirect_url, include_in_schema=False)
    async def swagger_ui_redirect() -> HTMLResponse:
        return get_swagger_ui_oauth2_redirect_html()

    @app.get("/redoc", include_in_schema=False)
    async def redoc() -> HTMLResponse:
        return get_redoc_html(
            openapi_url=app.openapi_url,
            title=f"{title}: ReDoc",
            redoc_js_url=f"{STATIC_PATH}/redoc/redoc.standalone.js",
            redoc_favicon_url=f"{STATIC_PATH}/swagger-ui/favicon-32x32.png",
            with_google_fonts=False,
        )
