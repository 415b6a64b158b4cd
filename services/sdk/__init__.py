"""The coexist Python SDK: typed clients of the policy server over HTTP and gRPC, sync and async.

| client                   | transport                 | target                    |
|--------------------------|---------------------------|---------------------------|
| `CoexistClient`          | REST, httpx (sync)        | `http://127.0.0.1:8000`   |
| `AsyncCoexistClient`     | REST, httpx (async)       | `http://127.0.0.1:8000`   |
| `GrpcCoexistClient`      | gRPC (sync)               | `127.0.0.1:50051`         |
| `AsyncGrpcCoexistClient` | gRPC, grpc.aio            | `127.0.0.1:50051`         |

Every client has `act(env, ego_goal, observation=None, *, state=None, ego_index=0, partners=None,
method="aail", temperature=None, seed=None, alias="production", versions=None) -> Action`,
`act_batch(...) -> list[Action]`, `act_batch_columns(...) -> ActionColumns` (the same batch as
numpy arrays, one per field: the server's columnar format, which `act_batch` also asks for),
`envs() -> list[EnvInfo]`, `health() -> Health` and `episode(env, ego_goal, ...)` (a session
whose `act(observation)` is one environment step).
Partners: `{1: "b3"}`, `{1: {"b3": 0.7, "c": 0.3}}` or a list of PartnerSpec-like objects.

Goals inferred online (issue 9): the HTTP clients' `create_session(env, ego_goal, partners={1:
None}, ...) -> Session` (REST `/v1/sessions`; `session.step(obs, observed={1: 3}) ->
SessionStep`, `session.info()`, `session.close()`), and the gRPC clients' `episode(...,
partners={1: None})` whose `act(obs, observed={1: 3})` answers carry `Action.beliefs`.

Errors: `CoexistError(code, message, field)` and its subclasses `InvalidArgument`, `NotFound`,
`Unavailable`, `Conflict` (a session step's `expected_step`), `ResourceExhausted` (too many
sessions).

    from services.sdk import CoexistClient
    with CoexistClient("http://127.0.0.1:8000") as client:
        a = client.act("particle", "a2", [0.1, 0.4, 0, 0, 0.7, 0.6, 0, 0], partners={1: "b3"})
        print(a.action_meaning, a.probs, a.diagnostics.task_weight)
"""

from services.sdk.errors import (
    CoexistError,
    Conflict,
    InvalidArgument,
    NotFound,
    ResourceExhausted,
    Unavailable,
)
from services.sdk.grpc_aio_client import AsyncGrpcCoexistClient
from services.sdk.grpc_client import GrpcCoexistClient
from services.sdk.http_aio_client import AsyncCoexistClient
from services.sdk.http_client import CoexistClient
from services.sdk.http_sessions import AsyncSession, Session
from services.sdk.jobs import JobsClient as JobsClient  # the job API (services.sdk.jobs)
from services.sdk.types import (
    Action,
    ActionColumns,
    Diagnostics,
    EnvInfo,
    Health,
    ModelUsed,
    PartnerBelief,
    PartnerWeight,
    SessionInfo,
    SessionStep,
)

__all__ = [
    "Action",
    "ActionColumns",
    "AsyncCoexistClient",
    "AsyncGrpcCoexistClient",
    "AsyncSession",
    "CoexistClient",
    "CoexistError",
    "Conflict",
    "Diagnostics",
    "EnvInfo",
    "GrpcCoexistClient",
    "Health",
    "InvalidArgument",
    "ModelUsed",
    "NotFound",
    "PartnerBelief",
    "PartnerWeight",
    "ResourceExhausted",
    "Session",
    "SessionInfo",
    "SessionStep",
    "Unavailable",
]
