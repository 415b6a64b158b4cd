"""Error answers as RFC 9457 problem details (`application/problem+json`), and the pages their
problem types name.

Every HTTP error the server makes outside `/v2` (which keeps the Open Inference Protocol's
`{"error": "<message>"}`, `services.oip.rest`) has this body:

    {"type": "/problems/model_not_found", "title": "Model not found", "status": 404,
     "detail": "versions[particle/task/a2]: no task network: model 'particle/task/a2' has no
     version 7", "instance": "/v1/act", "code": "model_not_found",
     "field": "versions[particle/task/a2]"}

| member     | what                                                                         |
|------------|------------------------------------------------------------------------------|
| `type`     | the problem type, a URI reference resolved against the server's address:     |
|            | `GET` it for a page saying what the problem is and what to do about it;      |
|            | `about:blank` for an HTTP error with no meaning of coexist's own             |
| `title`    | the type's short summary, the same for every occurrence (`about:blank`: the  |
|            | HTTP status phrase)                                                          |
| `status`   | the HTTP status code, repeated                                               |
| `detail`   | this occurrence in words, naming the field at fault (clipped)                |
| `instance` | the path of the request answered (no query string), where one was read      |
| `code`     | extension: the machine-readable code (the last segment of `type`; with       |
|            | `about:blank`, `http_error` or a code not in `PROBLEM_TYPES`), the one       |
|            | clients keyed on before                                                      |
| `field`    | extension: the request field at fault (`partners[0].goal`, `body`), or null  |
| `errors`   | extension, request validation only: each problem as `{field, detail}`, at    |
|            | most `MAX_DETAILS`                                                           |

Messages and fields are clipped, so no answer echoes a request without bound, and none holds a
secret: a token is never part of a message, and `instance` leaves the query string out.
"""

from __future__ import annotations

import html
import re
from http import HTTPStatus
from typing import Any
from urllib.parse import quote

import orjson
from fastapi import APIRouter, HTTPException
from fastapi.responses import HTMLResponse, JSONResponse
from pydantic import BaseModel

from model_store.errors import clip

MEDIA_TYPE = "application/problem+json"
PREFIX = "/problems/"
FIELD_CHARS = 200  # field names hold request keys (`versions[...]`): clipped like messages
MAX_DETAILS = 20  # validation problems answered (`detail` names the first)
INSTANCE_CHARS = 200

# code -> (title, what it means and what to do). A code not here answers as `about:blank`.
PROBLEM_TYPES: dict[str, tuple[str, str]] = {
    "invalid_request": (
        "Invalid request",
        "A field of the request is missing, of the wrong type or out of range, or the body is "
        "not JSON. `field` names it; `errors` lists every problem found. Fix the request.",
    ),
    "invalid_argument": (
        "Invalid argument",
        "A value given to the model registry is not acceptable (a name, a version, a spec). "
        "`field` names it. Fix the request.",
    ),
    "invalid_artifact": (
        "Invalid artifact",
        "Uploaded weights are not a safetensors file matching the spec. Upload the file "
        "`coexist train` wrote for this spec.",
    ),
    "artifact_too_large": (
        "Artifact too large",
        "The uploaded weights are over the server's limit (COEXIST_MAX_ARTIFACT_BYTES).",
    ),
    "body_too_large": (
        "Body too large",
        "The request body is over the server's limit (COEXIST_MAX_BODY_BYTES). Send fewer "
        "rows per request.",
    ),
    "unsupported_media_type": (
        "Unsupported media type",
        "The body is not of the media type the route reads (`detail` says which).",
    ),
    "not_found": (
        "Not found",
        "The model, version, alias, job or route named does not exist.",
    ),
    "model_not_found": (
        "Model not found",
        "No network serves the goal, alias or version asked for. `GET /v1/envs` and "
        "`GET /v1/registry/models` say what is served.",
    ),
    "session_not_found": (
        "Session not found",
        "The session expired, was deleted or was made by another server process. Start a new one.",
    ),
    "method_not_allowed": (
        "Method not allowed",
        "The route exists but does not take this HTTP method (`Allow` lists those it takes).",
    ),
    "conflict": (
        "Conflict",
        "The request conflicts with the registry's or the job's current state (`detail` says "
        "how). Read the current state and decide again.",
    ),
    "already_exists": (
        "Already exists",
        "What the request creates exists already.",
    ),
    "step_conflict": (
        "Step conflict",
        "`expected_step` is not the session's next step: another request moved it first. Read "
        "the session and continue from its step.",
    ),
    "too_many_sessions": (
        "Too many sessions",
        "The server, or this client, holds its maximum of sessions. Retry after `Retry-After` "
        "seconds, or delete sessions no longer used.",
    ),
    "unauthorized": (
        "Token required",
        "The route needs `Authorization: Bearer <token>` (the read or the admin token).",
    ),
    "forbidden": (
        "Token not accepted",
        "The bearer token sent is not valid for this route (writes need the admin token).",
    ),
    "invalid_host": (
        "Host not allowed",
        "The request's `Host` is not a name this server answers to (COEXIST_ALLOWED_HOSTS).",
    ),
    "request_timeout": (
        "Request too slow",
        "The request's head did not arrive in time (COEXIST_HTTP_HEADER_TIMEOUT_S).",
    ),
    "headers_too_large": (
        "Headers too large",
        "The request line and headers are over the server's limit.",
    ),
    "checksum_mismatch": (
        "Checksum mismatch",
        "Stored weights do not match their recorded sha256: the store is damaged. Tell the "
        "operator.",
    ),
    "session_state_invalid": (
        "Session record invalid",
        "The shared session store's record of the session fails its signature or its format: "
        "it was not written by a server with this secret. Start a new session.",
    ),
    "session_store_unavailable": (
        "Session store unavailable",
        "The shared session store cannot be reached. Retry later.",
    ),
    "sessions_unavailable": (
        "Sessions unavailable",
        "This server runs several worker processes and cannot keep sessions. Use `/v1/act` or "
        "the gRPC `Episode` stream.",
    ),
    "model_unavailable": (
        "Model unavailable",
        "The model store cannot be read, or a stored network cannot be used. Retry later.",
    ),
    "store_unavailable": (
        "Model store unavailable",
        "The model store cannot be reached or used. Retry later; the operator sees why in the "
        "logs.",
    ),
    "schema_too_new": (
        "Store schema too new",
        "The model store was migrated by a newer coexist. Upgrade the server.",
    ),
    "model_store_error": (
        "Model store error",
        "The model store failed. Retry later; the operator sees why in the logs.",
    ),
    "engine_error": (
        "Inference error",
        "The request could not be answered by the inference engine (`detail` says why).",
    ),
    "session_error": (
        "Session error",
        "The session could not be used (`detail` says why).",
    ),
    "too_many_connections": (
        "Too many connections",
        "The server holds its maximum of connections. Retry later.",
    ),
    "internal": (
        "Internal error",
        "An error the server did not foresee. The operator finds it in the logs by the "
        "response's `X-Request-ID`.",
    ),
}


def type_of(code: str) -> str:
    """The problem type URI of `code` (`about:blank` for a code without a type of its own)."""
    return PREFIX + code if code in PROBLEM_TYPES else "about:blank"


def problem(
    status: int,
    code: str,
    detail: str,
    field: str | None = None,
    *,
    instance: str | None = None,
    details: list[dict[str, str]] | None = None,
) -> dict[str, Any]:
    """The problem details object (module docstring), every string clipped."""
    # about:blank (a code without a type of its own): the title is the status phrase (RFC
    # 9457, 4.2.1), the code still the one raised
    title = PROBLEM_TYPES[code][0] if code in PROBLEM_TYPES else _phrase(status)
    body: dict[str, Any] = {"type": type_of(code), "title": title, "status": status}
    body["detail"] = clip(detail)
    if instance:  # a URI reference: the decoded path percent-encoded again
        body["instance"] = clip(quote(instance, safe="/!$&'()*+,;=:@"), INSTANCE_CHARS)
    body["code"] = code
    body["field"] = None if field is None else clip(field, FIELD_CHARS)
    if details is not None:
        body["errors"] = [
            {"field": clip(d["field"], FIELD_CHARS), "detail": clip(d["message"])}
            for d in details[:MAX_DETAILS]
        ]
    return body


def problem_bytes(
    status: int, code: str, detail: str, field: str | None = None, *, instance: str | None = None
) -> bytes:
    """`problem(...)` serialised, for the layers that write raw ASGI messages or bytes."""
    return orjson.dumps(problem(status, code, detail, field, instance=instance))


class ProblemResponse(JSONResponse):
    media_type = MEDIA_TYPE


class FieldProblem(BaseModel):
    field: str
    detail: str


class Problem(BaseModel):
    """RFC 9457 problem details: the body of every error response outside `/v2`."""

    type: str
    title: str
    status: int
    detail: str
    instance: str | None = None
    code: str
    field: str | None = None
    errors: list[FieldProblem] | None = None


PROBLEM_SCHEMA = Problem.model_json_schema(ref_template="#/components/schemas/{model}")


def _inline(schema: Any, defs: dict[str, Any]) -> Any:
    """`schema` with its references to `defs` replaced by what they name."""
    if isinstance(schema, dict):
        ref = schema.get("$ref", "")
        if ref.startswith("#/components/schemas/"):
            return _inline(defs[ref.rsplit("/", 1)[1]], defs)
        return {k: _inline(v, defs) for k, v in schema.items() if k != "$defs"}
    if isinstance(schema, list):
        return [_inline(v, defs) for v in schema]
    return schema


INLINE_SCHEMA = _inline(PROBLEM_SCHEMA, PROBLEM_SCHEMA.get("$defs", {}))


def documented(description: str) -> dict[str, Any]:
    """An error response for a route's `responses=`: problem details, as answered (the schema
    inline: a route documents it whichever app includes it; `with_problem_responses` turns it
    into a reference to one component)."""
    return {"description": description, "content": {MEDIA_TYPE: {"schema": INLINE_SCHEMA}}}


def _schema_ref() -> dict[str, Any]:
    return {"$ref": "#/components/schemas/Problem"}


def with_problem_responses(openapi: dict[str, Any]) -> dict[str, Any]:
    """`openapi` with every 4xx and 5xx response outside `/v2` documented as problem details
    (FastAPI documents its own 422 as `application/json` with its validation error model);
    the `Problem` schema joins the components. Changes `openapi` in place and returns it."""
    schemas = openapi.setdefault("components", {}).setdefault("schemas", {})
    defs = PROBLEM_SCHEMA.get("$defs", {})
    schemas.update(defs)
    schemas["Problem"] = {k: v for k, v in PROBLEM_SCHEMA.items() if k != "$defs"}
    schemas["InferenceError"] = V2_ERROR_SCHEMA
    for path, operations in openapi.get("paths", {}).items():
        if path == "/v2" or path.startswith("/v2/"):
            _protocol_errors(operations)
            continue
        for operation in operations.values():
            for status, response in operation.get("responses", {}).items():
                if status[:1] in ("4", "5"):
                    response["content"] = {MEDIA_TYPE: {"schema": _schema_ref()}}
    used = str(openapi.get("paths", {}))
    for name in ("HTTPValidationError", "ValidationError"):
        if f"#/components/schemas/{name}'" not in used:
            schemas.pop(name, None)
    return openapi


# The Open Inference Protocol's error body (`/v2`): one string, as its clients parse it.
V2_ERROR_SCHEMA: dict[str, Any] = {
    "title": "InferenceError",
    "type": "object",
    "required": ["error"],
    "properties": {"error": {"type": "string", "description": "what went wrong"}},
}
V2_ERRORS = {
    "400": "The request does not follow the protocol or names a bad tensor",
    "404": "No such model or model version",
    "503": "The model's store cannot be reached",
}


def _protocol_errors(operations: dict[str, Any]) -> None:
    """A `/v2` route's errors as the protocol answers them: 400, not FastAPI's own 422, with
    `{"error": "<string>"}` (services/oip/rest.py, `error_status`)."""
    for operation in operations.values():
        responses = operation.setdefault("responses", {})
        responses.pop("422", None)
        for status, description in V2_ERRORS.items():
            responses[status] = {
                "description": description,
                "content": {
                    "application/json": {"schema": {"$ref": "#/components/schemas/InferenceError"}}
                },
            }


def _phrase(status: int) -> str:
    try:
        return HTTPStatus(status).phrase
    except ValueError:
        return "Error"


def is_public(path: str) -> bool:
    """Whether `path` is a problem type's page (documentation: open whatever the tokens)."""
    if path == PREFIX.rstrip("/"):
        return True
    return path.startswith(PREFIX) and path[len(PREFIX) :] in PROBLEM_TYPES


router = APIRouter(include_in_schema=False)


@router.get(PREFIX.rstrip("/"))
def problem_index() -> HTMLResponse:
    """Every problem type, linked."""
    items = "".join(
        f'<li><a href="{PREFIX}{code}"><code>{code}</code></a>: {html.escape(title)}</li>'
        for code, (title, _) in PROBLEM_TYPES.items()
    )
    return _page("coexist: problem types", f"<ul>{items}</ul>")


@router.get(PREFIX + "{code}")
def problem_page(code: str) -> HTMLResponse:
    """What the problem type `code` means: the page its `type` URI names."""
    if code not in PROBLEM_TYPES:
        raise HTTPException(404, f"no problem type {clip(code, FIELD_CHARS)!r}")
    title, text = PROBLEM_TYPES[code]
    body = (
        f"<p>{_code_spans(text)}</p><p>Answered as <code>application/problem+json</code> with "
        f'<code>"code": "{code}"</code>. <a href="{PREFIX.rstrip("/")}">All problem types</a>.</p>'
    )
    return _page(f"{title} ({code})", body)


def _code_spans(text: str) -> str:
    """`text` escaped for HTML, its `backquoted` parts as code."""
    return re.sub(r"`([^`]*)`", r"<code>\1</code>", html.escape(text))


def _page(title: str, body: str) -> HTMLResponse:
    return HTMLResponse(
        f"<!doctype html><html lang=en><meta charset=utf-8><title>{html.escape(title)}</title>"
        f"<h1>{html.escape(title)}</h1>{body}</html>"
    )
