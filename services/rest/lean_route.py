"""`LeanJsonRoute`: `FastJsonRoute` with a direct path for a valid JSON body (the act
and session routers).

FastAPI's request handler does work on every request before the endpoint runs (dependency
solving, query, header and cookie parsing, exit stacks): more than half of a session step's
route overhead (docs/performance.md). For an endpoint taking only plain `str` path parameters, one pydantic
body model and the `Request`, a request whose `content-type` is `application/json` and whose body
parses (orjson, as `FastJsonRequest`) and validates against the model calls the endpoint
directly, with the arguments FastAPI would pass. Anything else (another content type, an empty,
malformed or invalid body, an unreadable stream, a body size limit, FastAPI telemetry on) takes
FastAPI's own handler, so every error and its message is FastAPI's.

Dependencies are never skipped: an endpoint with any, or a route included with router-level ones
(`include_router(..., dependencies=[...])`), always takes FastAPI's handler. Recent FastAPI keeps
an inclusion's dependencies in an "effective route context" it sets while building the handler;
older versions merge them into the route's own dependant; both are read.
tests/services/test_sessions_lean_route.py checks that an included dependency still runs and
that both paths answer alike.
"""

from __future__ import annotations

import inspect
import typing
from collections.abc import Callable, Coroutine
from typing import Any

import fastapi.routing
from fastapi import Request, Response
from fastapi.routing import APIRoute
from pydantic import BaseModel
from starlette.concurrency import run_in_threadpool

from services.rest.json_body import OFFLOAD_BYTES, FastJsonRequest, FastJsonRoute

try:  # FastAPI with OpenTelemetry support: the direct path stays off while it records a request
    from fastapi.telemetry import get_telemetry_data
except ImportError:  # pragma: no cover - an older FastAPI: nothing to record

    def get_telemetry_data() -> object:  # type: ignore[misc]
        return None


try:  # the scope key of a body size limit (FastAPI's handler maps its errors): none, no limit
    from starlette.middleware.body_limit import MAX_BODY_SIZE_SCOPE_KEY
except ImportError:  # pragma: no cover - an older Starlette: no such limit
    MAX_BODY_SIZE_SCOPE_KEY = "max_body_size"

Handler = Callable[[Request], Coroutine[Any, Any, Response]]
# set while FastAPI builds the handler of an included route (recent versions); absent before
_INCLUSION = getattr(fastapi.routing, "_effective_route_context_var", None)
# what a dependant may hold besides path parameters, one body and the request
_EXTRAS = (
    "dependencies", "query_params", "header_params", "cookie_params", "websocket_param_name",
    "http_connection_param_name", "response_param_name", "background_tasks_param_name",
    "security_scopes_param_name",
)  # fmt: skip


class DirectCall(typing.NamedTuple):
    """How to call an endpoint straight from a request."""

    body_model: type[BaseModel]
    body_name: str
    request_name: str
    path_names: tuple[str, ...]


def _dependant(route: APIRoute) -> Any:
    """The dependant FastAPI builds this handler from: the inclusion's while one is built."""
    context = _INCLUSION.get() if _INCLUSION is not None else None
    if context is not None and getattr(context, "original_route", None) is route:
        return getattr(context, "dependant", None)
    return route.dependant


def direct_call(route: APIRoute) -> DirectCall | None:
    """How to call the route's endpoint directly, or None when it does not qualify (module
    docstring: plain `str` path parameters, one body model, the request, nothing else)."""
    endpoint, dependant = route.endpoint, _dependant(route)
    if dependant is None or not inspect.iscoroutinefunction(endpoint):
        return None
    if any(getattr(dependant, name, None) for name in _EXTRAS):
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


class LeanJsonRoute(FastJsonRoute):
    def get_route_handler(self) -> Handler:
        call = direct_call(self)
        if call is None:
            return super().get_route_handler()
        full = APIRoute.get_route_handler(self)  # FastAPI's, fed a `FastJsonRequest` below
        endpoint = self.endpoint
        model, body_name, request_name, path_names = call

        async def route_handler(request: Request) -> Response:
            request = FastJsonRequest(request.scope, request.receive)
            if (
                request.headers.get("content-type") == "application/json"
                and MAX_BODY_SIZE_SCOPE_KEY not in request.scope
                and get_telemetry_data() is None
            ):
                try:
                    parsed = await request.json()
                    if len(await request.body()) < OFFLOAD_BYTES:
                        body = model.model_validate(parsed)
                    else:  # as the parse: a large body is validated off the event loop
                        body = await run_in_threadpool(model.model_validate, parsed)
                except Exception:  # unreadable, malformed or invalid: FastAPI's handler says so
                    return await full(request)
                arguments: dict[str, Any] = {name: request.path_params[name] for name in path_names}
                arguments[body_name], arguments[request_name] = body, request
                response: Response = await endpoint(**arguments)
                return response
            return await full(request)

        return route_handler
