"""Request ids and access lines for gRPC calls: the gRPC twin of `services.logging`'s
`RequestIdMiddleware`, as a server interceptor.

| what                 | how                                                                   |
|----------------------|-----------------------------------------------------------------------|
| id in                | the call's `x-request-id` metadata when it is a plain token (the same |
|                      | rule as HTTP: 1-128 characters from `A-Za-z0-9._:-`), else a new one  |
| id on log lines      | `services.logging.request_id_var` is set while the handler runs (for  |
|                      | a stream: while each of its steps runs), so every line has it         |
| id out               | `x-request-id` metadata: for a unary call in the trailing metadata    |
|                      | (sent with the answer and the status, beside an error's               |
|                      | `coexist-field`), for a stream in the initial metadata, before the    |
|                      | first answer                                                          |
| access line          | logger `coexist.access`, one per call when it ends: `method` "GRPC",  |
|                      | `route` the full method (`/coexist.v1.PolicyService/Act`), `status`   |
|                      | the status code name (`OK`, `INVALID_ARGUMENT` ...), `duration_ms`;   |
|                      | INFO, or DEBUG for health checks (load balancers poll them)           |
| metrics              | with `metrics`: `coexist_grpc_requests_total{method, code}` and       |
|                      | `coexist_grpc_request_seconds{method}` (`services.metrics`)           |
| trace                | with `tracer`: one server span per call (`services.tracing`)          |

Why unary calls echo the id in the trailers: grpcio sends initial metadata set by a handler
(`send_initial_metadata`) as a write of its own ahead of the answer, which costs a unary call a
measurable share of its latency (`benchmarks/serving.py`, docs/performance.md); the trailers
travel in the answer's own write. A stream's id comes first, so a client can correlate it with
the logs while the stream is still open.

A load balancer or client that forwards one id through every hop (envoy does with
`x-request-id`) therefore gets the same id in the HTTP and gRPC logs of every replica.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterator
from typing import Any

import grpc

from services.logging import (
    ACCESS_LOGGER,
    REQUEST_ID_HEADER,
    VALID_REQUEST_ID,
    new_request_id,
    request_id_var,
)
from services.metrics import GrpcMetrics

access_log = logging.getLogger(ACCESS_LOGGER)
HEALTH_PREFIX = "/grpc.health.v1.Health/"


def request_id_from(metadata: Any) -> str:
    """The caller's id from invocation metadata when it is a plain token, else a new one."""
    for key, value in metadata or ():
        if key == REQUEST_ID_HEADER:
            if isinstance(value, str) and VALID_REQUEST_ID.fullmatch(value):
                return value
            break
    return new_request_id()


def _status_name(context: grpc.ServicerContext, failed: bool) -> str:
    code = context.code()  # set by abort() or set_code(); None when the handler did neither
    if isinstance(code, grpc.StatusCode):
        return str(code.name)
    return "UNKNOWN" if failed else "OK"


def _log_access(route: str, status: str, seconds: float) -> None:
    level = logging.DEBUG if route.startswith(HEALTH_PREFIX) else logging.INFO
    if not access_log.isEnabledFor(level):
        return
    fields = {
        "method": "GRPC",
        "route": route,
        "path": route,
        "status": status,
        "duration_ms": round(seconds * 1000, 3),
    }
    access_log.log(level, "GRPC %s %s %.1f ms", route, status, seconds * 1000, extra=fields)


class _Observed:
    """What every call of one method shares: its route, the metrics and the tracer."""

    def __init__(self, route: str, metrics: GrpcMetrics | None, tracer: Any) -> None:
        self.route, self.metrics, self.tracer = route, metrics, tracer

    def begin(self, context: grpc.ServicerContext, attach: bool) -> tuple[str, Any]:
        """The call's id and its span (None: tracing off), made the thread's current span with
        `attach`."""
        request_id = request_id_from(context.invocation_metadata())
        if self.tracer is None:
            return request_id, None
        return request_id, self.tracer.grpc_span(self.route, request_id, attach=attach)

    def end(self, context: grpc.ServicerContext, failed: bool, start: float, span: Any) -> None:
        seconds = time.perf_counter() - start
        status = _status_name(context, failed)
        if self.metrics is not None:
            self.metrics.record(self.route, status, seconds)
        if span is not None:
            span.end(self.route, status)
        _log_access(self.route, status, seconds)

    def unary(self, behaviour: Callable[..., Any]) -> Callable[..., Any]:
        def call(request: Any, context: grpc.ServicerContext) -> Any:
            start = time.perf_counter()
            request_id, span = self.begin(context, attach=True)
            token = request_id_var.set(request_id)
            failed = True
            try:
                response = behaviour(request, context)
                failed = False
                return response
            finally:
                # after the handler: kept beside the trailing metadata an error set
                echoed = (*(context.trailing_metadata() or ()), (REQUEST_ID_HEADER, request_id))
                context.set_trailing_metadata(echoed)
                self.end(context, failed, start, span)
                request_id_var.reset(token)

        return call

    def streaming(self, behaviour: Callable[..., Iterator[Any]]) -> Callable[..., Any]:
        def call(request: Any, context: grpc.ServicerContext) -> Iterator[Any]:
            start = time.perf_counter()
            request_id, span = self.begin(context, attach=False)
            context.send_initial_metadata(((REQUEST_ID_HEADER, request_id),))
            failed = True
            responses = behaviour(request, context)
            try:
                while True:
                    # set around each step only: between steps the worker thread serves grpcio
                    token = request_id_var.set(request_id)
                    step = None if span is None else span.activate()
                    try:
                        response = next(responses)
                    except StopIteration:
                        break
                    finally:
                        if step is not None:
                            span.deactivate(step)
                        request_id_var.reset(token)
                    yield response
                failed = False
            finally:
                self.end(context, failed, start, span)

        return call


class RequestIdInterceptor(grpc.ServerInterceptor):
    """Wraps every handler of the server (module docstring); with `metrics`, each call is
    counted and timed (`services.metrics.GrpcMetrics`); with `tracer`
    (`services.tracing.Tracer`), each call is a server span.

    grpcio asks the interceptors for every call; the wrapped handler of a method is built once
    and kept (keyed by the handler it wraps, so a refusal built per call is wrapped per call).
    """

    CACHE_SIZE = 256  # more methods than any server here has; beyond it handlers are not kept

    def __init__(self, metrics: GrpcMetrics | None = None, tracer: Any = None) -> None:
        self.metrics, self.tracer = metrics, tracer
        self._wrapped: dict[int, tuple[grpc.RpcMethodHandler, grpc.RpcMethodHandler]] = {}

    def intercept_service(
        self,
        continuation: Callable[[grpc.HandlerCallDetails], grpc.RpcMethodHandler | None],
        handler_call_details: grpc.HandlerCallDetails,
    ) -> grpc.RpcMethodHandler | None:
        handler = continuation(handler_call_details)
        if handler is None:  # unknown method: grpcio answers UNIMPLEMENTED itself
            return None
        kept = self._wrapped.get(id(handler))
        if kept is not None and kept[0] is handler:
            return kept[1]
        wrapped = self._wrap(handler, str(handler_call_details.method))
        if len(self._wrapped) < self.CACHE_SIZE:
            self._wrapped[id(handler)] = (handler, wrapped)  # the handler kept: its id stays
        return wrapped

    def _wrap(self, handler: grpc.RpcMethodHandler, route: str) -> grpc.RpcMethodHandler:
        observed = _Observed(route, self.metrics, self.tracer)
        common = {
            "request_deserializer": handler.request_deserializer,
            "response_serializer": handler.response_serializer,
        }
        if handler.unary_unary is not None:
            return grpc.unary_unary_rpc_method_handler(
                observed.unary(handler.unary_unary), **common
            )
        if handler.unary_stream is not None:
            return grpc.unary_stream_rpc_method_handler(
                observed.streaming(handler.unary_stream), **common
            )
        if handler.stream_unary is not None:
            return grpc.stream_unary_rpc_method_handler(
                observed.unary(handler.stream_unary), **common
            )
        if handler.stream_stream is not None:
            return grpc.stream_stream_rpc_method_handler(
                observed.streaming(handler.stream_stream), **common
            )
        return handler
