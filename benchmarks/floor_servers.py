"""The floors of `benchmarks/serving.py`: servers that do nothing but answer, with the settings
coexist serves with, so that a ratio against them shows what coexist adds per request.

Run: `.venv/bin/python benchmarks/floor_servers.py rest PORT` or `... grpc PORT`.

| floor  | what                                                                             |
|--------|----------------------------------------------------------------------------------|
| `rest` | a FastAPI app with one route, `GET /healthz` answering `{"status": "ok"}` as      |
|        | coexist's does, on uvicorn with uvloop and httptools, one worker, no access log   |
| `grpc` | grpcio's sync server on a pool of `GRPC_THREADS` threads with the standard health |
|        | servicer (`grpc_health.v1.health.HealthServicer`) set to SERVING, nothing else    |
"""

from __future__ import annotations

import sys
from concurrent import futures
from typing import Any

GRPC_THREADS = 8  # as `services.settings.Settings.grpc_workers`


def rest_app() -> Any:
    from fastapi import FastAPI

    app = FastAPI()

    @app.get("/healthz")
    async def healthz() -> dict[str, str]:
        return {"status": "ok"}

    return app


def serve_rest(port: int) -> None:
    run_uvicorn(rest_app(), port)


def run_uvicorn(app: Any, port: int) -> None:
    """`app` on uvicorn with the settings `coexist serve` uses (loopback), until stopped."""
    import uvicorn

    uvicorn.run(
        app,
        host="127.0.0.1",
        port=port,
        workers=1,
        loop="uvloop",
        http="httptools",
        log_level="warning",
        access_log=False,
    )


def serve_grpc(port: int) -> None:
    import grpc
    from grpc_health.v1 import health, health_pb2, health_pb2_grpc

    server = grpc.server(futures.ThreadPoolExecutor(max_workers=GRPC_THREADS))
    servicer = health.HealthServicer()
    servicer.set("", health_pb2.HealthCheckResponse.SERVING)
    health_pb2_grpc.add_HealthServicer_to_server(servicer, server)
    server.add_insecure_port(f"127.0.0.1:{port}")
    server.start()
    server.wait_for_termination()


if __name__ == "__main__":
    kind, port = sys.argv[1], int(sys.argv[2])
    {"rest": serve_rest, "grpc": serve_grpc}[kind](port)
