"""Bearer tokens on every door: the REST gate (pure ASGI) and the gRPC interceptor.

Reads need a token when `COEXIST_REQUIRE_READ_TOKEN` is set or `COEXIST_READ_TOKEN` is given
(`Settings.reads_need_token`); then every request must carry `Authorization: Bearer <token>`
(gRPC: the metadata `authorization: Bearer <token>`) with the read token or the admin token:

| door                                              | without a token  | with a wrong one    |
|---------------------------------------------------|------------------|---------------------|
| every REST route (inference, sessions, registry,  | 401 `unauthorized` | 403 `forbidden`   |
| jobs, `/metrics`, `/docs`, `/openapi.json`)       | (`WWW-Authenticate: Bearer`) |          |
| `GET /healthz` (liveness)                         | open             | open                |
| `GET /readyz`                                     | the status alone | the status alone    |
|                                                   | (no versions)    |                     |
| every gRPC method, reflection included            | UNAUTHENTICATED  | PERMISSION_DENIED   |
| `grpc.health.v1.Health` (probes)                  | open             | open                |

Writes (registry and job routes) still need the admin token itself (`services.deps`). With reads
open the gate and the interceptor still look at a token that is sent: a request without one
passes, a request with a wrong one is refused (403 / PERMISSION_DENIED) rather than served as if
the mistake did not matter (a client configured for another server learns it at its first
read, not at its first write). Tokens are compared in constant time (`hmac.compare_digest`), against every
accepted token (no early exit), so timing tells nothing about a guess.
"""

from __future__ import annotations

import hmac
from collections.abc import Callable
from typing import Any

import grpc

from services.problems import MEDIA_TYPE, problem_bytes

OPEN_PATHS = frozenset({"/healthz"})
READY_PATH = "/readyz"
TOKEN_OK_SCOPE_KEY = "coexist.token_ok"  # set by the gate on /readyz: may it see the details?
HEALTH_PREFIX = "/grpc.health.v1.Health/"


def token_matches(given: str, *accepted: str | None) -> bool:
    """Whether `given` is one of the `accepted` tokens (None and empty ones never match)."""
    given_bytes = given.encode()
    results = [hmac.compare_digest(given_bytes, a.encode()) for a in accepted if a]
    return any(results)


def bearer(value: str | bytes | None) -> str | None:
    """The token of an `Authorization: Bearer <token>` value, or None."""
    if value is None:
        return None
    text = value.decode("latin-1") if isinstance(value, bytes) else value
    scheme, _, token = text.strip().partition(" ")
    if scheme.lower() != "bearer":
        return None
    return token.strip() or None


def judge(
    token: str | None, accepted: tuple[str, ...], *, required: bool = True
) -> tuple[int, str, str] | None:
    """None when `token` is accepted, else (HTTP status, code, message). `required=False`
    (reads open): no token passes, a wrong one is still refused."""
    if token is None:
        if not required:
            return None
        return 401, "unauthorized", "this server needs 'Authorization: Bearer <token>'"
    if not token_matches(token, *accepted):
        return 403, "forbidden", "the bearer token is not valid for this server"
    return None


class TokenGate:
    """ASGI middleware: the REST rows of the module docstring's table."""

    def __init__(
        self,
        app: Any,
        *,
        accepted: tuple[str, ...],
        is_public: Callable[[str], bool] = lambda path: False,
        required: bool = True,
    ) -> None:
        """`is_public`: paths open whatever the tokens besides `/healthz` (the web console's page
        and its static files, which hold no data: a browser loads them without a token).
        `required=False`: reads are open, only a wrong token is refused."""
        self.app, self.accepted, self.is_public = app, accepted, is_public
        self.required = required

    async def __call__(self, scope: dict[str, Any], receive: Any, send: Any) -> None:
        path = scope.get("path", "")
        if scope["type"] != "http" or path in OPEN_PATHS or self.is_public(path):
            await self.app(scope, receive, send)
            return
        token = None
        for name, value in scope["headers"]:
            if name == b"authorization":
                token = bearer(value)
                break
        refused = judge(token, self.accepted, required=self.required)
        if scope["path"] == READY_PATH:  # open, but only the token sees the details
            scope[TOKEN_OK_SCOPE_KEY] = refused is None
            await self.app(scope, receive, send)
        elif refused is None:
            await self.app(scope, receive, send)
        else:
            await _refuse(send, *refused, instance=path)


async def _refuse(send: Any, status: int, code: str, message: str, *, instance: str) -> None:
    body = problem_bytes(status, code, message, instance=instance)
    headers = [
        (b"content-type", MEDIA_TYPE.encode()),
        (b"content-length", str(len(body)).encode()),
    ]
    if status == 401:
        headers.append((b"www-authenticate", b"Bearer"))
    await send({"type": "http.response.start", "status": status, "headers": headers})
    await send({"type": "http.response.body", "body": body})


class TokenInterceptor(grpc.ServerInterceptor):
    """gRPC server interceptor: the gRPC rows of the module docstring's table."""

    def __init__(self, accepted: tuple[str, ...], *, required: bool = True) -> None:
        self.accepted, self.required = accepted, required

    def intercept_service(
        self,
        continuation: Callable[[grpc.HandlerCallDetails], grpc.RpcMethodHandler | None],
        handler_call_details: grpc.HandlerCallDetails,
    ) -> grpc.RpcMethodHandler | None:
        handler = continuation(handler_call_details)
        if handler is None or str(handler_call_details.method).startswith(HEALTH_PREFIX):
            return handler
        metadata = handler_call_details.invocation_metadata or ()
        token = next((bearer(v) for k, v in metadata if k == "authorization"), None)
        refused = judge(token, self.accepted, required=self.required)
        if refused is None:
            return handler
        status, _, message = refused
        unauthenticated = status == 401
        code = (
            grpc.StatusCode.UNAUTHENTICATED
            if unauthenticated
            else grpc.StatusCode.PERMISSION_DENIED
        )
        return _refusing(handler, code, message)


def _refusing(handler: grpc.RpcMethodHandler, code: grpc.StatusCode, message: str) -> Any:
    """A handler of `handler`'s kind that ends every call with `code`."""

    def refuse(_request: Any, context: grpc.ServicerContext) -> Any:
        context.abort(code, message)

    common = {
        "request_deserializer": handler.request_deserializer,
        "response_serializer": handler.response_serializer,
    }
    if handler.unary_unary is not None:
        return grpc.unary_unary_rpc_method_handler(refuse, **common)
    if handler.unary_stream is not None:
        return grpc.unary_stream_rpc_method_handler(refuse, **common)
    if handler.stream_unary is not None:
        return grpc.stream_unary_rpc_method_handler(refuse, **common)
    return grpc.stream_stream_rpc_method_handler(refuse, **common)
