"""A real HTTP server (uvicorn in a thread, 127.0.0.1, a free port) serving a minimal inference
app over an engine, for the SDK and environment-client tests (imported by them; not a test module).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager

import uvicorn
from fastapi import FastAPI, Response

from services.engine import InferenceEngine
from services.rest import install_error_handlers, router


def inference_app(engine: InferenceEngine) -> FastAPI:
    """The inference routes, their error handlers, and /healthz + /readyz like the real app."""
    app = FastAPI()
    app.include_router(router)
    install_error_handlers(app)
    app.state.engine = engine

    @app.get("/healthz")
    def healthz() -> dict[str, str]:
        return {"status": "ok"}

    @app.get("/readyz")
    def readyz(response: Response) -> dict[str, object]:
        status = engine.status()
        if not status.store_reachable:
            response.status_code = 503
        return {"store_reachable": status.store_reachable, "models_loaded": status.models_loaded}

    return app


@contextmanager
def live_http_server(app: FastAPI) -> Iterator[str]:
    """Serve `app` with uvicorn in a daemon thread; yields the base URL."""
    config = uvicorn.Config(app, host="127.0.0.1", port=0, log_level="warning", lifespan="off")
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 10
    while not server.started:
        if time.monotonic() > deadline or not thread.is_alive():
            raise RuntimeError("uvicorn did not start")
        time.sleep(0.01)
    port = server.servers[0].sockets[0].getsockname()[1]
    try:
        yield f"http://127.0.0.1:{port}"
    finally:
        server.should_exit = True
        thread.join(timeout=10)
