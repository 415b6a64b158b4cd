"""Errors of the session store. They are `EngineError`s (field + message), so the transports'
existing error mapping carries them; each transport maps them to its status in its one place.

| error                 | meaning                                              | REST | gRPC               |
|-----------------------|------------------------------------------------------|------|--------------------|
| `SessionNotFound`     | no such session: expired, deleted, or made elsewhere | 404  | NOT_FOUND          |
| `SessionLimitReached` | `max_sessions` live sessions, or `max_per_client` of | 429 + `Retry-After` | RESOURCE_EXHAUSTED |
|                       | the creating client (after purging expired)          |      |                    |
| `StepConflict`        | `expected_step` is not the session's next step       | 409  | ABORTED            |
| `SessionsUnavailable` | this server cannot keep sessions (several workers)   | 501  | UNIMPLEMENTED      |
| `SessionStateInvalid` | the shared store's record of the session fails its   | 410  | (REST only: the    |
|                       | tag or format: that session cannot go on             |      | `Episode` stream   |
| `SessionStoreUnavailable` | the shared session store does not answer         | 503  | keeps no store)    |

Bad input to a step (observation length, an `observed` entry, ...) is `InvalidRequest`, as for
`/v1/act`.
"""

from __future__ import annotations

from model_store.errors import brief
from services.engine.errors import EngineError


class SessionError(EngineError):
    """Base class of the session errors."""

    code = "session_error"


class SessionNotFound(SessionError, LookupError):
    code = "session_not_found"

    def __init__(self, session_id: str, reason: str) -> None:
        super().__init__("session_id", f"session {brief(session_id)} not found: {reason}")
        self.session_id = session_id


class SessionLimitReached(SessionError):
    """The server's `max_sessions`, or the client's `max_per_client`, are live; `retry_after_s`:
    when the first of them (the client's, for its own limit) expires if left idle."""

    code = "too_many_sessions"

    # what a REST client can do about it; a gRPC `Episode` client is told its own remedy
    REST_REMEDY = (
        "delete finished sessions (DELETE /v1/sessions/{id}) or retry after idle ones expire"
    )

    def __init__(
        self,
        limit: int,
        retry_after_s: float = 0.0,
        *,
        per_client: bool = False,
        what: str = "live sessions",
        remedy: str = REST_REMEDY,
    ) -> None:
        holder = "this client holds its" if per_client else "the server holds its"
        super().__init__(None, f"{holder} maximum of {limit} {what}; {remedy}")
        self.limit, self.retry_after_s, self.per_client = limit, retry_after_s, per_client


class StepConflict(SessionError):
    code = "step_conflict"

    def __init__(self, session_id: str, expected: int, actual: int, raced: bool = False) -> None:
        why = (
            "another request stepped it at the same time, on another server process, and its "
            "step was applied instead of this one; send the next step with expected_step"
            if raced
            else "another request stepped it, or a retry of an answered step"
        )
        super().__init__(
            "expected_step",
            f"session {brief(session_id)} is at step {actual}, not {expected} ({why})",
        )
        self.expected = expected
        self.actual = actual


class SessionsUnavailable(SessionError):
    code = "sessions_unavailable"


class SessionStateInvalid(SessionError):
    """The shared store holds a record of the session that this deployment cannot trust or
    read (`services.sessions.codec`); the other sessions are untouched."""

    code = "session_state_invalid"

    def __init__(self, session_id: str, reason: str) -> None:
        super().__init__(
            "session_id",
            f"session {brief(session_id)} cannot go on: {reason}; create a new session",
        )
        self.session_id = session_id


class SessionStoreUnavailable(SessionError):
    """The shared session store (`COEXIST_SESSION_STORE_URL`) did not answer; the message names
    it (without a password) and the cause. Nothing was changed by the failed request."""

    code = "session_store_unavailable"
