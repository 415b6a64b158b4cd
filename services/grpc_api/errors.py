"""The one place where errors become gRPC status codes.

| error                                           | status           | details message        |
|-------------------------------------------------|------------------|------------------------|
| `services.engine.InvalidRequest`                | INVALID_ARGUMENT | "FIELD: problem"       |
| a request that is not valid protobuf            | INVALID_ARGUMENT | "request: ..."         |
| `services.engine.ModelNotFound`                 | NOT_FOUND        | "FIELD: problem"       |
| `model_store.NotFound`                          | NOT_FOUND        | the store's message    |
| `services.engine.ModelUnavailable`              | UNAVAILABLE      | the engine's message   |
| `services.sessions.SessionNotFound`             | NOT_FOUND        | "session_id: ..."      |
| `services.sessions.SessionLimitReached`         | RESOURCE_EXHAUSTED | the store's message  |
| `episode_slots.EpisodeIdle` (a silent stream)   | DEADLINE_EXCEEDED | how long it was idle  |
| `services.sessions.StepConflict`                | ABORTED          | "expected_step: ..."   |
| `services.sessions.SessionsUnavailable`         | UNIMPLEMENTED    | the message            |
| `model_store.StoreUnavailable`, other store err | UNAVAILABLE      | the store's message    |
| other `services.engine.EngineError`             | INTERNAL         | the engine's message   |
| anything else (a bug)                           | INTERNAL         | "internal error ..."   |

The field also travels alone in the trailing metadata under `coexist-field` (the SDK reads it),
so a client need not parse the message. Messages quote request values through
`model_store.errors.brief`, and `abort` clips the message and the field besides: a long value
stays an INVALID_ARGUMENT naming its field rather than overflowing the trailers (which grpcio
answers with RESOURCE_EXHAUSTED). Unexpected errors are logged with their traceback and answered
with INTERNAL; the server keeps serving.

`translate_errors` wraps unary handlers, `translate_stream_errors` generator handlers. Malformed
protobuf is caught by the servers' deserializers (`parse_or_malformed`), which hand the handler a
`MalformedMessage` instead of raising (grpcio would answer INTERNAL).
"""

from __future__ import annotations

import functools
import logging
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any, NoReturn, TypeVar

import grpc
from google.protobuf.message import DecodeError

from model_store.errors import ModelStoreError, clip
from model_store.errors import NotFound as StoreNotFound
from services.engine import EngineError, InvalidRequest, ModelNotFound, ModelUnavailable
from services.grpc_api.episode_slots import EpisodeIdle
from services.sessions.errors import (
    SessionLimitReached,
    SessionNotFound,
    SessionsUnavailable,
    StepConflict,
)

log = logging.getLogger(__name__)

FIELD_METADATA_KEY = "coexist-field"
FIELD_CHARS = 200  # as over HTTP (`services.registry.errors`)

Request = TypeVar("Request")
Response = TypeVar("Response")


@dataclass(frozen=True)
class MalformedMessage:
    """Stands in for a request whose bytes are not a valid protobuf message of the method's type."""

    message_type: str
    problem: str


def parse_or_malformed(message_class: Any) -> Callable[[bytes], Any]:
    """A request deserializer that returns `MalformedMessage` instead of raising."""

    def deserialize(data: bytes) -> Any:
        try:
            return message_class.FromString(data)
        except (DecodeError, ValueError) as err:  # ValueError: invalid UTF-8 in a string field
            return MalformedMessage(message_class.DESCRIPTOR.full_name, str(err) or "decode error")

    return deserialize


class InvalidMessage(Exception):
    """A request the transport itself rejects (malformed protobuf); maps to INVALID_ARGUMENT."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(message)
        self.field = field
        self.message = message


def check_parsed(request: Any) -> None:
    """Raise `InvalidMessage` if the deserializer could not parse the request."""
    if isinstance(request, MalformedMessage):
        raise InvalidMessage(
            "request", f"not a valid {request.message_type} protobuf message ({request.problem})"
        )


def _field_and_message(err: BaseException) -> tuple[str | None, str]:
    field = getattr(err, "field", None)
    message = str(getattr(err, "message", None) or err)
    if field and not message.startswith(f"{field}:"):
        message = f"{field}: {message}"
    return field, message


_SESSION_CODES: tuple[tuple[type[EngineError], grpc.StatusCode], ...] = (
    (SessionLimitReached, grpc.StatusCode.RESOURCE_EXHAUSTED),
    (StepConflict, grpc.StatusCode.ABORTED),
    (SessionsUnavailable, grpc.StatusCode.UNIMPLEMENTED),
    (EpisodeIdle, grpc.StatusCode.DEADLINE_EXCEEDED),
)


def status_of(err: BaseException) -> tuple[grpc.StatusCode, str, str | None]:
    """(status code, details message, field) for an error raised while serving a request."""
    if isinstance(err, InvalidRequest | InvalidMessage):
        field, message = _field_and_message(err)
        return grpc.StatusCode.INVALID_ARGUMENT, message, field
    if isinstance(err, ModelNotFound | StoreNotFound | SessionNotFound):
        field, message = _field_and_message(err)
        return grpc.StatusCode.NOT_FOUND, message, field
    for session_error, code in _SESSION_CODES:  # Episode: a client's streams past its bound
        if isinstance(err, session_error):
            field, message = _field_and_message(err)
            return code, message, field
    if isinstance(err, ModelUnavailable):
        return grpc.StatusCode.UNAVAILABLE, str(err), None
    if isinstance(err, ModelStoreError):
        return grpc.StatusCode.UNAVAILABLE, f"model store: {err}", None
    if isinstance(err, EngineError):
        return grpc.StatusCode.INTERNAL, str(err), None
    return grpc.StatusCode.INTERNAL, "internal error (the server logged the details)", None


def abort(context: grpc.ServicerContext, err: BaseException, prefix: str = "") -> NoReturn:
    """End the call with the status `err` maps to; `prefix` goes before the message."""
    code, message, field = status_of(err)
    if code == grpc.StatusCode.INTERNAL:
        log.error("gRPC call failed: %s", err, exc_info=err)
    if field:  # clipped, as the message: both travel in the trailers, whose size is bounded
        context.set_trailing_metadata(((FIELD_METADATA_KEY, clip(field, FIELD_CHARS)),))
    context.abort(code, clip(prefix + message))
    raise AssertionError("grpc context.abort() returned")  # it always raises


def translate_errors(
    handler: Callable[[Any, Request, grpc.ServicerContext], Response],
) -> Callable[[Any, Request, grpc.ServicerContext], Response]:
    """Decorate a unary servicer method: parse check before, error mapping around."""

    @functools.wraps(handler)
    def wrapper(self: Any, request: Request, context: grpc.ServicerContext) -> Response:
        try:
            check_parsed(request)
            return handler(self, request, context)
        except Exception as err:
            abort(context, err)

    return wrapper


def translate_stream_errors(
    handler: Callable[[Any, Iterator[Request], grpc.ServicerContext], Iterator[Response]],
) -> Callable[[Any, Iterator[Request], grpc.ServicerContext], Iterator[Response]]:
    """Decorate a streaming servicer method; the handler may raise `StepError` to add a step."""

    @functools.wraps(handler)
    def wrapper(
        self: Any, requests: Iterator[Request], context: grpc.ServicerContext
    ) -> Iterator[Response]:
        try:
            yield from handler(self, requests, context)
        except StepError as err:
            abort(context, err.cause, prefix=f"step[{err.step}]: ")
        except Exception as err:
            abort(context, err)

    return wrapper


class StepError(Exception):
    """An error at step `step` of a stream (wraps the original error)."""

    def __init__(self, step: int, cause: Exception) -> None:
        super().__init__(f"step[{step}]: {cause}")
        self.step = step
        self.cause = cause
