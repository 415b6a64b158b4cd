"""The two transports the SDK's plans (`coexist_client.exchange`) run on, each blocking or async.

| transport       | exchanges                                   | token                   | TLS                        |
|-----------------|---------------------------------------------|-------------------------|----------------------------|
| `HttpTransport` | `Http` (one request; JSON or raw bytes)     | `Authorization: Bearer` on every request | an `https://` URL; `verify=` a CA file (a server's own certificate authority) or False |
| `GrpcTransport` | `Unary` (one call), `StreamOpen` / `StreamSend` / `StreamClose` (a bidirectional stream) | `authorization: Bearer` metadata on every call (streams included) | `tls=True` or a `grpcs://` target; `root_certificates=` a CA file (default: the system's) |

Failures become the SDK's errors (`coexist_client.errors`): an HTTP error body or a gRPC status
(its field from the `coexist-field` trailing metadata); no connection, HTTP 503 and gRPC
UNAVAILABLE are `Unavailable` with `unsent=True` (the server did not act on the request, so any
exchange may be retried). The server side is `services.auth` and the `COEXIST_TLS_*` settings
(docs/security.md).
"""

from __future__ import annotations

import queue
import ssl
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import grpc
import httpx

from coexist_client.address import parse_address
from coexist_client.errors import CoexistError, Unavailable, error_for_grpc, error_for_http
from coexist_client.exchange import Retry

Verify = bool | str | Path
FIELD_METADATA_KEY = "coexist-field"


@dataclass(frozen=True)
class Http:
    """One HTTP request; answered with its JSON (None for an empty body) or, `raw`, a `Raw`."""

    method: str
    path: str
    json: Any = None
    params: Mapping[str, Any] | None = None
    headers: Mapping[str, str] | None = None
    files: Mapping[str, Any] | None = None  # multipart parts (httpx's `files`)
    raw: bool = False
    idempotent: bool = True
    retry: bool = True


@dataclass(frozen=True)
class Raw:
    content: bytes
    headers: Mapping[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class Unary:
    """One unary gRPC call of `path` (`/package.Service/Method`), answered with the response."""

    path: str
    request: Any
    response_type: Any
    retry: bool = True


@dataclass(frozen=True)
class StreamOpen:
    """Open a bidirectional stream; answered with a handle for `StreamSend` and `StreamClose`."""

    path: str
    request_type: Any
    response_type: Any
    retry: bool = False


@dataclass(frozen=True)
class StreamSend:
    """Send one message on an open stream; answered with the server's next message."""

    handle: Any
    message: Any
    retry: bool = False


@dataclass(frozen=True)
class StreamClose:
    """Half-close a stream and wait for the server to end it (errors already reported: none)."""

    handle: Any
    retry: bool = False


def _unavailable(err: Exception, *, unsent: bool) -> Unavailable:
    error = Unavailable("unavailable", f"{type(err).__name__}: {err}")
    error.unsent = unsent
    return error


class HttpTransport:
    """httpx underneath (`httpx.Client`, or `httpx.AsyncClient` with `aio`)."""

    grpc = False

    def __init__(
        self,
        base_url: str,
        *,
        aio: bool = False,
        timeout: float | None = 10.0,
        token: str | None = None,
        headers: Mapping[str, str] | None = None,
        verify: Verify = True,
        transport: Any = None,
        retry: Retry = Retry(),
    ) -> None:
        base_url = parse_address(base_url, "http").target  # a bad address: ValueError now
        merged = dict(headers or {})
        if token:
            merged["Authorization"] = f"Bearer {token}"
        kind = httpx.AsyncClient if aio else httpx.Client
        self.http: Any = kind(
            base_url=base_url,
            timeout=timeout,
            headers=merged or None,
            transport=transport,
            verify=verify
            if isinstance(verify, bool)
            else ssl.create_default_context(cafile=str(verify)),
        )
        self.retry = retry

    def _args(self, x: Http) -> dict[str, Any]:
        args: dict[str, Any] = {"params": x.params, "headers": x.headers}
        if x.files is not None:
            args["files"] = x.files
        elif x.json is not None:
            args["json"] = x.json
        return args

    def send(self, x: Http) -> Any:
        try:
            response = self.http.request(x.method, x.path, **self._args(x))
        except httpx.TransportError as err:
            raise _unavailable(err, unsent=isinstance(err, httpx.ConnectError)) from err
        return answer(response, x.raw)

    async def asend(self, x: Http) -> Any:
        try:
            response = await self.http.request(x.method, x.path, **self._args(x))
        except httpx.TransportError as err:
            raise _unavailable(err, unsent=isinstance(err, httpx.ConnectError)) from err
        return answer(response, x.raw)

    def close(self) -> None:
        self.http.close()

    async def aclose(self) -> None:
        await self.http.aclose()


def answer(response: httpx.Response, raw: bool = False) -> Any:
    """The response's JSON (or bytes and headers), or the SDK error its error body describes."""
    if response.status_code < 400:
        if raw:
            return Raw(response.content, dict(response.headers))
        return response.json() if response.content else None  # 204: no body
    message, field_name = error_message(response)
    err = error_for_http(response.status_code, message, field_name)
    err.unsent = response.status_code == 503
    raise err


def error_message(response: httpx.Response) -> tuple[str, str | None]:
    """(message, field at fault) of an error answer. The server answers RFC 9457 problem
    details (`{"type", "title", "status", "detail", "code", "field", ...}`); servers before them
    answered `{"error": {"code", "message", "field"}}`, read too for one release. Anything
    else (a proxy's page) is told by its status and its first 500 characters."""
    try:
        body = response.json()
    except ValueError:
        body = None
    if isinstance(body, dict):
        error = body.get("error")
        if isinstance(error, dict) and isinstance(error.get("message"), str):  # the older shape
            return error["message"], _text_or_none(error.get("field"))
        detail = body.get("detail")
        if isinstance(detail, str):  # problem details
            return detail, _text_or_none(body.get("field"))
        if isinstance(body.get("title"), str):  # problem details without a detail
            return body["title"], _text_or_none(body.get("field"))
        if isinstance(error, str):  # the Open Inference Protocol's `{"error": "<message>"}`
            return error, None
    return f"HTTP {response.status_code}: {response.text[:500]}", None


def _text_or_none(value: Any) -> str | None:
    return value if isinstance(value, str) else None


def grpc_error(err: grpc.RpcError) -> CoexistError:
    """The SDK error for a failed call (sync `grpc.RpcError` or `grpc.aio.AioRpcError`)."""
    code = err.code() if hasattr(err, "code") else grpc.StatusCode.UNKNOWN
    details = (err.details() if hasattr(err, "details") else None) or str(code)
    metadata = err.trailing_metadata() if hasattr(err, "trailing_metadata") else None
    field_name = next((v for k, v in (metadata or ()) if k == FIELD_METADATA_KEY), None)
    error = error_for_grpc(code.name, details, field_name)
    error.unsent = code == grpc.StatusCode.UNAVAILABLE
    return error


def grpc_target(target: str) -> tuple[str, bool]:
    """(what the channel dials, whether the target asked for TLS) of `host:port`,
    `grpc://host:port`, `grpcs://host:port` or `unix:/path` (`coexist_client.address`)."""
    address = parse_address(target, "grpc")
    return address.target, address.tls


class _SyncStream:
    """A sync bidirectional call: requests from a queue, responses from its iterator."""

    def __init__(self, call: Any, metadata: Any) -> None:
        self.outbox: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self.responses = call(self._drain(), metadata=metadata)

    def _drain(self) -> Iterator[Any]:
        while (message := self.outbox.get()) is not None:
            yield message


class GrpcTransport:
    """One persistent channel (`grpc`, or `grpc.aio` with `aio`: create it inside the event loop
    that uses it)."""

    grpc = True

    def __init__(
        self,
        target: str,
        *,
        aio: bool = False,
        timeout: float | None = 10.0,
        token: str | None = None,
        tls: bool = False,
        root_certificates: str | Path | None = None,
        options: list[tuple[str, Any]] | None = None,
        retry: Retry = Retry(),
    ) -> None:
        address, secure = grpc_target(target)
        module: Any = grpc.aio if aio else grpc
        if tls or secure or root_certificates is not None:
            roots = Path(root_certificates).read_bytes() if root_certificates is not None else None
            credentials = grpc.ssl_channel_credentials(root_certificates=roots)
            self.channel = module.secure_channel(address, credentials, options=options)
        else:
            self.channel = module.insecure_channel(address, options=options)
        self.timeout = timeout
        self.metadata = (("authorization", f"Bearer {token}"),) if token else None
        self.retry = retry
        self._calls: dict[str, Any] = {}

    def _unary(self, x: Unary) -> Any:
        call = self._calls.get(x.path)
        if call is None:
            call = self._calls[x.path] = self.channel.unary_unary(
                x.path,
                request_serializer=type(x.request).SerializeToString,
                response_deserializer=x.response_type.FromString,
            )
        return call

    def _stream(self, x: StreamOpen) -> Any:
        return self.channel.stream_stream(
            x.path,
            request_serializer=x.request_type.SerializeToString,
            response_deserializer=x.response_type.FromString,
        )

    def send(self, x: Unary | StreamOpen | StreamSend | StreamClose) -> Any:
        try:
            if isinstance(x, Unary):
                return self._unary(x)(x.request, timeout=self.timeout, metadata=self.metadata)
            if isinstance(x, StreamOpen):
                return _SyncStream(self._stream(x), self.metadata)
            if isinstance(x, StreamSend):
                x.handle.outbox.put(x.message)
                return next(x.handle.responses)
            x.handle.outbox.put(None)
            for _ in x.handle.responses:
                pass
        except grpc.RpcError as err:
            if isinstance(x, StreamClose):
                return None  # the stream already failed; the step that failed reported it
            raise grpc_error(err) from None
        except StopIteration:
            raise CoexistError("internal", "the server closed the stream") from None
        return None

    async def asend(self, x: Unary | StreamOpen | StreamSend | StreamClose) -> Any:
        try:
            if isinstance(x, Unary):
                call = self._unary(x)
                return await call(x.request, timeout=self.timeout, metadata=self.metadata)
            if isinstance(x, StreamOpen):
                return self._stream(x)(metadata=self.metadata)
            if isinstance(x, StreamSend):
                await x.handle.write(x.message)
                response = await x.handle.read()
                if response is grpc.aio.EOF:
                    raise CoexistError("internal", "the server closed the stream")
                return response
            await x.handle.done_writing()
            while await x.handle.read() is not grpc.aio.EOF:
                pass
        except grpc.RpcError as err:
            if isinstance(x, StreamClose):
                return None
            raise grpc_error(err) from None
        return None

    def close(self) -> None:
        self.channel.close()

    async def aclose(self) -> None:
        await self.channel.close()
