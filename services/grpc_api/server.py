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

Threads: unary calls and `Episode` streams share the `max_workers` pool. An open stream holds a
thread until it ends, so streams are bounded (`episode_slots`: fewer than the workers, shared by
all clients, a few per client, ended when silent) and unary calls always find a thread. Health
`Check` runs on a small pool of its own (grpcio's per-method `experimental_thread_pool`), so a
probe answers even while every worker is busy; health `Watch` streams take stream slots.

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
from services.grpc_api.episode_slots import EpisodeSlots
from services.grpc_api.errors import parse_or_malformed
from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb
from services.grpc_api.request_ids import RequestIdInterceptor
from services.grpc_api.servicer import PolicyServicer
from services.metrics import GrpcMetrics
from services.oip.grpc_servicer import SERVICE_NAME as OIP_SERVICE_NAME
from services.oip.grpc_servicer import InferenceServicer
from services.oip.grpc_servicer import handlers as oip_handlers
from services.sessions.errors import SessionLimitReached

log = logging.getLogger(__name__)

SERVICE_NAME: str = pb.DESCRIPTOR.services_by_name["PolicyService"].full_name
SERVING = health_pb2.HealthCheckResponse.SERVING
NOT_SERVING = health_pb2.HealthCheckResponse.NOT_SERVING
HEALTH_CHECK = "/grpc.health.v1.Health/Check"
HEALTH_WORKERS = 2  # threads of health Check alone: a probe never waits for the workers


class EngineHealthServicer(health.HealthServicer):
    """Standard health service whose status follows `ready()`, re-read at most every
    `recheck_s` seconds when a client asks."""

    def __init__(
        self,
        ready: Callable[[], bool],
        recheck_s: float = 1.0,
        streams: EpisodeSlots | None = None,
    ) -> None:
        super().__init__()
        self._ready = ready
        self._streams = streams  # a blocking `Watch` holds a worker thread: it takes a slot
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
        if send_response_callback is not None or self._streams is None:
            return super().Watch(request, context, send_response_callback)
        return self._watch_in_a_slot(request, context)

    def _watch_in_a_slot(self, request: Any, context: Any) -> Any:
        """grpcio's blocking `Watch` (the server's interceptors make it so), holding one of the
        stream slots for as long as it holds its worker thread."""
        assert self._streams is not None
        try:
            with self._streams.held(context.peer()):
                yield from super().Watch(request, context)
        except SessionLimitReached as err:
            limit = f"{err.limit} open streams" + (" of this client" if err.per_client else "")
            context.abort(
                grpc.StatusCode.RESOURCE_EXHAUSTED,
                f"the server holds its maximum of {limit} (Episode and health Watch); "
                "retry once one ends, or poll with health Check",
            )


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


class OwnPool(grpc.ServerInterceptor):
    """Runs the calls of `methods` on `pool` instead of the server's workers: grpcio takes a
    handler's `experimental_thread_pool`. First among the interceptors, so the attribute sits on
    the handler grpcio runs (the others wrap theirs in new functions)."""

    def __init__(self, methods: tuple[str, ...], pool: futures.ThreadPoolExecutor) -> None:
        self.methods, self.pool = methods, pool
        self._wrapped: dict[int, tuple[grpc.RpcMethodHandler, grpc.RpcMethodHandler]] = {}

    def intercept_service(
        self,
        continuation: Callable[[grpc.HandlerCallDetails], grpc.RpcMethodHandler | None],
        handler_call_details: grpc.HandlerCallDetails,
    ) -> grpc.RpcMethodHandler | None:
        handler = continuation(handler_call_details)
        if handler is None or handler.unary_unary is None:
            return handler
        if str(handler_call_details.method) not in self.methods:
            return handler
        kept = self._wrapped.get(id(handler))
        if kept is not None and kept[0] is handler:
            return kept[1]
        behaviour = handler.unary_unary

        def on_pool(request: Any, context: grpc.ServicerContext) -> Any:
            return behaviour(request, context)

        on_pool.experimental_thread_pool = self.pool  # type: ignore[attr-defined]
        wrapped = grpc.unary_unary_rpc_method_handler(
            on_pool,
            request_deserializer=handler.request_deserializer,
            response_serializer=handler.response_serializer,
        )
        self._wrapped[id(handler)] = (handler, wrapped)  # few methods: kept for every call
        return wrapped


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
    tokens_required: bool = True,
    tls: tuple[bytes, bytes] | None = None,
    max_episodes: int | None = None,
    episodes_per_client: int | None = None,
    episode_idle_s: float = 60.0,
    metrics: GrpcMetrics | None = None,
    tracer: Any = None,
) -> GrpcServer:
    """A gRPC server (not started) bound to `host:port`; port 0 binds a free port (`.port`).

    `ready` decides health SERVING; by default the engine's store must be reachable.
    Each open Episode stream holds one of the `max_workers` threads until it ends: at most
    `max_episodes` are open (None: half the workers; always fewer than them), at most
    `episodes_per_client` of one client address (None: `max_episodes`), and a stream that sent
    nothing for `episode_idle_s` seconds is ended (`episode_slots`).
    `reuse_port` lets several processes bind the same port (SO_REUSEPORT: the kernel spreads
    connections over them), as uvicorn workers of one server do; otherwise a port already in
    use is an error. `session_prefetch`: an `Episode` with inferred partners scores the next
    step's evidence after sending each answer (`services.sessions.session`, "Scoring ahead").
    `tokens`: every call but health checks needs `authorization: Bearer <one of them>`
    (`services.auth.TokenInterceptor`); with `tokens_required=False` a call without a token
    passes and only a wrong one is refused; None: open. `tls`: (certificate chain, private key),
    PEM: the port speaks TLS only; None: plaintext. `metrics`: every call counted and timed
    (`services.metrics.GrpcMetrics`, served on the REST server's `/metrics`); `tracer`: every
    call a span (`services.tracing.Tracer`; None, the default: tracing off).
    """
    if max_workers < 2:
        raise ValueError(
            f"max_workers: expected >= 2 (a stream and a unary call), got {max_workers}"
        )
    total = max_episodes or max(1, max_workers // 2)
    if total >= max_workers:
        raise ValueError(
            f"max_episodes: expected fewer than the {max_workers} workers (each open stream holds "
            f"one, and unary calls need some), got {total}"
        )
    streams = EpisodeSlots(total, episodes_per_client)
    health_pool = futures.ThreadPoolExecutor(HEALTH_WORKERS, thread_name_prefix="coexist-health")
    interceptors: list[grpc.ServerInterceptor] = [
        OwnPool((HEALTH_CHECK,), health_pool),  # first: see `OwnPool`
        RequestIdInterceptor(metrics, tracer),  # ids, access lines, metrics, spans
    ]
    if tokens is not None:
        interceptors.append(
            TokenInterceptor(tokens, required=tokens_required)
        )  # inside: refusals are logged with ids
    server = grpc.server(
        futures.ThreadPoolExecutor(max_workers=max_workers, thread_name_prefix="coexist-grpc"),
        options=[("grpc.so_reuseport", 1 if reuse_port else 0)],
        interceptors=interceptors,
    )
    servicer = PolicyServicer(
        engine,
        session_prefetch=session_prefetch,
        episode_slots=streams,
        episode_idle_s=episode_idle_s,
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
        ready or (lambda: engine.status().store_reachable),
        recheck_s=health_recheck_s,
        streams=streams,
    )
    health_pb2_grpc.add_HealthServicer_to_server(health_servicer, server)
    reflection.enable_server_reflection(
        (SERVICE_NAME, OIP_SERVICE_NAME, health.SERVICE_NAME, reflection.SERVICE_NAME), server
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
