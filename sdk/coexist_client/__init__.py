"""coexist_client: the client of a coexist policy server, over HTTP or gRPC, sync or async.

| class                              | what                                                       |
|------------------------------------|------------------------------------------------------------|
| `Client`, `AsyncClient`            | the policy API: act, batches, sessions, episodes, envs, health (`client`) |
| `RegistryClient`, `AsyncRegistryClient` | the model registry: list, show, upload, promote, download (`registry`) |
| `JobsClient`, `AsyncJobsClient`    | training jobs: submit, list, get, logs, cancel, wait (`jobs`) |
| `RemotePolicy`                     | a server as the policy of any registered PettingZoo env (`policy`) |

    from coexist_client import Client
    with Client("http://127.0.0.1:8000") as client:            # or "grpc://127.0.0.1:50051"
        a = client.act("particle", "a2", [0.1, 0.4, 0, 0, 0.7, 0.6, 0, 0], partners={1: "b3"})
        print(a.action_meaning, a.probs, a.diagnostics.task_weight)

Errors: `CoexistError(code, message, field)` and its subclasses `InvalidArgument`, `NotFound`,
`Unavailable`, `Conflict` (a session step's `expected_step`), `ResourceExhausted` (too many
sessions); `ChecksumMismatch` (a download whose sha256 is not the registry's). The package
imports nothing of the server: it needs httpx, grpcio, protobuf and numpy.
"""

from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _version

from coexist_client.client import (
    AsyncClient,
    AsyncCoexistClient,
    AsyncGrpcCoexistClient,
    Client,
    CoexistClient,
    GrpcCoexistClient,
)
from coexist_client.errors import (
    CoexistError,
    Conflict,
    InvalidArgument,
    NotFound,
    ResourceExhausted,
    Unavailable,
)
from coexist_client.exchange import Retry
from coexist_client.jobs import AsyncJobsClient, JobInfo, JobLog, JobsClient
from coexist_client.policy import RemotePolicy
from coexist_client.registry import (
    AsyncRegistryClient,
    ChecksumMismatch,
    ModelInfo,
    ModelPage,
    RegistryClient,
    VersionInfo,
)
from coexist_client.sessions import AsyncSession, Session
from coexist_client.types import (
    Action,
    ActionColumns,
    Budget,
    Diagnostics,
    EnvInfo,
    Health,
    ModelUsed,
    PartnerBelief,
    PartnerWeight,
    SessionInfo,
    SessionStep,
)

try:
    __version__ = _version("coexist-client")
except PackageNotFoundError:  # imported from a checkout without installing it
    __version__ = "0+unknown"

__all__ = [
    "Action",
    "ActionColumns",
    "AsyncClient",
    "AsyncCoexistClient",
    "AsyncGrpcCoexistClient",
    "AsyncJobsClient",
    "AsyncRegistryClient",
    "AsyncSession",
    "Budget",
    "ChecksumMismatch",
    "Client",
    "CoexistClient",
    "CoexistError",
    "Conflict",
    "Diagnostics",
    "EnvInfo",
    "GrpcCoexistClient",
    "Health",
    "InvalidArgument",
    "JobInfo",
    "JobLog",
    "JobsClient",
    "ModelInfo",
    "ModelPage",
    "ModelUsed",
    "NotFound",
    "PartnerBelief",
    "PartnerWeight",
    "RegistryClient",
    "RemotePolicy",
    "ResourceExhausted",
    "Retry",
    "Session",
    "SessionInfo",
    "SessionStep",
    "Unavailable",
    "VersionInfo",
]
