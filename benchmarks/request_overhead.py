"""Per-request overhead of the server's observability, in microseconds, measured in-process.

Run: `.venv/bin/python benchmarks/request_overhead.py [--requests 20000] [--rounds 5]`

No sockets and no load generator: each request is one call of the ASGI application (scope,
receive and send as uvicorn would pass them), so what is timed is the application's own Python
per request, the part a load test cannot separate from the server and the kernel.

| case          | what is called                                                            |
|---------------|---------------------------------------------------------------------------|
| bare          | a FastAPI app with only `GET /healthz` (the floor of `benchmarks/serving`)|
| coexist       | `services.app.create_app` (request ids, metrics, access log, body limit)  |
| grpc bare     | a grpcio health `Check` handler called directly                           |
| grpc coexist  | the same handler wrapped by coexist's interceptor (ids, metrics, log)     |

Every round times the cases alternately; the report is the median over rounds of microseconds
per request and of the coexist - bare difference (the overhead).
"""

from __future__ import annotations

import argparse
import asyncio
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))


def bare_app() -> Any:
    """The bare FastAPI app of `benchmarks/serving.py`'s REST floor."""
    from floor_servers import rest_app

    return rest_app()


def coexist_app(tmp: str) -> Any:
    from model_store.defaults import open_store
    from services.app import create_app
    from services.settings import Settings

    store = open_store(f"sqlite:///{tmp}/models.db", create=True)
    return create_app(Settings(dev_mode=True, grpc_enabled=False, data_dir=Path(tmp)), store)


def asgi_timer(app: Any, path: str) -> Callable[[int], float]:
    """A function timing `n` GET requests of `path` through `app`, in µs per request."""
    scope = {
        "type": "http",
        "asgi": {"version": "3.0"},
        "http_version": "1.1",
        "method": "GET",
        "scheme": "http",
        "path": path,
        "raw_path": path.encode(),
        "query_string": b"",
        "root_path": "",
        "headers": [(b"host", b"bench")],
        "client": ("127.0.0.1", 1),
        "server": ("127.0.0.1", 80),
    }
    request = {"type": "http.request", "body": b"", "more_body": False}

    async def receive() -> dict[str, Any]:
        return request

    async def send(message: dict[str, Any]) -> None:
        if message["type"] == "http.response.start" and message["status"] != 200:
            raise RuntimeError(f"{path}: status {message['status']}")

    async def run(n: int) -> float:
        start = time.perf_counter()
        for _ in range(n):
            await app(dict(scope), receive, send)
        return (time.perf_counter() - start) / n * 1e6

    loop = asyncio.new_event_loop()
    return lambda n: loop.run_until_complete(run(n))


def grpc_timers() -> tuple[Callable[[int], float], Callable[[int], float]]:
    """(bare, coexist) timers of a health `Check` through the handler grpcio would call."""
    import grpc
    from grpc_health.v1 import health, health_pb2

    from services.grpc_api.request_ids import RequestIdInterceptor
    from services.metrics import GrpcMetrics

    servicer = health.HealthServicer()
    servicer.set("", health_pb2.HealthCheckResponse.SERVING)
    method = "/grpc.health.v1.Health/Check"
    plain = grpc.unary_unary_rpc_method_handler(servicer.Check)
    from prometheus_client import CollectorRegistry

    interceptor = RequestIdInterceptor(metrics=GrpcMetrics(CollectorRegistry()))

    class Details(grpc.HandlerCallDetails):
        def __init__(self) -> None:
            self.method, self.invocation_metadata = method, ()

    class Context:  # what the handlers use of grpc.ServicerContext
        def invocation_metadata(self) -> tuple[()]:
            return ()

        def send_initial_metadata(self, metadata: Any) -> None:
            pass

        def trailing_metadata(self) -> None:
            return None

        def set_trailing_metadata(self, metadata: Any) -> None:
            pass

        def code(self) -> None:
            return None

        def set_code(self, code: Any) -> None:
            pass

        def set_details(self, details: Any) -> None:
            pass

    request, context, details = health_pb2.HealthCheckRequest(), Context(), Details()

    def timer(wrapped: bool) -> Callable[[int], float]:
        def run(n: int) -> float:
            start = time.perf_counter()
            for _ in range(n):  # grpcio asks the interceptor for the handler on every call
                handler = (
                    interceptor.intercept_service(lambda d: plain, details) if wrapped else plain
                )
                handler.unary_unary(request, context)  # type: ignore[union-attr]
            return (time.perf_counter() - start) / n * 1e6

        return run

    return timer(False), timer(True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--requests", type=int, default=20000)
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    import logging

    logging.getLogger("coexist.access").setLevel(logging.WARNING)  # as `serving.py` measures
    with tempfile.TemporaryDirectory() as tmp:
        app = coexist_app(tmp)
        from fastapi.testclient import TestClient

        with TestClient(app):  # runs the lifespan: engine, sessions
            grpc_bare, grpc_coexist = grpc_timers()
            timers = {
                "bare": asgi_timer(bare_app(), "/healthz"),
                "coexist": asgi_timer(app, "/healthz"),
                "grpc bare": grpc_bare,
                "grpc coexist": grpc_coexist,
            }
            for timer in timers.values():
                timer(args.requests // 10)  # warm-up
            rounds: dict[str, list[float]] = {name: [] for name in timers}
            for _ in range(args.rounds):
                for name, timer in timers.items():
                    rounds[name].append(timer(args.requests))
    from machine import describe

    print(describe())
    print(f"{args.requests} requests x {args.rounds} rounds, median µs per request")
    print("| case | µs / request |\n|---|---|")
    for name, values in rounds.items():
        print(f"| {name} | {statistics.median(values):.1f} |")
    for transport, bare, ours in (
        ("REST", "bare", "coexist"),
        ("gRPC", "grpc bare", "grpc coexist"),
    ):
        overhead = statistics.median(o - b for o, b in zip(rounds[ours], rounds[bare], strict=True))
        print(
            f"{transport} overhead (coexist - bare, median of per-round differences): "
            f"{overhead:.1f} µs"
        )


if __name__ == "__main__":
    main()
