"""Sessions: a partner's goal inferred online from its observed actions.

    store = SessionStore(engine)                                  # REST: many sessions
    info = store.create(SessionSettings("particle", "a2", (SessionPartner(1, infer=True),)))
    answer = store.step(info.session_id, obs, observed=[Observed(1, action=3)])
    answer.result.probs, answer.beliefs[0].top                    # the action, the belief

    session = Session(engine, settings)                           # gRPC Episode: one stream

| module     | what                                                                        |
|------------|-----------------------------------------------------------------------------|
| `messages` | `SessionPartner`, `SessionSettings`, `Observed`, `PartnerBelief`,           |
|            | `SessionStepResult`, `SessionInfo`                                          |
| `errors`   | `SessionNotFound`, `SessionLimitReached`, `StepConflict`, `SessionsUnavailable`|
| `checks`   | settings checked once at creation; each step's `observed` entries           |
| `session`  | `Session`: one session's state and its all-or-nothing step (step semantics) |
| `store`    | `SessionStore`: in-memory, bounded, expiring, one lock per session          |
| `shared`   | `SharedSessionStore`: the same over Redis or PostgreSQL, for every worker   |
|            | and replica (`COEXIST_SESSION_STORE_URL`); `open_session_store` picks one   |
| `codec`    | a session's settings and state as signed bytes (no pickle)                  |
| `backends` | the Redis and PostgreSQL records: versioned, compare-and-set                |

The transports only translate: REST `services.rest.sessions_api`, gRPC `Episode`
(`services.grpc_api.servicer`). The maths is `policy.belief`; the likelihood pass is
`InferenceEngine.goal_log_likelihoods`.
"""

from services.sessions.errors import (
    SessionError,
    SessionLimitReached,
    SessionNotFound,
    SessionStateInvalid,
    SessionStoreUnavailable,
    SessionsUnavailable,
    StepConflict,
)
from services.sessions.messages import (
    Observed,
    PartnerBelief,
    SessionInfo,
    SessionPartner,
    SessionSettings,
    SessionState,
    SessionStepResult,
)
from services.sessions.session import Session
from services.sessions.shared import SharedSessionStore
from services.sessions.store import SessionStore

__all__ = [
    "Observed",
    "PartnerBelief",
    "Session",
    "SessionError",
    "SessionInfo",
    "SessionLimitReached",
    "SessionNotFound",
    "SessionPartner",
    "SessionSettings",
    "SessionState",
    "SessionStateInvalid",
    "SessionStepResult",
    "SessionStore",
    "SessionStoreUnavailable",
    "SessionsUnavailable",
    "SharedSessionStore",
    "StepConflict",
]
