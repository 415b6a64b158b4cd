"""`DirectJson`: the app's innermost middleware, which hands a valid JSON body for one of the
routes it is given (the act and session routes, `direct_routes`) straight to the route's
endpoint, before FastAPI's router.

Why: FastAPI's router, its request wrapper, exception and exit-stack layers and dependency
solving cost more per act than the act's own work outside the engine; the same app without this
middleware spends about 1.4x the server CPU per act (docs/performance.md, "FastAPI's dispatch").

How, with public APIs only (ASGI, Starlette's `compile_path`, `Request` and
`ExceptionMiddleware`, the routes' `path`, `methods`, `endpoint` and `dependencies`, pydantic):
for a `POST` whose `content-type` is exactly `application/json` and whose path matches a given
route's template, it reads the body, parses it (`json_body.parse_json`: orjson), validates it
with the endpoint's body model and awaits `endpoint(body, request, **path parameters)`. The
endpoint's exceptions go to the app's exception handlers through Starlette's
`ExceptionMiddleware`, as from the router. Anything else goes to the app unchanged: another
method, content type or path, a root path (a mounted app), or a body that does not parse or
validate (replayed, so every validation error is FastAPI's own).

A route qualifies (`direct_call`) when its endpoint is a coroutine whose parameters are exactly
one pydantic model (the body), the `Request`, and `str` path parameters, none with a default,
and the route has no dependency. A dependency given to `include_router` is not visible on the
route, so the routers given here are included without any (`services.app`).
"""

from __future__ import annotations

import inspect
import re
import typing
from collections.abc import Sequence
from typing import Any, NamedTuple

from fastapi import APIRouter, Request
from fastapi.routing import APIRoute
from pydantic import BaseModel
from starlette.concurrency import run_in_threadpool
from starlette.middleware.exceptions import ExceptionMiddleware
from starlette.routing import compile_path
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from services.rest.json_body import OFFLOAD_BYTES, FastJsonRequest, parse_json

ERROR_KEY = "coexist.endpoint_error"  # the scope key that carries an endpoint's exception


class DirectCall(NamedTuple):
    """How to call an endpoint straight from a request."""

    body_model: type[BaseModel]
    body_name: str
    request_name: str
    path_names: tuple[str, ...]


class DirectRoute(NamedTuple):
    """A route answered by `DirectJson`: its path's pattern and how to call its endpoint."""

    route: APIRoute
    pattern: re.Pattern[str]
    call: DirectCall


def direct_call(route: APIRoute) -> DirectCall | None:
    """How to call the route's endpoint directly, or None where it does not qualify (module
    docstring)."""
    endpoint = route.endpoint
    if route.dependencies or not inspect.iscoroutinefunction(endpoint):
        return None
    hints = typing.get_type_hints(endpoint, include_extras=True)  # Annotated[...] stays visible
    parameters = inspect.signature(endpoint).parameters
    if any(p.default is not inspect.Parameter.empty for p in parameters.values()):
        return None  # Body(embed=...), Path(...) and the like: FastAPI's handler applies them
    _, _, convertors = compile_path(route.path)
    bodies = [name for name in parameters if _is_model(hints.get(name))]
    requests = [name for name in parameters if hints.get(name) is Request]
    paths = tuple(name for name in parameters if name in convertors and hints.get(name) is str)
    if len(bodies) != 1 or len(requests) != 1 or len(parameters) != 2 + len(paths):
        return None
    return DirectCall(hints[bodies[0]], bodies[0], requests[0], paths)


def _is_model(hint: object) -> bool:
    return isinstance(hint, type) and issubclass(hint, BaseModel)


def direct_routes(*routers: APIRouter) -> tuple[DirectRoute, ...]:
    """The `POST` routes of `routers` that qualify (`direct_call`), for `DirectJson`."""
    found = []
    for router in routers:
        for route in router.routes:
            if isinstance(route, APIRoute) and route.methods == {"POST"}:
                call = direct_call(route)
                if call is not None:
                    pattern, _, _ = compile_path(route.path)
                    found.append(DirectRoute(route, pattern, call))
    return tuple(found)


class DirectJson:
    """ASGI middleware: the direct way of a valid JSON body to a given route (module docstring)."""

    def __init__(self, app: ASGIApp, routes: Sequence[DirectRoute]) -> None:
        self.app = app
        self.routes = tuple(routes)
        self._prefixes = tuple({r.route.path.split("{")[0] for r in self.routes})
        self._errors: ExceptionMiddleware | None = None  # the app's handlers, at first error

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        path = scope.get("path", "")
        if (
            scope["type"] != "http"
            or scope["method"] != "POST"
            or not path.startswith(self._prefixes)
            or scope.get("root_path")
            or not _is_json(scope)
        ):
            await self.app(scope, receive, send)
            return
        for direct in self.routes:
            match = direct.pattern.match(path)
            if match is not None:
                await self._direct(scope, receive, send, direct, match.groupdict())
                return
        await self.app(scope, receive, send)

    async def _direct(
        self,
        scope: Scope,
        receive: Receive,
        send: Send,
        direct: DirectRoute,
        params: dict[str, Any],
    ) -> None:
        body = await _read_body(receive)
        if body is None:
            return  # the client is gone (or the body limit answered): nobody to answer
        replay = _replaying(body, receive)
        try:
            if len(body) < OFFLOAD_BYTES:
                value = _validated(direct.call.body_model, body)
            else:  # off the event loop, as `FastJsonRequest` parses a large body
                value = await run_in_threadpool(_validated, direct.call.body_model, body)
        except Exception:  # malformed or invalid: FastAPI's handler says why, from the same bytes
            await self.app(scope, replay, send)
            return
        scope.update(
            path_params=params, route=direct.route, endpoint=direct.route.endpoint
        )  # as the router sets them (the access log and metrics read the route's template)
        call = direct.call
        arguments: dict[str, Any] = {name: params[name] for name in call.path_names}
        arguments[call.body_name] = value
        arguments[call.request_name] = FastJsonRequest(scope, replay)
        try:
            response = await direct.route.endpoint(**arguments)
        except Exception as exc:
            # Answered by the app's handler for it, found as the router's would be: Starlette's
            # `ExceptionMiddleware` around an app that raises it, entered only when an endpoint
            # raises, so a call that succeeds passes through no exception layer.
            scope[ERROR_KEY] = exc
            await self._handled(scope["app"])(scope, replay, send)
            return
        await response(scope, replay, send)

    def _handled(self, app: Any) -> ExceptionMiddleware:
        """`ExceptionMiddleware` with the app's handlers but the server error's (as Starlette
        builds it) around `_raise_error`."""
        if self._errors is None:
            handlers = {
                key: handler
                for key, handler in app.exception_handlers.items()
                if key not in (500, Exception)
            }
            self._errors = ExceptionMiddleware(_raise_error, handlers=handlers)
        return self._errors


async def _raise_error(scope: Scope, receive: Receive, send: Send) -> None:
    """Raise the endpoint's exception that `DirectJson` put in the scope."""
    raise scope.pop(ERROR_KEY)


def _validated(model: type[BaseModel], body: bytes) -> BaseModel:
    return model.model_validate(parse_json(body))


def _is_json(scope: Scope) -> bool:
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
