"""`LeanJsonRoute`: `FastJsonRoute` with a direct path for a valid JSON body (the act
and session routers).

FastAPI's request handler does work per request before the endpoint runs (dependency solving,
query, header and cookie parsing, exit stacks) that an endpoint of the shape below does not need:
a measurable share of a session step's route overhead (`benchmarks/session_breakdown.py`).
For an endpoint taking only plain `str` path parameters, one pydantic body model and the
`Request`, a request whose `content-type` is `application/json` and whose body
parses (orjson, as `FastJsonRequest`) and validates against the model calls the endpoint
directly, with the arguments FastAPI would pass. Anything else (another content type, an empty,
malformed or invalid body, an unreadable stream, a body size limit, FastAPI telemetry on) takes
FastAPI's own handler, so every error and its message is FastAPI's.

Dependencies are never skipped: an endpoint with any, or a route included with router-level ones
(`include_router(..., dependencies=[...])`, at any depth), always takes FastAPI's handler. Only
FastAPI's public API is read: the route's own dependant when the handler is built, and, at the
first request a handler serves, every inclusion of the route in the app
(`fastapi.routing.iter_route_contexts(app.routes)`, whose contexts carry each inclusion's
dependant): if any inclusion adds a dependency, that handler keeps FastAPI's path for good.
FastAPI versions without `iter_route_contexts` copy an included route with the inclusion's
dependencies merged into its own dependant, which the build-time check reads.
tests/services/rest/test_sessions_lean_route.py checks that included dependencies (also nested)
still run and that both paths answer alike.
"""

from __future__ import annotations

import inspect
import typing
from collections.abc import Callable, Coroutine
from typing import Any

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

try:  # FastAPI that includes routers lazily: each inclusion's effective route, public
    from fastapi.routing import iter_route_contexts
except ImportError:  # pragma: no cover - older FastAPI: inclusions are copies (module docstring)
    iter_route_contexts = None  # type: ignore[assignment]

Handler = Callable[[Request], Coroutine[Any, Any, Response]]
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


def _adds_nothing(dependant: Any) -> bool:
    """Whether a dependant holds nothing but path parameters, the body and the request."""
    return dependant is not None and not any(getattr(dependant, n, None) for n in _EXTRAS)


def inclusions_add_nothing(app: Any, route: APIRoute) -> bool:
    """Whether no inclusion of `route` in `app` adds a dependency (or a parameter) to it."""
    if iter_route_contexts is None:
        return True  # older FastAPI: the route's own dependant has the inclusion's, checked
    contexts = [c for c in iter_route_contexts(app.routes) if c.original_route is route]
    return all(_adds_nothing(getattr(context, "dependant", None)) for context in contexts)


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


class LeanJsonRoute(FastJsonRoute):
    def get_route_handler(self) -> Handler:
        call = direct_call(self)
        if call is None:
            return super().get_route_handler()
        full = APIRoute.get_route_handler(self)  # FastAPI's, fed a `FastJsonRequest` below
        endpoint = self.endpoint
        model, body_name, request_name, path_names = call

        direct: bool | None = None  # known at the first request: `inclusions_add_nothing`

        async def route_handler(request: Request) -> Response:
            nonlocal direct
            request = FastJsonRequest(request.scope, request.receive)
            if direct is None:
                direct = inclusions_add_nothing(request.app, self)
            if (
                direct
                and request.headers.get("content-type") == "application/json"
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
