"""`LeanDispatch`: a valid JSON body for a `LeanJsonRoute` (the act and session routes) goes
straight to the route's endpoint, before FastAPI's router and its request handler.

FastAPI does work per request before an endpoint runs (route resolution over lazily included
routers, the request-response wrappers, dependency solving, query, header and cookie parsing,
exit stacks) that an endpoint of the shape below does not need: the larger part of an act's
time outside the engine (docs/performance.md, "The direct dispatch"). `LeanDispatch` is a pure
ASGI layer, the innermost of the app's own middleware (so request ids, metrics, the token gate
and the body limit all run as for any request). For a `POST` whose `content-type` is
`application/json` it finds the route FastAPI would pick (the first route of the app, in
FastAPI's order, that matches path and method in full); if that is a `LeanJsonRoute` whose
endpoint qualifies (`direct_call`: plain `str` path parameters, one pydantic body model, the
`Request`, nothing else) and whose inclusion adds no dependency, it reads the body, parses it
(orjson, as `FastJsonRequest`) and validates it against the model, and calls the endpoint with
the arguments FastAPI would pass. An exception from the endpoint is answered by the app's own
exception handlers, looked up as Starlette's exception middleware does (by status code for an
`HTTPException`, else by the exception's classes); one no handler takes propagates, as it would
from FastAPI's router.

Anything else goes to the app unchanged: another method, content type or route, an empty,
malformed or invalid body (replayed to the app, so every error and its message is FastAPI's),
a Starlette body size limit in the scope, FastAPI telemetry recording the request.
`LeanJsonRoute` itself is `FastJsonRoute` (FastAPI's handler, orjson parsing): what answers
where the dispatch does not.

Dependencies are never skipped: an endpoint with any, or a route included with router-level ones
(`include_router(..., dependencies=[...])`, at any depth), always takes FastAPI's handler. Only
FastAPI's public API is read: each route's dependant, and each inclusion's effective path and
dependant (`fastapi.routing.iter_route_contexts`), listed at the first request (routes added to
an app after it has served a request are not dispatched directly). FastAPI versions without
`iter_route_contexts` copy an included route with the inclusion's prefix and dependencies
merged into it, which the same checks read. tests/services/rest/test_lean_dispatch.py checks
that both ways answer alike, that included dependencies (also nested) still run, and that the
endpoint is reached without FastAPI's dependency solving.
"""

from __future__ import annotations

import inspect
import typing
from collections.abc import Awaitable, Callable
from typing import Any

from fastapi.routing import APIRoute
from pydantic import BaseModel
from starlette.concurrency import run_in_threadpool
from starlette.exceptions import HTTPException
from starlette.routing import Host, Match

from services.rest.json_body import OFFLOAD_BYTES, FastJsonRequest, FastJsonRoute, parse_json

try:  # FastAPI with OpenTelemetry support: the direct way stays off while it records a request
    from fastapi.telemetry import get_telemetry_data
except ImportError:  # pragma: no cover - an older FastAPI: nothing to record

    def get_telemetry_data() -> object:  # type: ignore[misc]
        return None


try:  # the scope key of a body size limit (FastAPI's handler maps its errors): none, no limit
    from starlette.middleware.body_limit import MAX_BODY_SIZE_SCOPE_KEY
except ImportError:  # pragma: no cover - an older Starlette: no such limit
    MAX_BODY_SIZE_SCOPE_KEY = "max_body_size"

try:  # FastAPI that includes routers lazily: each inclusion's effective route, public
    from fastapi.routing import iter_route_contexts
except ImportError:  # pragma: no cover - older FastAPI: inclusions are copies (module docstring)
    iter_route_contexts = None  # type: ignore[assignment]

PICKS_MAX = 1024  # paths whose route is remembered (`LeanDispatch._picks`; cleared when full)
Message = dict[str, Any]
Receive = Callable[[], Awaitable[Message]]
Send = Callable[[Message], Awaitable[None]]
# what a dependant may hold besides path parameters, one body and the request
_EXTRAS = (
    "dependencies",
    "query_params",
    "header_params",
    "cookie_params",
    "websocket_param_name",
    "http_connection_param_name",
    "response_param_name",
    "background_tasks_param_name",
    "security_scopes_param_name",
)


class LeanJsonRoute(FastJsonRoute):
    """A route `LeanDispatch` may answer directly (module docstring); FastAPI's otherwise."""


class DirectCall(typing.NamedTuple):
    """How to call an endpoint straight from a request."""

    body_model: type[BaseModel]
    body_name: str
    request_name: str
    path_names: tuple[str, ...]


def _adds_nothing(dependant: Any) -> bool:
    """Whether a dependant holds nothing but path parameters, the body and the request."""
    return dependant is not None and not any(getattr(dependant, n, None) for n in _EXTRAS)


def direct_call(route: APIRoute) -> DirectCall | None:
    """How to call the route's endpoint directly, or None when it does not qualify (module
    docstring: plain `str` path parameters, one body model, the request, nothing else)."""
    endpoint, dependant = route.endpoint, route.dependant
    if not inspect.iscoroutinefunction(endpoint) or not _adds_nothing(dependant):
        return None
    if len(dependant.body_params) != 1 or not dependant.request_param_name:
        return None
    body_name = dependant.body_params[0].name
    path_names = tuple(field.name for field in dependant.path_params)
    hints = typing.get_type_hints(endpoint, include_extras=True)  # Annotated[...] stays visible
    parameters = inspect.signature(endpoint).parameters
    if set(parameters) != {body_name, dependant.request_param_name, *path_names}:
        return None
    model = hints.get(body_name)
    if not (isinstance(model, type) and issubclass(model, BaseModel)):
        return None
    if any(hints.get(name) is not str for name in path_names):  # no Path(...) constraints
        return None
    if any(parameters[name].default is not inspect.Parameter.empty for name in parameters):
        return None  # Body(embed=...), Path(...) and the like: FastAPI's handler applies them
    return DirectCall(model, body_name, dependant.request_param_name, path_names)


class _Target(typing.NamedTuple):
    """One route of the app, in FastAPI's order: how to match it, and how to call it directly
    (None: FastAPI answers it)."""

    route: Any  # a route, or an inclusion's context (`matches`, `path`, `endpoint`)
    call: DirectCall | None


def _targets(app: Any) -> list[_Target]:
    """The app's routes in the order FastAPI tries them, each with its direct call if any;
    none at all where a `Host` route matches on a header (a route is then not a path's alone)."""
    if iter_route_contexts is None:  # pragma: no cover - older FastAPI: inclusions are copies
        targets = [_target(route, route, getattr(route, "dependant", None)) for route in app.routes]
    else:
        targets = [
            _target(context, context.original_route, getattr(context, "dependant", None))
            for context in iter_route_contexts(app.routes)
        ]
    hosts = [t for t in targets if isinstance(getattr(t.route, "original_route", t.route), Host)]
    return [] if hosts else targets


def _target(route: Any, original: Any, dependant: Any) -> _Target:
    if not isinstance(original, LeanJsonRoute) or not _adds_nothing(dependant):
        return _Target(route, None)  # not lean, or an inclusion adds a dependency
    return _Target(route, direct_call(original))


def _is_json(scope: dict[str, Any]) -> bool:
    for name, value in scope["headers"]:
        if name == b"content-type":
            return bool(value == b"application/json")
    return False


async def _read_body(receive: Receive) -> bytes | None:
    """The whole body, or None when the client disconnected first (or the body limit cut the
    stream: `services.rest.body_limit` has answered 413 then)."""
    chunks: list[bytes] = []
    while True:
        message = await receive()
        if message["type"] == "http.disconnect":
            return None
        chunks.append(message.get("body", b""))
        if not message.get("more_body", False):
            return chunks[0] if len(chunks) == 1 else b"".join(chunks)


def _replaying(body: bytes, receive: Receive) -> Receive:
    """A `receive` that delivers `body` once, then whatever the connection says."""
    sent = False

    async def replay() -> Message:
        nonlocal sent
        if sent:
            return await receive()
        sent = True
        return {"type": "http.request", "body": body, "more_body": False}

    return replay


class LeanDispatch:
    """ASGI middleware: the direct way to a `LeanJsonRoute`'s endpoint (module docstring)."""

    def __init__(self, app: Any) -> None:
        self.app = app
        self._targets: list[_Target] | None = None
        self._prefixes: tuple[str, ...] = ()
        # (root path, path) -> the pick: routes match on the path alone (no `Host` route here)
        self._picks: dict[tuple[str, str], tuple[_Target | None, dict[str, Any] | None]] = {}

    async def __call__(self, scope: dict[str, Any], receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope["method"] != "POST" or not _is_json(scope):
            await self.app(scope, receive, send)
            return
        if self._targets is None:
            self._targets = _targets(scope["app"])
            self._prefixes = tuple(
                {t.route.path_format.split("{")[0] for t in self._targets if t.call is not None}
            )
        target, child = (None, None)
        if scope["path"].startswith(self._prefixes):
            key = (scope.get("root_path", ""), scope["path"])
            picked = self._picks.get(key)
            if picked is None:
                picked = self._pick(scope)
                if len(self._picks) >= PICKS_MAX:
                    self._picks.clear()
                self._picks[key] = picked
            target, child = picked
        if target is None or MAX_BODY_SIZE_SCOPE_KEY in scope or get_telemetry_data() is not None:
            await self.app(scope, receive, send)
            return
        await self._direct(scope, receive, send, target, child)

    def _pick(self, scope: dict[str, Any]) -> tuple[_Target | None, dict[str, Any] | None]:
        """The route FastAPI would answer a POST of this path with (the first full match), if
        it is direct, and its child scope (endpoint, path parameters)."""
        for target in self._targets or ():
            match, child = target.route.matches(scope)
            if match is Match.FULL:
                return (target, child) if target.call is not None else (None, None)
        return None, None

    async def _direct(
        self, scope: dict[str, Any], receive: Receive, send: Send, target: _Target, child: Any
    ) -> None:
        body = await _read_body(receive)
        if body is None:
            return  # nobody to answer
        replay = _replaying(body, receive)
        call = target.call
        assert call is not None
        try:
            if len(body) < OFFLOAD_BYTES:
                value = _validated(call.body_model, body)
            else:  # off the event loop, as `FastJsonRequest` parses a large body
                value = await run_in_threadpool(_validated, call.body_model, body)
        except Exception:  # malformed or invalid: FastAPI's handler says so, from the same bytes
            await self.app(scope, replay, send)
            return
        scope.update(child)
        scope["path_params"] = dict(child["path_params"])  # the remembered pick's stays as it is
        scope["route"] = target.route  # its `path` is the template with the prefixes
        request = FastJsonRequest(scope, replay)
        arguments: dict[str, Any] = {name: scope["path_params"][name] for name in call.path_names}
        arguments[call.body_name], arguments[call.request_name] = value, request
        try:
            response = await target.route.endpoint(**arguments)
        except Exception as exc:
            handler = _handler_for(scope["app"], exc)
            if handler is None:
                raise
            if inspect.iscoroutinefunction(handler):
                response = await handler(request, exc)
            else:
                response = await run_in_threadpool(handler, request, exc)
        await response(scope, replay, send)


def _validated(model: type[BaseModel], body: bytes) -> BaseModel:
    return model.model_validate(parse_json(body))


def _handler_for(app: Any, exc: Exception) -> Callable[..., Any] | None:
    """The app's handler of `exc` as Starlette's exception middleware finds it: by status code
    for an `HTTPException`, else by the exception's classes in order (`Exception` itself is the
    server error layer's, not this one's)."""
    handlers = app.exception_handlers
    if isinstance(exc, HTTPException) and exc.status_code in handlers:
        handler: Callable[..., Any] = handlers[exc.status_code]
        return handler
    for cls in type(exc).__mro__:
        if cls is Exception:
            return None
        if cls in handlers:
            return typing.cast(Callable[..., Any], handlers[cls])
    return None
