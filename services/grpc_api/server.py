"""The gRPC server: grpcio's *sync* server on a thread pool (faster than `grpc.aio` for
these calls: `docs/performance.md`), serving

| service                          | what                                                     |
|----------------------------------|----------------------------------------------------------|
| `coexist.v1.PolicyService`       | `PolicyServicer` over the shared `InferenceEngine`       |
| `grpc.health.v1.Health`          | SERVING once the engine is ready (store reachable), for  |
|                                  | "" and for `coexist.v1.PolicyService`                    |
| `grpc.reflection.v1alpha...`     | server reflection (grpcurl, grpc_cli list and describe)  |

Every call goes through `request_ids.RequestIdInterceptor`: the caller's `x-request-id` (or a
new one) is on every log line written while serving it, comes back in the metadata (a unary
call's trailers, a stream's initial metadata), and each call ends with one access line, as HTTP requests do (`services.logging`).

    server = build_grpc_server(engine, port=0)     # port 0: the OS picks; see server.port
    server.start(); ...; server.stop(grace=5.0)    # health -> NOT_SERVING, then drain

Readiness is checked lazily: a health `Check`/`Watch` re-reads `ready()` at most once per
`health_recheck_s`, so probes stay cheap and no background thread is needed. `stop(grace)` first
switches health to NOT_SERVING (load balancers stop routing), then lets in-flight calls finish for
up to `grace` seconds. Request bytes that are not valid protobuf get INVALID_ARGUMENT (grpcio's own
deserializer failure would be INTERNAL), see `errors.parse_or_malformed`.
"""

from __future__ import annotations

import logging
import signal
import threading
import time
from collections.abc import Callable
from concurrent import futures
from typing import Any

import grpc
from grpc_health.v1 import health, health_pb2, health_pb2_grpc
from grpc_reflection.v1alpha import reflection

from services.auth import TokenInterceptor
from services.engine import InferenceEngine
from services.grpc_api.errors import parse_or_malformed
from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb
from services.grpc_api.request_ids import RequestIdInterceptor
from services.grpc_api.servicer import PolicyServicer
from services.metrics import GrpcMetrics
from services.oip.grpc_servicer import SERVICE_NAME as OIP_SERVICE_NAME
from services.oip.grpc_servicer import InferenceServicer
from services.oip.grpc_servicer import handlers as oip_handlers

log = logging.getLogger(__name__)

SERVICE_NAME: str = pb.DESCRIPTOR.services_by_name["PolicyService"].full_name
SERVING = health_pb2.HealthCheckResponse.SERVING
NOT_SERVING = health_pb2.HealthCheckResponse.NOT_SERVING


class EngineHealthServicer(health.HealthServicer):
    """Standard health service whose status follows `ready()`, re-read at most every
    `recheck_s` seconds when a client asks."""

    def __init__(self, ready: Callable[[], bool], recheck_s: float = 1.0) -> None:
        super().__init__()
        self._ready = ready
        self._recheck_s = recheck_s
        self._checked_at = -float("inf")
        self._refresh_lock = threading.Lock()
        self.refresh(force=True)

    def refresh(self, *, force: bool = False) -> None:
        if not force and time.monotonic() - self._checked_at < self._recheck_s:
            return
        if not self._refresh_lock.acquire(blocking=force):
            return  # another thread is re-reading; answer with the current status
        try:
            try:
                ready = bool(self._ready())
            except Exception:
                log.exception("readiness check failed")
                ready = False
            for service in ("", SERVICE_NAME):
                self.set(service, SERVING if ready else NOT_SERVING)
            self._checked_at = time.monotonic()
        finally:
            self._refresh_lock.release()

    def Check(self, request: Any, context: Any) -> Any:
        self.refresh()
        return super().Check(request, context)

    def Watch(self, request: Any, context: Any, send_response_callback: Any = None) -> Any:
        self.refresh()
        return super().Watch(request, context, send_response_callback)


class GrpcServer(grpc.Server):
    """A `grpc.Server` that knows its bound `port` and its health servicer."""

    def __init__(self, server: grpc.Server, port: int, health_servicer: EngineHealthServicer):
        self._server = server
        self.port = port
        self.health = health_servicer

    def add_generic_rpc_handlers(self, generic_rpc_handlers: Any) -> None:
        self._server.add_generic_rpc_handlers(generic_rpc_handlers)

    def add_insecure_port(self, address: str) -> int:
        return self._server.add_insecure_port(address)

    def add_secure_port(self, address: str, server_credentials: Any) -> int:
        return self._server.add_secure_port(address, server_credentials)

    def start(self) -> None:
        self._server.start()

    def stop(self, grace: float | None) -> threading.Event:
        """Health NOT_SERVING first, then stop accepting and drain for `grace` seconds."""
        self.health.enter_graceful_shutdown()
        event: threading.Event = self._server.stop(grace)
        return event

    def wait_for_termination(self, timeout: float | None = None) -> bool:
        return bool(self._server.wait_for_termination(timeout))


def _policy_handlers(servicer: PolicyServicer) -> dict[str, grpc.RpcMethodHandler]:
    def unary(method: Any, request: Any, response: Any) -> grpc.RpcMethodHandler:
        return grpc.unary_unary_rpc_method_handler(
            method,
            request_deserializer=parse_or_malformed(request),
            response_serializer=response.SerializeToString,
        )

    return {
        "Act": unary(servicer.Act, pb.ActRequest, pb.ActResponse),
        "ActBatch": unary(servicer.ActBatch, pb.ActBatchRequest, pb.ActBatchResponse),
        "ListEnvs": unary(servicer.ListEnvs, pb.ListEnvsRequest, pb.ListEnvsResponse),
        "Episode": grpc.stream_stream_rpc_method_handler(
            servicer.Episode,
            request_deserializer=parse_or_malformed(pb.EpisodeStep),
            response_serializer=pb.ActResponse.SerializeToString,
        ),
    }


def build_grpc_server(
    engine: InferenceEngine,
    *,
    port: int,
    host: str = "127.0.0.1",
    max_workers: int = 8,
    ready: Callable[[], bool] | None = None,
    health_recheck_s: float = 1.0,
    reuse_port: bool = False,
    session_prefetch: bool = True,
    tokens: tuple[str, ...] | None = None,
    tls: tuple[bytes, bytes] | None = None,
    episodes_per_client: int | None = None,
    metrics: GrpcMetrics | None = None,
    tracer: Any = None,
) -> GrpcServer:
    """A gRPC server (not started) bound to `host:port`; port 0 binds a free port (`.port`).

    `ready` decides health SERVING; by default the engine's store must be reachable.
    Each open Episode stream holds one of the `max_workers` threads until it ends; one client
    (address) may hold at most `episodes_per_client` of them (None: half; `episode_slots`).
    `reuse_port` lets several processes bind the same port (SO_REUSEPORT: the kernel spreads
    connections over them), as uvicorn workers of one server do; otherwise a port already in
    use is an error. `session_prefetch`: an `Episode` with inferred partners scores the next
    step's evidence after sending each answer (`services.sessions.session`, "Scoring ahead").
    `tokens`: every call but health checks needs `authorization: Bearer <one of them>`
    (`services.auth.TokenInterceptor`); None: open. `tls`: (certificate chain, private key),
    PEM: the port speaks TLS only; None: plaintext. `metrics`: every call counted and timed
    (`services.metrics.GrpcMetrics`, served on the REST server's `/metrics`); `tracer`: every
    call a span (`services.tracing.Tracer`; None, the default: tracing off).
    """
    if max_workers < 1:
        raise ValueError(f"max_workers: expected >= 1, got {max_workers}")
    # ids, access lines, metrics, spans
    interceptors: list[grpc.ServerInterceptor] = [RequestIdInterceptor(metrics, tracer)]
    if tokens is not None:
        interceptors.append(TokenInterceptor(tokens))  # inside: refusals are logged with ids
    server = grpc.server(
        futures.ThreadPoolExecutor(max_workers=max_workers, thread_name_prefix="coexist-grpc"),
        options=[("grpc.so_reuseport", 1 if reuse_port else 0)],
        interceptors=interceptors,
    )
    per_client = episodes_per_client or max(1, max_workers // 2)
    servicer = PolicyServicer(
        engine, session_prefetch=session_prefetch, episodes_per_client=per_client
    )
    handlers = _policy_handlers(servicer)
    server.add_generic_rpc_handlers((grpc.method_handlers_generic_handler(SERVICE_NAME, handlers),))
    server.add_registered_method_handlers(SERVICE_NAME, handlers)
    # the Open Inference Protocol (KServe v2) beside the policy service
    v2_handlers = oip_handlers(InferenceServicer(engine))
    server.add_generic_rpc_handlers(
        (grpc.method_handlers_generic_handler(OIP_SERVICE_NAME, v2_handlers),)
    )

    health_servicer = EngineHealthServicer(
        ready or (lambda: engine.status().store_reachable), recheck_s=health_recheck_s
    )
    health_pb2_grpc.add_HealthServicer_to_server(health_servicer, server)
    reflection.enable_server_reflection(
        (SERVICE_NAME, health.SERVICE_NAME, reflection.SERVICE_NAME), server
    )
    if tls is None:
        bound = server.add_insecure_port(f"{host}:{port}")
    else:
        chain, key = tls
        credentials = grpc.ssl_server_credentials([(key, chain)])
        bound = server.add_secure_port(f"{host}:{port}", credentials)
    return GrpcServer(server, bound, health_servicer)


def serve_grpc(
    engine: InferenceEngine,
    *,
    port: int = 50051,
    host: str = "127.0.0.1",
    max_workers: int = 8,
    grace_s: float = 5.0,
    ready: Callable[[], bool] | None = None,
) -> None:
    """Build, start and serve until SIGINT/SIGTERM (main thread) or termination, then stop
    gracefully (health NOT_SERVING, in-flight calls get `grace_s` seconds)."""
    server = build_grpc_server(engine, port=port, host=host, max_workers=max_workers, ready=ready)
    server.start()
    log.info("gRPC server listening on %s:%d", host, server.port)
    if threading.current_thread() is threading.main_thread():

        def on_signal(signum: int, frame: Any) -> None:
            log.info("signal %d: stopping the gRPC server (grace %.1f s)", signum, grace_s)
            server.stop(grace_s)

        for signum in (signal.SIGINT, signal.SIGTERM):
            signal.signal(signum, on_signal)
    server.wait_for_termination()
