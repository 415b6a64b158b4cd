"""Errors the SDK raises: one base class carrying the server's code, message and field.

| class             | also a            | HTTP status     | gRPC status                  |
|-------------------|-------------------|-----------------|------------------------------|
| `InvalidArgument` | `ValueError`      | 400, 413, 422   | INVALID_ARGUMENT, OUT_OF_RANGE |
| `NotFound`        | `LookupError`     | 404             | NOT_FOUND                    |
| `Unavailable`     | `ConnectionError` | 502, 503, 504, no connection | UNAVAILABLE, DEADLINE_EXCEEDED |
| `Conflict`        |                   | 409 (a session's `expected_step`) | ABORTED           |
| `ResourceExhausted` |                 | 429 (too many sessions) | RESOURCE_EXHAUSTED           |
| `CoexistError`    |                   | anything else   | anything else                |

`code` is the same whichever transport answered: the gRPC status name in lower case
(`invalid_argument`, `not_found`, `unavailable`, `internal`, ...; an HTTP status is mapped to its
gRPC counterpart). `field` names the bad part of the request as the server saw it
(`observation`, `partners[0].goal_probs`, ...) or is None; `message` is the server's (over
HTTP the problem details' `detail`; `coexist_client.transport.error_message` reads the older
`{"error": {...}}` body too).
"""

from __future__ import annotations


class CoexistError(Exception):
    """An error answered by (or on the way to) a coexist server."""

    # True where the server did not act on the request (no connection, HTTP 503, gRPC
    # UNAVAILABLE): safe to send again (`coexist_client.exchange`)
    unsent: bool = False

    def __init__(self, code: str, message: str, field: str | None = None) -> None:
        super().__init__(message)
        self.code = code
        self.message = message
        self.field = field

    def __str__(self) -> str:
        if self.field and not self.message.startswith(f"{self.field}:"):
            return f"{self.code}: {self.field}: {self.message}"
        return f"{self.code}: {self.message}"


class InvalidArgument(CoexistError, ValueError):
    """The request was refused as invalid (REST 4xx, gRPC INVALID_ARGUMENT)."""


class NotFound(CoexistError, LookupError):
    """A model the request needs is not in the store (REST 404, gRPC NOT_FOUND)."""


class Unavailable(CoexistError, ConnectionError):
    """The server (or its model store) cannot be reached or is not ready."""


class Conflict(CoexistError):
    """A session step's `expected_step` is not the session's next step (REST 409)."""


class ResourceExhausted(CoexistError):
    """The server holds its maximum of sessions (REST 429): delete finished ones, or retry."""


_HTTP_CODES = {
    400: "invalid_argument",
    401: "unauthenticated",
    403: "permission_denied",
    404: "not_found",
    409: "aborted",  # the policy API's one 409: a session step conflict (gRPC ABORTED)
    413: "invalid_argument",
    422: "invalid_argument",
    429: "resource_exhausted",
    500: "internal",
    501: "unimplemented",
    502: "unavailable",
    503: "unavailable",
    504: "unavailable",
}
_CLASSES: dict[str, type[CoexistError]] = {
    "invalid_argument": InvalidArgument,
    "out_of_range": InvalidArgument,
    "not_found": NotFound,
    "unavailable": Unavailable,
    "deadline_exceeded": Unavailable,
    "aborted": Conflict,
    "resource_exhausted": ResourceExhausted,
}


def error_for_http(status: int, message: str, field: str | None) -> CoexistError:
    """The SDK error for an HTTP error response."""
    code = _HTTP_CODES.get(status, "unknown")
    return _CLASSES.get(code, CoexistError)(code, message, field)


def error_for_grpc(code_name: str, message: str, field: str | None) -> CoexistError:
    """The SDK error for a gRPC status (`code_name` as in `grpc.StatusCode.X.name`)."""
    code = code_name.lower()
    return _CLASSES.get(code, CoexistError)(code, message, field)
