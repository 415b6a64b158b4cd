"""The coexist server application: REST (FastAPI) and, in the same process, gRPC.

    app = create_app()                                   # settings from COEXIST_* variables
    app = create_app(Settings(dev_mode=True), store=s)   # tests: explicit settings and store

What the lifespan sets up, in order: the model store (from `settings.store_url` unless one is
given), the inference engine with its hot-reload thread, and the gRPC server on
`settings.grpc_port` (unless disabled). Several uvicorn workers can run this app side by side:
uvicorn shares the HTTP socket, and gRPC binds its port with SO_REUSEPORT (grpcio's default on
Linux), so the kernel spreads both kinds of connections over the workers. Nothing in a worker is
state another worker needs: the store is the only shared state. REST sessions (`/v1/sessions`,
`app.state.sessions`) are kept in Redis or PostgreSQL with `settings.session_store_url`, which
every worker and replica reaches; without it they live in one process's memory, and with
`settings.workers` > 1 creating one is refused (docs/architecture.md, "Sessions").

Routes: `/v1/act`, `/v1/act:batch`, `/v1/envs`, `/v1/sessions` (services.rest), the registry under
`/v1/registry` (services.registry), `/v1/jobs`, `/healthz` (liveness), `/readyz` (models loaded,
store reachable), `/metrics` (Prometheus), the OpenAPI docs at `/docs`, the pages of the error
answers' problem types at `/problems/...` (services.problems) and, after all of them,
the web console at `/console/` (services.console; `/` redirects there); with a read token
required, all of them but `/healthz` and the console's page behind it (`services.auth`). Every response carries
`X-Request-ID` (the request's own, else a new one) and every log line written while serving it
has the id (`services.logging`).
"""

from __future__ import annotations

import gc
import inspect
import logging
from collections.abc import AsyncIterator, Sequence
from contextlib import asynccontextmanager
from typing import Any

from fastapi import APIRouter, FastAPI, Request
from fastapi.responses import JSONResponse, Response
from prometheus_client import CONTENT_TYPE_LATEST, CollectorRegistry, generate_latest

from model_store.defaults import open_store
from model_store.store import ModelStore
from services.auth import TOKEN_OK_SCOPE_KEY, TokenGate
from services.console import install as install_console
from services.console import is_public as console_is_public
from services.docs_page import DOCS_PATH
from services.docs_page import install as install_docs_page
from services.docs_page import is_public as docs_is_public
from services.engine import InferenceEngine
from services.jobs_api import router as jobs_router
from services.logging import RequestIdMiddleware
from services.metrics import (
    EngineCollector,
    GrpcMetrics,
    HttpMetrics,
    SessionCollector,
    register_process_metrics,
    request_registry,
    scrape_registry,
)
from services.oip.rest import V2ErrorBodies
from services.oip.rest import router as v2_router
from services.problems import is_public as problem_is_public
from services.problems import router as problems_router
from services.problems import with_problem_responses
from services.registry import router as registry_router
from services.registry.errors import install_error_handlers as install_registry_errors
from services.registry.errors import unexpected_response
from services.registry.versions_routes import FORM_OVERHEAD_BYTES
from services.rest import install_error_handlers as install_act_errors
from services.rest import router as act_router
from services.rest import sessions_router
from services.rest.body_limit import BodyLimit
from services.rest.direct_route import DirectJson, direct_routes
from services.rest.sessions_api import open_session_store
from services.sessions import SharedSessionStore
from services.settings import Settings, get_settings
from services.version import VERSION
from services.warmup import warm_up

log = logging.getLogger("coexist.server")

ROUTERS: list[APIRouter] = [
    act_router,
    sessions_router,
    registry_router,
    jobs_router,
    v2_router,
    problems_router,
]


def create_app(
    settings: Settings | None = None,
    store: ModelStore | None = None,
    *,
    engine: InferenceEngine | None = None,
    routers: Sequence[APIRouter] = (),
    tracer_provider: Any = None,
) -> FastAPI:
    settings = settings or get_settings()
    settings.check_secure()
    # OpenTelemetry (services.tracing) with `otel_enabled` or a provider given (the tests'):
    # otherwise None, and nothing of tracing runs per request
    tracer = _tracer(tracer_provider) if settings.otel_enabled or tracer_provider else None

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        owned_store: ModelStore | None = None
        owned_engine: InferenceEngine | None = None
        grpc_server: Any = None
        if app.state.store is None:
            owned_store = open_store(
                settings.resolved_store_url(),
                max_artifact_bytes=settings.max_artifact_bytes,
                create=settings.creates_store,
            )
            app.state.store = owned_store
        if app.state.engine is None:
            owned_engine = InferenceEngine(
                app.state.store,
                cache_size=settings.cache_size,
                refresh_interval_s=settings.refresh_interval_s,
                max_batch=settings.max_batch,
            )
            warm_up(owned_engine, limit=settings.cache_size)
            owned_engine.start_refresh_thread()
            app.state.engine = owned_engine
        if tracer is not None:
            tracer.instrument(app.state.engine, app.state.engine.store)
        app.state.sessions = open_session_store(app.state.engine, settings)
        if settings.grpc_enabled:
            from services.grpc_api.server import build_grpc_server

            grpc_server = build_grpc_server(
                app.state.engine,
                port=settings.grpc_port,
                host=settings.host,
                max_workers=settings.grpc_workers,
                session_prefetch=settings.session_prefetch,
                ready=lambda: _readiness(app.state.engine)[0],
                reuse_port=True,  # uvicorn workers of one server share the gRPC port
                tokens=settings.accepted_tokens(),
                tokens_required=settings.reads_need_token,
                tls=settings.tls_pair(),
                max_episodes=settings.max_episodes,
                episodes_per_client=settings.max_episodes_per_client,
                episode_idle_s=settings.episode_idle_timeout_s,
                metrics=app.state.grpc_metrics,
                tracer=tracer,
            )
            grpc_server.start()
            app.state.grpc_port = grpc_server.port
            log.info("gRPC listening on %s:%d", settings.host, grpc_server.port)
        # Everything alive now (torch, numpy, the loaded networks: millions of objects) lives as
        # long as the server: keep it out of the garbage collector's scans, which otherwise
        # walked it on every full collection triggered by request garbage.
        gc.freeze()
        try:
            yield
        finally:
            if grpc_server is not None:
                grace = settings.shutdown_grace_s  # in-flight calls finish first
                grpc_server.stop(grace).wait(grace + 1.0)
            if isinstance(app.state.sessions, SharedSessionStore):
                app.state.sessions.backend.close()
            app.state.sessions = None
            if owned_engine is not None:
                owned_engine.stop()
                app.state.engine = None
            if owned_store is not None:
                owned_store.close()
                app.state.store = None

    app = FastAPI(
        title="coexist",
        summary="Policy server for multi-agent coexistence (AAIL) and its model registry.",
        version=VERSION,
        lifespan=lifespan,
        docs_url=None,  # services.docs_page serves /docs from local assets
        redoc_url=None,
        **_without_fastapi_telemetry(),
    )
    app.state.settings = settings
    app.state.store = store
    app.state.engine = engine
    app.state.sessions = None  # the lifespan's session store
    app.state.grpc_port = None
    # The registry's handlers first, then the inference API's (which also format request
    # validation errors for every route): problem details everywhere (services.problems).
    install_registry_errors(app)
    install_act_errors(app)

    registry = CollectorRegistry()
    registry.register(EngineCollector(lambda: app.state.engine))
    registry.register(SessionCollector(lambda: getattr(app.state, "sessions", None)))
    register_process_metrics(registry)
    http_metrics = HttpMetrics(request_registry(registry))
    app.state.grpc_metrics = GrpcMetrics(request_registry(registry))
    scraped = scrape_registry(registry)  # every worker's requests with `--workers N`
    # Outermost last: request ids, then metrics, then the body limit (pure ASGI, cheap checks);
    # innermost, the direct way of a valid JSON body to the act and session endpoints.
    # (these two routers are included without dependencies, which it could not see)
    if settings.direct_json:
        app.add_middleware(DirectJson, routes=direct_routes(act_router, sessions_router))
    app.add_middleware(
        BodyLimit,
        max_bytes=settings.max_body_bytes,
        upload_max_bytes=settings.max_artifact_bytes + FORM_OVERHEAD_BYTES,
    )
    # with reads open the gate still refuses a wrong token (services.auth)
    app.add_middleware(
        TokenGate,
        accepted=settings.accepted_tokens(),
        is_public=lambda path: (
            console_is_public(path) or docs_is_public(path) or problem_is_public(path)
        ),
        required=settings.reads_need_token,
    )
    # outermost: the id is set before anything logs, and an error no handler took is answered
    # here (with the id; Starlette's last-resort handler would close the connection); the same
    # layer counts the request and times it for /metrics
    app.add_middleware(
        RequestIdMiddleware,
        on_error=unexpected_response,
        record=http_metrics.record,
        tracer=tracer,
    )
    # outside even that: every error answer on /v2 in the protocol's shape (`{"error": str}`),
    # whichever layer made it
    app.add_middleware(V2ErrorBodies)

    # The probes first: routes are matched in order, and a load balancer polls these often.
    @app.get("/healthz", tags=["health"])
    async def healthz() -> dict[str, str]:
        """Liveness: the process answers (touches neither the database nor the models)."""
        return {"status": "ok"}

    @app.get("/readyz", tags=["health"])
    async def readyz(request: Request) -> JSONResponse:
        """Readiness: the store is reachable and production models can be served. Without the
        token a server that wants one answers the status alone (`services.auth`)."""
        ready, body = _readiness(request.app.state.engine)
        if not request.scope.get(TOKEN_OK_SCOPE_KEY, True):
            body = {"status": body["status"]}
        return JSONResponse(body, status_code=200 if ready else 503)

    @app.get("/metrics", tags=["health"])
    async def metrics() -> Response:
        """Prometheus metrics: request counts, latency histograms, cache hits, models served."""
        return Response(generate_latest(scraped), media_type=CONTENT_TYPE_LATEST)

    for router in [*ROUTERS, *routers]:
        app.include_router(router)
    install_docs_page(app)
    _docs_after_the_api(app)
    _problem_details_in_openapi(app)
    install_console(app)  # last: every other route is matched before a console route is tried
    return app


def _docs_after_the_api(app: FastAPI) -> None:
    """Move FastAPI's documentation routes (`/openapi.json`, `/docs`, `/redoc`), which it adds
    first, behind the probes and the APIs: routes are matched in order, and every request tried
    these four before its own."""
    docs_paths = {app.openapi_url, DOCS_PATH, app.swagger_ui_oauth2_redirect_url}
    routes = app.router.routes
    docs = [route for route in routes if getattr(route, "path", None) in docs_paths]
    routes[:] = [route for route in routes if route not in docs] + docs


def _problem_details_in_openapi(app: FastAPI) -> None:
    """`/openapi.json` documents every error answer outside `/v2` as problem details, the
    validation errors FastAPI documents itself included (`services.problems`)."""
    build = app.openapi

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is None:
            app.openapi_schema = with_problem_responses(build())
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]


def _without_fastapi_telemetry() -> dict[str, Any]:
    """FastAPI's own OpenTelemetry instrumentation switched off, where this FastAPI has it (the
    `telemetry` argument): coexist traces every request itself (`services.tracing`, on the
    global provider unless given one), so with a global provider configured FastAPI's would add
    a second server span per request; and FastAPI reads the global providers on every request
    to decide whether to trace it, off or not."""
    if "telemetry" not in inspect.signature(FastAPI.__init__).parameters:
        return {}
    return {"telemetry": {"tracing": False, "metrics": False, "logs": False}}


def _tracer(provider: Any) -> Any:
    """A `services.tracing.Tracer`, or a clear error when the `otel` extra is not installed."""
    try:
        from services.tracing import Tracer

        return Tracer(provider)
    except ImportError as err:
        raise RuntimeError(
            f"COEXIST_OTEL_ENABLED needs OpenTelemetry ({err.name} is missing): "
            "pip install 'coexist[otel]'"
        ) from None


def _readiness(engine: InferenceEngine | None) -> tuple[bool, dict[str, Any]]:
    """Ready = the store answers and at least one network is loaded (warm-up or traffic)."""
    if engine is None:
        return False, {"status": "starting", "store_reachable": False, "models_loaded": 0}
    status = engine.status()
    ready = status.store_reachable and status.models_loaded > 0
    reason = "ready" if ready else "no models loaded (is the store empty?)"
    body = {
        "status": reason if status.store_reachable else "store unreachable",
        "store_reachable": status.store_reachable,
        "store_error": status.store_error,
        "models_loaded": status.models_loaded,
        "versions_served": status.versions_served,
        "refresh_thread_alive": status.refresh_thread_alive,
    }
    return ready, body
