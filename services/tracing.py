"""OpenTelemetry traces of a request, from the REST or gRPC call into the engine and the store.

Optional: `pip install coexist[otel]` (opentelemetry-api and -sdk) and `COEXIST_OTEL_ENABLED=1`.
Off (the default), nothing of this module runs per request: the middleware and the gRPC
interceptor hold `tracer=None` and only test it.

| span                               | kind   | attributes                                        |
|------------------------------------|--------|---------------------------------------------------|
| `GET /v1/...` (method and route)   | server | `http.request.method`, `url.path`, `http.route`,  |
|                                    |        | `http.response.status_code`, `coexist.request_id` |
| `/coexist.v1.PolicyService/Act`    | server | `rpc.system` "grpc", `rpc.method`,                |
| (the full method)                  |        | `rpc.grpc.status_code` (name), `coexist.request_id`|
| `engine.act`, `engine.act_columns` | internal | `coexist.env`, `coexist.ego_goal`, `coexist.method`|
| `store.load_weights`               | internal | `coexist.model`, `coexist.version`              |

The engine's and the store's spans are children of the request's span when the request made
them (a cache miss loads weights inside `engine.act`); a load by the hot-reload thread is a
trace of its own. They come from wrappers `instrument` puts on the engine and store objects
(`act`, `act_checked`, which the sessions call, `act_columns`, `load_weights`), so the engine
and the store know nothing of tracing. Spans go to the global tracer provider, which the operator
configures (exporter, sampling: the SDK's `TracerProvider`, or `opentelemetry-instrument`), or
to the provider `create_app(..., tracer_provider=...)` is given (the tests: an in-memory exporter).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

TRACER_NAME = "coexist"


class Span:
    """One request's span, current (attached) from its start until `end` unless `attach` is
    False; a stream attaches it around each of its steps (`activate`, `deactivate`)."""

    def __init__(self, span: Any, attach: bool) -> None:
        from opentelemetry import context, trace

        self._context, self._trace = context, trace
        self.span = span
        self._token = self.activate() if attach else None

    def activate(self) -> object:
        return self._context.attach(self._trace.set_span_in_context(self.span))

    def deactivate(self, token: Any) -> None:
        self._context.detach(token)

    def fail(self, exc: BaseException) -> None:
        self.span.record_exception(exc)
        self.span.set_status(self._trace.Status(self._trace.StatusCode.ERROR, type(exc).__name__))

    def end(self, route: str | None, status: int | str) -> None:
        if isinstance(status, int):  # HTTP
            if route is not None:
                self.span.set_attribute("http.route", route)
                self.span.update_name(f"{self.span.name} {route}")
            self.span.set_attribute("http.response.status_code", status)
            if status >= 500:
                self.span.set_status(self._trace.Status(self._trace.StatusCode.ERROR))
        else:  # gRPC: the status code's name
            self.span.set_attribute("rpc.grpc.status_code", status)
            if status not in (
                "OK",
                "INVALID_ARGUMENT",
                "NOT_FOUND",
                "UNAUTHENTICATED",
                "PERMISSION_DENIED",
                "FAILED_PRECONDITION",
            ):
                self.span.set_status(self._trace.Status(self._trace.StatusCode.ERROR, status))
        if self._token is not None:
            self.deactivate(self._token)
        self.span.end()


class Tracer:
    """The spans of the module docstring, from an OpenTelemetry `TracerProvider` (None: the
    global one)."""

    def __init__(self, provider: Any = None) -> None:
        from opentelemetry import trace

        self._kind = trace.SpanKind
        self.tracer = trace.get_tracer(TRACER_NAME, tracer_provider=provider)

    def http_span(self, scope: dict[str, Any], request_id: str) -> Span:
        """A server span for an HTTP request (named after the method; `end` adds the route)."""
        method = scope.get("method", "")
        attributes = {
            "http.request.method": method,
            "url.path": scope.get("path", ""),
            "coexist.request_id": request_id,
        }
        span = self.tracer.start_span(method, kind=self._kind.SERVER, attributes=attributes)
        return Span(span, attach=True)

    def grpc_span(self, route: str, request_id: str, *, attach: bool) -> Span:
        """A server span for a gRPC call of the full method `route`."""
        attributes = {"rpc.system": "grpc", "rpc.method": route, "coexist.request_id": request_id}
        span = self.tracer.start_span(route, kind=self._kind.SERVER, attributes=attributes)
        return Span(span, attach=attach)

    def instrument(self, engine: Any, store: Any) -> None:
        """Wrap the engine's acts and the store's weight loads of these two objects in spans."""
        for name in ("act", "act_checked", "act_columns"):  # none calls another (one path)
            span_name = "engine.act_columns" if name == "act_columns" else "engine.act"
            setattr(engine, name, self._traced(getattr(engine, name), span_name, _act_attributes))
        store.load_weights = self._traced(
            store.load_weights, "store.load_weights", _load_attributes
        )

    def _traced(
        self, call: Callable[..., Any], name: str, attributes: Callable[..., dict[str, Any]]
    ) -> Callable[..., Any]:
        if getattr(call, "coexist_traced", False):  # a second lifespan over the same objects
            return call

        @functools.wraps(call)
        def traced(*args: Any, **kwargs: Any) -> Any:
            with self.tracer.start_as_current_span(name, attributes=attributes(*args, **kwargs)):
                return call(*args, **kwargs)

        traced.coexist_traced = True  # type: ignore[attr-defined]
        return traced


def _act_attributes(request: Any, *_: Any, **__: Any) -> dict[str, Any]:
    return {
        "coexist.env": str(request.env),
        "coexist.ego_goal": str(request.ego_goal),
        "coexist.method": str(request.method),
    }


def _load_attributes(name: str, version: int, *_: Any, **__: Any) -> dict[str, Any]:
    return {"coexist.model": name, "coexist.version": version}
