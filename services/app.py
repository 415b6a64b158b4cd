"""The coexist HTTP application: `create_app()` builds it, uvicorn serves it.

    app = create_app()                                   # settings from COEXIST_* variables
    app = create_app(Settings(dev_mode=True), store=s)   # tests: explicit settings and store

Routers: the model registry (`/v1/registry`, `services.registry`) and `/healthz`; other parts
(the inference API) add theirs by passing `routers=` or by extending `ROUTERS`. The store is
opened by the lifespan (from `settings.store_url`) unless one is given, in which case the caller
owns and closes it. Creating the app refuses the default admin token outside dev mode.
"""

from __future__ import annotations

from collections.abc import AsyncIterator, Sequence
from contextlib import asynccontextmanager

from fastapi import APIRouter, FastAPI

from model_store.defaults import open_store
from model_store.store import ModelStore
from services.registry import router as registry_router
from services.registry.errors import install_error_handlers
from services.settings import Settings, get_settings

ROUTERS: list[APIRouter] = [registry_router]


def create_app(
    settings: Settings | None = None,
    store: ModelStore | None = None,
    *,
    routers: Sequence[APIRouter] = (),
) -> FastAPI:
    settings = settings or get_settings()
    settings.check_secure()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        owned: ModelStore | None = None
        if app.state.store is None:
            owned = open_store(
                settings.resolved_store_url(), max_artifact_bytes=settings.max_artifact_bytes
            )
            app.state.store = owned
        try:
            yield
        finally:
            if owned is not None:
                owned.close()
                app.state.store = None

    app = FastAPI(
        title="coexist",
        summary="Policy server for multi-agent coexistence (AAIL) and its model registry.",
        version="0.1.0",
        lifespan=lifespan,
    )
    app.state.settings = settings
    app.state.store = store
    install_error_handlers(app)
    for router in [*ROUTERS, *routers]:
        app.include_router(router)

    @app.get("/healthz", tags=["health"])
    def healthz() -> dict[str, str]:
        """Liveness: the process answers (does not touch the database)."""
        return {"status": "ok"}

    return app
