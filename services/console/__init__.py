"""The web console: one page served by `coexist serve` itself, nothing to build or start.

| path                    | what                                                           |
|-------------------------|----------------------------------------------------------------|
| `/`                     | redirects to the console                                       |
| `/console/`             | the page (`static/index.html`)                                 |
| `/console/static/...`   | its stylesheet and JavaScript modules (no build step)          |
| `/v1/console/...`       | the page's own read routes (`services.console.api`)            |

The page has three views: the registry (models, versions, lineage with the training curve,
promote / archive / delete, the change feed live), training jobs (submit, follow the progress
and the log, cancel) and live episodes (`services.console.episodes`: the server plays, the page
draws the world, the action distributions, the blend weights and beliefs, lanes side by side).
It calls the public REST API with the token typed into it (kept in the tab's session storage),
so it can read what the read-token setting lets through and write only with the admin token.

`install(app)` adds it after every other route: a request to `/v1/act` is matched before any
console route is looked at, and no middleware is added.

The page and its files hold no data, and a browser cannot send a bearer token when it loads a
page: `is_public(path)` names them, for anything that guards every route with the read token
(the data the page then asks for carries the token).
"""

from __future__ import annotations

from pathlib import Path

from fastapi import APIRouter, FastAPI
from fastapi.responses import FileResponse, RedirectResponse
from fastapi.staticfiles import StaticFiles

from services.console.api import router as api_router

STATIC_DIR = Path(__file__).with_name("static")
# The page loads nothing from elsewhere and runs no inline script or style.
CONTENT_SECURITY_POLICY = (
    "default-src 'self'; script-src 'self'; style-src 'self'; img-src 'self' data:; "
    "connect-src 'self'; frame-ancestors 'none'; base-uri 'none'; form-action 'self'"
)

PUBLIC_PATHS = frozenset({"/", "/console", "/console/"})
PUBLIC_PREFIX = "/console/static/"

pages = APIRouter(include_in_schema=False)


def is_public(path: str) -> bool:
    """Whether `path` is the console's page or one of its files (open whatever the tokens)."""
    if path in PUBLIC_PATHS:
        return True
    return path.startswith(PUBLIC_PREFIX) and ".." not in path.split("/")


@pages.get("/")
def root() -> RedirectResponse:
    return RedirectResponse("/console/")


@pages.get("/console")
def console_without_slash() -> RedirectResponse:
    return RedirectResponse("/console/")


@pages.get("/console/")
def console_page() -> FileResponse:
    headers = {"Content-Security-Policy": CONTENT_SECURITY_POLICY, "Cache-Control": "no-cache"}
    return FileResponse(STATIC_DIR / "index.html", media_type="text/html", headers=headers)


def install(app: FastAPI) -> None:
    """Add the console's routes and static files to `app` (call it after the other routers)."""
    app.include_router(api_router)
    app.include_router(pages)
    app.mount("/console/static", StaticFiles(directory=STATIC_DIR), name="console-static")
