"""Request ids and access lines for gRPC calls: the gRPC twin of `services.logging`'s
`RequestIdMiddleware`, as a server interceptor.

| what                 | how                                                                   |
|----------------------|-----------------------------------------------------------------------|
| id in                | the call's `x-request-id` metadata when it is a plain token (the same |
|                      | rule as HTTP: 1-128 characters from `A-Za-z0-9._:-`), else a new one  |
| id on log lines      | `services.logging.request_id_var` is set while the handler runs (for  |
|                      | a stream: while each of its steps runs), so every line has it         |
| id out               | initial metadata `x-request-id`, sent before the first response       |
| access line          | logger `coexist.access`, one per call when it ends: `method` "GRPC",  |
|                      | `route` the full method (`/coexist.v1.PolicyService/Act`), `status`   |
|                      | the status code name (`OK`, `INVALID_ARGUMENT` ...), `duration_ms`;   |
|                      | INFO, or DEBUG for health checks (load balancers poll them)           |

A load balancer or client that forwards one id through every hop (envoy does with
`x-request-id`) therefore gets the same id in the HTTP and gRPC logs of every replica.
"""

from __future__ import annotations

import logging
import time
import uuid
from collections.abc import Callable, Iterator
from typing import Any

import grpc

from services.logging import ACCESS_LOGGER, REQUEST_ID_HEADER, VALID_REQUEST_ID, request_id_var

access_log = logging.getLogger(ACCESS_LOGGER)
HEALTH_PREFIX = "/grpc.health.v1.Health/"


def request_id_from(metadata: Any) -> str:
    """The caller's id from invocation metadata when it is a plain token, else a new one."""
    for key, value in metadata or ():
        if key == REQUEST_ID_HEADER:
            if isinstance(value, str) and VALID_REQUEST_ID.fullmatch(value):
                return value
            break
    return uuid.uuid4().hex


def _status_name(context: grpc.ServicerContext, failed: bool) -> str:
    code = context.code()  # set by abort() or set_code(); None when the handler did neither
    if isinstance(code, grpc.StatusCode):
        return str(code.name)
    return "UNKNOWN" if failed else "OK"


def _log_access(route: str, status: str, seconds: float) -> None:
    level = logging.DEBUG if route.startswith(HEALTH_PREFIX) else logging.INFO
    if not access_log.isEnabledFor(level):
        return
    fields = {"method": "GRPC", "route": route, "path": route, "status": status,
              "duration_ms": round(seconds * 1000, 3)}  # fmt: skip
    access_log.log(level, "GRPC %s %s %.1f ms", route, status, seconds * 1000, extra=fields)


def _unary(behaviour: Callable[..., Any], route: str) -> Callable[..., Any]:
    def call(request: Any, context: grpc.ServicerContext) -> Any:
        request_id = request_id_from(context.invocation_metadata())
        context.send_initial_metadata(((REQUEST_ID_HEADER, request_id),))
        token = request_id_var.set(request_id)
        start, failed = time.perf_counter(), True
        try:
            response = behaviour(request, context)
            failed = False
            return response
        finally:
            _log_access(route, _status_name(context, failed), time.perf_counter() - start)
            request_id_var.reset(token)

    return call


def _streaming(behaviour: Callable[..., Iterator[Any]], route: str) -> Callable[..., Any]:
    def call(request: Any, context: grpc.ServicerContext) -> Iterator[Any]:
        request_id = request_id_from(context.invocation_metadata())
        context.send_initial_metadata(((REQUEST_ID_HEADER, request_id),))
        start, failed = time.perf_counter(), True
        responses = behaviour(request, context)
        try:
            while True:
                # set around each step only: between steps the worker thread serves grpcio
                token = request_id_var.set(request_id)
                try:
                    response = next(responses)
                except StopIteration:
                    break
                finally:
                    request_id_var.reset(token)
                yield response
            failed = False
        finally:
            _log_access(route, _status_name(context, failed), time.perf_counter() - start)

    return call


class RequestIdInterceptor(grpc.ServerInterceptor):
    """Wraps every handler of the server (module docstring)."""

    def intercept_service(
        self,
        continuation: Callable[[grpc.HandlerCallDetails], grpc.RpcMethodHandler | None],
        handler_call_details: grpc.HandlerCallDetails,
    ) -> grpc.RpcMethodHandler | None:
        handler = continuation(handler_call_details)
        if handler is None:  # unknown method: grpcio answers UNIMPLEMENTED itself
            return None
        route = str(handler_call_details.method)
        common = {
            "request_deserializer": handler.request_deserializer,
            "response_serializer": handler.response_serializer,
        }
        if handler.unary_unary is not None:
            return grpc.unary_unary_rpc_method_handler(_unary(handler.unary_unary, route), **common)
        if handler.unary_stream is not None:
            return grpc.unary_stream_rpc_method_handler(
                _streaming(handler.unary_stream, route), **common
            )
        if handler.stream_unary is not None:
            return grpc.stream_unary_rpc_method_handler(
                _unary(handler.stream_unary, route), **common
            )
        if handler.stream_stream is not None:
            return grpc.stream_stream_rpc_method_handler(
                _streaming(handler.stream_stream, route), **common
            )
        return handler
