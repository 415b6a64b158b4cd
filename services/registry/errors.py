"""One error shape for every HTTP error, and the one table mapping domain errors to statuses.

Every 4xx/5xx body is `{"error": {"code": str, "message": str, "field": str | null}}`; request
validation errors also carry `details` (FastAPI's list, the first `MAX_DETAILS`). Messages and
fields are clipped (`error_response`), so no answer echoes a request without bound. No error
leaves as a bare 500 page: the model store turns database failures into `StoreUnavailable`
(503), and anything unforeseen is still answered in this shape.

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
from pydantic import BaseModel
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
    clip,
)

log = logging.getLogger(__name__)

FIELD_CHARS = 200  # field names hold request keys (`versions[...]`): clipped like messages
MAX_DETAILS = 20  # validation details answered (the message names the first)

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


class ErrorBody(BaseModel):
    code: str
    message: str
    field: str | None = None


class ErrorResponse(BaseModel):
    """The body of every error response."""

    error: ErrorBody


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
) -> JSONResponse:
    """The error body; the message, the field and at most `MAX_DETAILS` details, each clipped:
    whatever a request held, the answer stays small."""
    error: dict[str, Any] = {
        "code": code,
        "message": clip(message),
        "field": None if field is None else clip(field, FIELD_CHARS),
    }
    if details is not None:
        error["details"] = [
            {"field": clip(d["field"], FIELD_CHARS), "message": clip(d["message"])}
            for d in details[:MAX_DETAILS]
        ]
    return JSONResponse({"error": error}, status_code=status, headers=headers)


def status_of(exc: ModelStoreError) -> int:
    return next(status for cls, status in DOMAIN_STATUS if isinstance(exc, cls))


async def _domain_error(_request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, ModelStoreError)
    status = status_of(exc)
    if status >= 500:
        log.warning("model store error: %s", exc)
    return error_response(status, exc.code, exc.message, exc.field)


async def _api_error(_request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, ApiError)
    return error_response(exc.status, exc.code, exc.message, exc.field, headers=exc.headers)


async def _validation_error(_request: Request, exc: Exception) -> JSONResponse:
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
    return error_response(422, "invalid_request", message, field, details=details)


async def _http_error(_request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, StarletteHTTPException)
    code = {404: "not_found", 405: "method_not_allowed"}.get(exc.status_code, "http_error")
    headers = dict(exc.headers) if exc.headers else None
    return error_response(exc.status_code, code, str(exc.detail), headers=headers)


async def _unexpected(_request: Request, exc: Exception) -> JSONResponse:
    return unexpected_response(exc)


def unexpected_response(exc: Exception) -> JSONResponse:
    """The 500 answer to an error nothing else handled (logged with its traceback)."""
    log.exception("unhandled error", exc_info=exc)
    return error_response(500, "internal", f"internal error ({type(exc).__name__}); see the logs")


def install_error_handlers(app: FastAPI) -> None:
    app.add_exception_handler(ModelStoreError, _domain_error)
    app.add_exception_handler(ApiError, _api_error)
    app.add_exception_handler(RequestValidationError, _validation_error)
    app.add_exception_handler(StarletteHTTPException, _http_error)
    app.add_exception_handler(Exception, _unexpected)


# For the `responses=` of routes: documents the error shape in OpenAPI.
ERROR_RESPONSES: dict[int | str, dict[str, Any]] = {
    status: {"model": ErrorResponse, "description": description}
    for status, description in (
        (401, "no bearer token"),
        (403, "wrong bearer token"),
        (404, "unknown model, version or alias"),
        (409, "conflicts with the registry's state"),
        (422, "invalid input; `field` names it"),
        (503, "model store unavailable"),
    )
}
