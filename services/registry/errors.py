"""One error shape for every HTTP error, and the one table mapping domain errors to statuses.

Every 4xx/5xx body is an RFC 9457 problem details object (`application/problem+json`,
`services.problems`): `type`, `title`, `status`, `detail`, `instance`, and the extension
members `code` and `field`; request validation errors also carry `errors` (FastAPI's list, the
first `MAX_DETAILS`). Messages and fields are clipped, so no answer echoes a request without
bound. No error leaves as a bare 500 page: the model store turns database failures into
`StoreUnavailable` (503), and anything unforeseen is still answered in this shape.

| domain error (model_store.errors) | status |
|-----------------------------------|--------|
| NotFound                          | 404    |
| Conflict, AlreadyExists           | 409    |
| ArtifactTooLarge                  | 413    |
| InvalidArgument, InvalidArtifact  | 422    |
| ChecksumMismatch                  | 502    |
| SchemaTooNew, StoreUnavailable    | 503    |
| other ModelStoreError             | 503    |
"""

from __future__ import annotations

import logging
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException

from model_store.errors import (
    ArtifactTooLarge,
    ChecksumMismatch,
    Conflict,
    InvalidArgument,
    ModelStoreError,
    NotFound,
    SchemaTooNew,
    StoreUnavailable,
)
from services.problems import MAX_DETAILS, ProblemResponse, documented, problem

log = logging.getLogger(__name__)

# Most specific first: the first class the error is an instance of decides.
DOMAIN_STATUS: tuple[tuple[type[ModelStoreError], int], ...] = (
    (NotFound, 404),
    (Conflict, 409),
    (ArtifactTooLarge, 413),
    (InvalidArgument, 422),
    (ChecksumMismatch, 502),
    (SchemaTooNew, 503),
    (StoreUnavailable, 503),
    (ModelStoreError, 503),
)


class ApiError(Exception):
    """An HTTP error raised by the API layer itself (auth, media type, body size)."""

    def __init__(
        self,
        status: int,
        code: str,
        message: str,
        *,
        field: str | None = None,
        headers: dict[str, str] | None = None,
    ) -> None:
        super().__init__(message)
        self.status, self.code, self.message = status, code, message
        self.field, self.headers = field, headers


def error_response(
    status: int,
    code: str,
    message: str,
    field: str | None = None,
    *,
    headers: dict[str, str] | None = None,
    details: list[dict[str, str]] | None = None,
    request: Request | None = None,
    instance: str | None = None,
) -> JSONResponse:
    """The problem details answer: `message` is its `detail`, the `instance` the path of
    `request` (or `instance`); the message, the field and at most `MAX_DETAILS` details are
    clipped: whatever a request held, the answer stays small."""
    if request is not None:
        instance = request.url.path
    body = problem(status, code, message, field, instance=instance, details=details)
    return ProblemResponse(body, status_code=status, headers=headers)


def status_of(exc: ModelStoreError) -> int:
    return next(status for cls, status in DOMAIN_STATUS if isinstance(exc, cls))


async def _domain_error(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, ModelStoreError)
    status = status_of(exc)
    if status >= 500:
        log.warning("model store error: %s", exc)
    return error_response(status, exc.code, exc.message, exc.field, request=request)


async def _api_error(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, ApiError)
    return error_response(
        exc.status, exc.code, exc.message, exc.field, headers=exc.headers, request=request
    )


async def _validation_error(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, RequestValidationError)
    errors = list(exc.errors())[:MAX_DETAILS]
    first = errors[0] if errors else {"loc": (), "msg": "invalid request"}
    loc = [str(p) for p in first.get("loc", ())]
    field = ".".join(loc[1:] if len(loc) > 1 else loc) or None
    details = [
        {"field": ".".join(str(p) for p in e.get("loc", ())[1:]), "message": e.get("msg", "")}
        for e in errors
    ]
    message = f"{field}: {first.get('msg')}" if field else str(first.get("msg"))
    return error_response(422, "invalid_request", message, field, details=details, request=request)


async def _http_error(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, StarletteHTTPException)
    code = {404: "not_found", 405: "method_not_allowed"}.get(exc.status_code, "http_error")
    headers = dict(exc.headers) if exc.headers else None
    return error_response(exc.status_code, code, str(exc.detail), headers=headers, request=request)


async def _unexpected(request: Request, exc: Exception) -> JSONResponse:
    return unexpected_response(exc, request.url.path)


def unexpected_response(exc: Exception, path: str | None = None) -> JSONResponse:
    """The 500 answer to an error nothing else handled (logged with its traceback; the answer
    names the exception's class, never its words)."""
    log.exception("unhandled error", exc_info=exc)
    message = f"internal error ({type(exc).__name__}); see the logs"
    return error_response(500, "internal", message, instance=path)


def install_error_handlers(app: FastAPI) -> None:
    app.add_exception_handler(ModelStoreError, _domain_error)
    app.add_exception_handler(ApiError, _api_error)
    app.add_exception_handler(RequestValidationError, _validation_error)
    app.add_exception_handler(StarletteHTTPException, _http_error)
    app.add_exception_handler(Exception, _unexpected)


# For the `responses=` of routes: documents the error shape in OpenAPI.
ERROR_RESPONSES: dict[int | str, dict[str, Any]] = {
    status: documented(description)
    for status, description in (
        (401, "no bearer token"),
        (403, "wrong bearer token"),
        (404, "unknown model, version or alias"),
        (409, "conflicts with the registry's state"),
        (422, "invalid input; `field` names it"),
        (503, "model store unavailable"),
    )
}
