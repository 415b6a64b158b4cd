"""`/docs`: the OpenAPI description in Swagger UI, from assets this server serves itself.

FastAPI's default page loads Swagger UI from a CDN, so on a machine without internet access (a
robot's network, a lab behind a firewall) it is blank. Here the page's script, style and icon
come from `/docs/assets/`, the files of the `swagger-ui-bundle-v2` package (Swagger UI 5: it
reads the OpenAPI 3.1 that FastAPI writes). The assets hold no data, so they are open whatever
the tokens (`is_public`); the page itself and `/openapi.json` are reads like any other. ReDoc
(`/redoc`) is not served: it has no packaged assets.
"""

from __future__ import annotations

from fastapi import FastAPI
from fastapi.openapi.docs import get_swagger_ui_html
from fastapi.responses import HTMLResponse
from fastapi.staticfiles import StaticFiles
from swagger_ui_bundle import swagger_ui_path

DOCS_PATH = "/docs"
ASSETS_PREFIX = "/docs/assets/"


def is_public(path: str) -> bool:
    """Whether `path` is one of Swagger UI's files (open whatever the tokens)."""
    return path.startswith(ASSETS_PREFIX) and ".." not in path.split("/")


def install(app: FastAPI) -> None:
    """Serve `/docs` and its assets on `app` (made with `docs_url=None`)."""
    assets = ASSETS_PREFIX.rstrip("/")
    openapi_url = app.openapi_url or "/openapi.json"

    @app.get(DOCS_PATH, include_in_schema=False)
    def swagger_ui() -> HTMLResponse:
        return get_swagger_ui_html(
            openapi_url=openapi_url,
            title=f"{app.title} API",
            swagger_js_url=f"{assets}/swagger-ui-bundle.js",
            swagger_css_url=f"{assets}/swagger-ui.css",
            swagger_favicon_url=f"{assets}/favicon-32x32.png",
        )

    app.mount(assets, StaticFiles(directory=str(swagger_ui_path)), name="docs-assets")
