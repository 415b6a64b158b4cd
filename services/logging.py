"""Server logs: one JSON object per line (or a plain text line), each with its request id.

    uvicorn.run(..., log_config=log_config("json", "info"), access_log=False)
    app.add_middleware(RequestIdMiddleware)          # done by services.app.create_app

| JSON field    | what                                                                      |
|---------------|---------------------------------------------------------------------------|
| `ts`          | UTC time, ISO 8601 with milliseconds (`2026-05-01T12:00:00.123Z`)         |
| `level`       | `DEBUG`, `INFO`, `WARNING`, `ERROR`, `CRITICAL`                           |
| `logger`      | logger name (`coexist.access`, `services.engine.model_cache`, `uvicorn`…) |
| `msg`         | the message                                                               |
| `request_id`  | id of the HTTP request being served when the line was written, else null  |
| `method`, `route`, `path`, `status`, `duration_ms` | access lines only (logger `coexist.access`) |
| `exc`         | the traceback, when there is one                                          |

Request ids: `RequestIdMiddleware` takes the request's `X-Request-ID` when it is a plain token
(1-128 characters from `A-Za-z0-9._:-`; a load balancer's or client's id is kept, so one id
follows a request through every hop), else makes one (32 hex digits). It sets the id for
every log line written while the request is served (a context variable, which FastAPI copies
into the thread pool of sync handlers), returns it in the response's `X-Request-ID` header, and
writes one access line per request when the response is complete: at INFO, or DEBUG for the
probes `/healthz`, `/readyz` and `/metrics` (a load balancer polls them every few seconds).
`route` is the path template (`/v1/registry/models/{name}/-/versions`), `path` the raw path.
gRPC calls get the same treatment from `services.grpc_api.request_ids` (id in the call's
`x-request-id` metadata, echoed in a unary call's trailers or a stream's initial metadata,
access lines with `method` "GRPC").
"""

from __future__ import annotations

import json
import logging
import os
import re
import time
from collections.abc import Callable
from contextvars import ContextVar
from datetime import UTC, datetime
from typing import Any, Literal

REQUEST_ID_HEADER = "x-request-id"
_HEADER_KEY = REQUEST_ID_HEADER.encode()  # as ASGI spells header names: lower-case bytes
ACCESS_LOGGER = "coexist.access"
PROBE_PATHS = frozenset({"/healthz", "/readyz", "/metrics"})
ACCESS_FIELDS = ("method", "route", "path", "status", "duration_ms")
VALID_REQUEST_ID = re.compile(r"[A-Za-z0-9._:-]{1,128}")

LogFormat = Literal["json", "text"]
request_id_var: ContextVar[str | None] = ContextVar("coexist_request_id", default=None)
access_log = logging.getLogger(ACCESS_LOGGER)


def _timestamp(record: logging.LogRecord) -> str:
    stamp = datetime.fromtimestamp(record.created, UTC).isoformat(timespec="milliseconds")
    return stamp.replace("+00:00", "Z")


class RequestIdFilter(logging.Filter):
    """Stamps every record with the current request id (None outside a request)."""

    def filter(self, record: logging.LogRecord) -> bool:
        if not hasattr(record, "request_id"):
            record.request_id = request_id_var.get()
        return True


class JsonFormatter(logging.Formatter):
    """One JSON object per line (fields in the module docstring)."""

    def format(self, record: logging.LogRecord) -> str:
        data: dict[str, Any] = {
            "ts": _timestamp(record),
            "level": record.levelname,
            "logger": record.name,
            "msg": record.getMessage(),
            "request_id": getattr(record, "request_id", None),
        }
        for key in ACCESS_FIELDS:
            if hasattr(record, key):
                data[key] = getattr(record, key)
        if record.exc_info:
            data["exc"] = self.formatException(record.exc_info)
        return json.dumps(data, default=str, ensure_ascii=False)


class TextFormatter(logging.Formatter):
    """`ts LEVEL logger [request id] message`, for a person at a terminal."""

    def format(self, record: logging.LogRecord) -> str:
        request_id = getattr(record, "request_id", None) or "-"
        line = f"{_timestamp(record)} {record.levelname:<7} {record.name} [{request_id}] "
        line += record.getMessage()
        if record.exc_info:
            line += "\n" + self.formatException(record.exc_info)
        return line


def log_config(log_format: LogFormat = "text", level: str = "info") -> dict[str, Any]:
    """A `logging.config.dictConfig` dict (uvicorn's `log_config`): everything, uvicorn's own
    loggers included, goes to stderr through one handler in `log_format` (alembic's start-up
    lines only at `debug`)."""
    if log_format not in ("json", "text"):
        raise ValueError(f"log_format: expected 'json' or 'text', got {log_format!r}")
    level_name = level.upper()
    if level_name not in ("DEBUG", "INFO", "WARNING", "ERROR", "CRITICAL"):
        raise ValueError(f"log_level: expected debug, info, warning or error, got {level!r}")
    return {
        "version": 1,
        "disable_existing_loggers": False,
        "filters": {"request_id": {"()": RequestIdFilter}},
        "formatters": {"json": {"()": JsonFormatter}, "text": {"()": TextFormatter}},
        "handlers": {
            "default": {
                "class": "logging.StreamHandler",
                "stream": "ext://sys.stderr",
                "formatter": log_format,
                "filters": ["request_id"],
            }
        },
        "root": {"handlers": ["default"], "level": level_name},
        "loggers": {
            **{
                name: {"handlers": [], "level": level_name, "propagate": True}
                for name in ("uvicorn", "uvicorn.error", "uvicorn.access")
            },
            # the store's schema check at start-up: alembic's chatter only when debugging
            "alembic": {"level": "DEBUG" if level_name == "DEBUG" else "WARNING"},
        },
    }


def _request_id_from(scope: dict[str, Any]) -> str:
    for key, value in scope.get("headers", ()):
        if key == _HEADER_KEY:
            candidate = value.decode("latin-1")
            if VALID_REQUEST_ID.fullmatch(candidate):
                return candidate
            break
    return new_request_id()


def new_request_id() -> str:
    """32 random hex digits (the form of `uuid.uuid4().hex`, without building a UUID)."""
    return os.urandom(16).hex()


# `record(route, method, status, seconds)`: what the middleware tells the metrics once a
# response's last byte is sent (`services.metrics.HttpMetrics.record`)
Recorder = Callable[[str, str, int, float], None]


class RequestIdMiddleware:
    """ASGI middleware: request id in, out and on every log line; one access line per request;
    with `record`, the request's count and latency for the metrics; with `tracer`, one span.

    All of a request's observability in one pure ASGI layer: one wrapper of `send`, one clock
    read at each end, the route template looked up once. `on_error(exc, path)`, when given, answers an
    exception that escaped the app before its response started (an ASGI response, e.g. the 500
    error body): here, inside the server's own error layer, the answer still carries the request
    id and the connection stays open. `tracer` (`services.tracing.Tracer`, None when tracing is
    off: then nothing of it runs) opens a server span around the request.
    """

    def __init__(
        self,
        app: Any,
        on_error: Callable[[Exception, str], Any] | None = None,
        record: Recorder | None = None,
        tracer: Any = None,
    ) -> None:
        self.app = app
        self.on_error = on_error
        self.record = record
        self.tracer = tracer

    async def __call__(self, scope: dict[str, Any], receive: Any, send: Any) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        start = time.perf_counter()
        request_id = _request_id_from(scope)
        token = request_id_var.set(request_id)
        id_header = (_HEADER_KEY, request_id.encode())
        status, started, recorded = 500, False, False  # unless a response starts
        record = self.record

        def record_once() -> None:
            nonlocal recorded
            if record is not None and not recorded:
                recorded = True
                record(
                    route_template(scope) or "unmatched",
                    scope["method"],
                    status,
                    time.perf_counter() - start,
                )

        async def send_with_id(message: dict[str, Any]) -> None:
            nonlocal status, started
            if message["type"] == "http.response.start":
                status, started = message["status"], True
                headers = message.get("headers") or []
                if any(h[0] == _HEADER_KEY for h in headers):  # the app's own id gives way
                    headers = [h for h in headers if h[0] != _HEADER_KEY]
                message = {**message, "headers": [*headers, id_header]}
            await send(message)
            # latency to the last byte: a streamed episode counts its whole length, not the
            # time its first frame took
            if message["type"] == "http.response.body" and not message.get("more_body", False):
                record_once()

        span = None if self.tracer is None else self.tracer.http_span(scope, request_id)
        try:
            await self.app(scope, receive, send_with_id)
        except Exception as exc:
            if self.on_error is None or started:
                if span is not None:
                    span.fail(exc)
                raise
            await self.on_error(exc, scope.get("path", ""))(scope, receive, send_with_id)
        finally:
            if started:
                record_once()  # a response cut off before its last byte still counts
            if span is not None:
                span.end(route_template(scope), status)
            _log_access(scope, status, time.perf_counter() - start)
            request_id_var.reset(token)


def _log_access(scope: dict[str, Any], status: int, seconds: float) -> None:
    path = scope.get("path", "")
    level = logging.DEBUG if path in PROBE_PATHS else logging.INFO
    if not access_log.isEnabledFor(level):
        return
    route = route_template(scope)
    method = scope.get("method", "")
    fields = {
        "method": method,
        "route": route,
        "path": path,
        "status": status,
        "duration_ms": round(seconds * 1000, 3),
    }
    access_log.log(level, "%s %s %d %.1f ms", method, path, status, seconds * 1000, extra=fields)


def route_template(scope: dict[str, Any]) -> str | None:
    """The matched route's path template with its routers' prefixes. FastAPI includes routers
    lazily, so `scope["route"].path` lacks the prefix; the include context has it (read
    defensively: without it the template is the bare route path)."""
    path = getattr(scope.get("route"), "path", None)
    if path is None:
        return None
    fastapi_scope = scope.get("fastapi")
    included = fastapi_scope.get("included_router") if isinstance(fastapi_scope, dict) else None
    prefix = getattr(getattr(included, "include_context", None), "prefix", "")
    return f"{prefix}{path}" if isinstance(prefix, str) else path
