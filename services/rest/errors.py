"""Engine errors and request-validation errors as 4xx problem details, in the registry's shape.

Every error body is an RFC 9457 problem details object (`application/problem+json`, written by
`services.registry.errors.error_response`, described in `services.problems`): `detail` says what
is wrong, the extension members `code` (below) and `field` name the problem and the field at
fault; validation errors add `errors`, one `{field, detail}` per problem. Fields use the
engine's naming: `partners[0].goal`, `observation`, `versions[particle/task/a2]`; malformed JSON
is blamed on `body`.

| error                              | status | code              |
|------------------------------------|--------|-------------------|
| `InvalidRequest`                   | 422    | invalid_request   |
| request validation (types, JSON)   | 422    | invalid_request   |
| `ModelNotFound`                    | 404    | model_not_found   |
| `ModelUnavailable`                 | 503    | model_unavailable |
| `SessionNotFound`                  | 404    | session_not_found |
| `StepConflict`                     | 409    | step_conflict     |
| `SessionLimitReached`              | 429    | too_many_sessions (with `Retry-After`) |
| `SessionsUnavailable`              | 501    | sessions_unavailable (several workers) |
| `SessionStateInvalid`              | 410    | session_state_invalid (shared store)   |
| `SessionStoreUnavailable`          | 503    | session_store_unavailable              |
| a body that is not UTF-8 (FastAPI) | 400    | (the app's HTTPException handler) |

`install_error_handlers(app)` registers both handlers. Call it *after* the registry's
`install_error_handlers`: the request-validation handler is app-wide and the later one wins
(this one formats list positions as `[i]` and blames malformed JSON on `body`).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse

from services.engine.errors import EngineError, InvalidRequest, ModelNotFound, ModelUnavailable
from services.problems import MAX_DETAILS, documented
from services.registry.errors import error_response
from services.sessions.errors import (
    SessionLimitReached,
    SessionNotFound,
    SessionStateInvalid,
    SessionStoreUnavailable,
    SessionsUnavailable,
    StepConflict,
)

log = logging.getLogger(__name__)

ENGINE_STATUS: tuple[tuple[type[EngineError], int], ...] = (
    (SessionNotFound, 404),
    (StepConflict, 409),
    (SessionLimitReached, 429),
    (SessionsUnavailable, 501),
    (SessionStateInvalid, 410),
    (SessionStoreUnavailable, 503),
    (InvalidRequest, 422),
    (ModelNotFound, 404),
    (ModelUnavailable, 503),
    (EngineError, 422),
)

# For the `responses=` of routes: documents the problem details in OpenAPI.
ACT_ERROR_RESPONSES: dict[int | str, dict[str, Any]] = {
    400: documented("the body cannot be decoded (not UTF-8)"),
    404: documented("no network for a goal, alias or version"),
    422: documented("invalid request; `field` names it"),
    503: documented("model store unavailable or model unusable"),
}

# The session routes: the same, plus the session store's errors.
SESSION_ERROR_RESPONSES: dict[int | str, dict[str, Any]] = {
    **ACT_ERROR_RESPONSES,
    404: documented(
        "no such session (expired, deleted, made by another process) or no network for a goal"
    ),
    409: documented("`expected_step` is not the next step"),
    429: documented(
        "the server, or this client, holds its maximum of sessions; `Retry-After` says when "
        "the first could expire"
    ),
    410: documented("the shared store's record of the session fails its signature or format"),
    501: documented("this server cannot keep sessions (workers > 1)"),
    503: documented("model store, model, or the shared session store unavailable"),
}


def engine_status(exc: EngineError) -> int:
    return next(status for cls, status in ENGINE_STATUS if isinstance(exc, cls))


def field_path(loc: Sequence[int | str]) -> str:
    """("body", "partners", 0, "goal") -> "partners[0].goal"; ("body",) -> "body"."""
    parts = list(loc[1:]) if len(loc) > 1 and loc[0] in ("body", "query", "path") else list(loc)
    path = ""
    for part in parts:
        path += f"[{part}]" if isinstance(part, int) else (f".{part}" if path else str(part))
    return path or "body"


async def _engine_error(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, EngineError)
    status = engine_status(exc)
    if status >= 500:
        log.warning("inference engine error: %s", exc)
    headers = None
    if isinstance(exc, SessionLimitReached):  # whole seconds, at least 1 (RFC 9110)
        headers = {"Retry-After": str(max(1, math.ceil(exc.retry_after_s)))}
    return error_response(status, exc.code, str(exc), exc.field, headers=headers, request=request)


async def _validation_error(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, RequestValidationError)
    details = []
    for error in exc.errors()[:MAX_DETAILS]:
        if error.get("type") == "json_invalid":
            position = error.get("loc", ("body", "?"))[-1]
            reason = error.get("ctx", {}).get("error", "invalid JSON")
            details.append({"field": "body", "message": f"malformed JSON at {position}: {reason}"})
        else:
            details.append({"field": field_path(error.get("loc", ())), "message": error["msg"]})
    first = details[0] if details else {"field": "body", "message": "invalid request"}
    message = f"{first['field']}: {first['message']}"
    return error_response(
        422, "invalid_request", message, first["field"], details=details, request=request
    )


def install_error_handlers(app: FastAPI) -> None:
    """Map `EngineError` and request-validation errors to problem details."""
    app.add_exception_handler(EngineError, _engine_error)
    app.add_exception_handler(RequestValidationError, _validation_error)
