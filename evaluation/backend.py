"""Where the evaluation gets its action distributions: the inference engine in-process, or a
running policy server through the SDK (HTTP or gRPC). Both answer the same `ActRequest`.

| backend         | built from                                   | one call                         |
|-----------------|----------------------------------------------|----------------------------------|
| `EngineBackend` | an `InferenceEngine` over a model store       | `engine.act(request)`            |
| `ServerBackend` | `CoexistClient` (http://...) or              | `client.act_batch(...)`          |
|                 | `GrpcCoexistClient` (grpc://host:port)       |                                  |

`probs(request)` returns the blended action distributions, shape (B, A), and the models the
server reports it used (name, version, sha256). The evaluation samples actions itself from these
probabilities (common random numbers, see `evaluation.rollout`), so the engine's own sampled
`action` is not used and both backends give the same episodes up to float rounding.

`has_models(request)` asks with a one-row request whether every network a request needs exists
(used to run JL only where a joint network was trained).

A request with more rows than one call may carry (the engine's `max_batch`, a server's
`COEXIST_MAX_BATCH`) goes in consecutive slices of at most `MAX_ROWS` rows: a large suite's
partner calls gather thousands of rows.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Protocol

import numpy as np

from model_store.store import ModelStore
from services.engine import ActRequest, InferenceEngine, ModelNotFound


@dataclass(frozen=True, order=True)
class ModelRecord:
    """One network a result was computed with."""

    name: str
    version: int
    sha256: str
    role: str


class PolicyBackend(Protocol):
    description: str

    def probs(self, request: ActRequest) -> tuple[np.ndarray, set[ModelRecord]]: ...

    def has_models(self, request: ActRequest) -> bool: ...


MAX_ROWS = 4096  # the engine's and the server's default batch limit


def _rows(request: ActRequest, start: int, stop: int) -> ActRequest:
    return replace(request, observations=np.asarray(request.observations)[start:stop])


def _first_row(request: ActRequest) -> ActRequest:
    return _rows(request, 0, 1)


def _sliced(probs: Any, request: ActRequest) -> tuple[np.ndarray, set[ModelRecord]]:
    """`probs(slice)` over consecutive slices of at most `MAX_ROWS` rows, concatenated."""
    n_rows = len(request.observations)
    parts, models = [], set()
    for start in range(0, max(n_rows, 1), MAX_ROWS):
        part, used = probs(_rows(request, start, start + MAX_ROWS))
        parts.append(part)
        models |= used
    return np.concatenate(parts), models


class EngineBackend:
    """The inference engine in-process: the code the REST and gRPC servers run."""

    def __init__(self, engine: InferenceEngine, description: str = "in-process engine") -> None:
        self.engine = engine
        self.description = description

    def probs(self, request: ActRequest) -> tuple[np.ndarray, set[ModelRecord]]:
        if len(request.observations) > MAX_ROWS:
            return _sliced(self.probs, request)
        results = self.engine.act(request)
        probs_BA = np.asarray([r.probs for r in results], dtype=np.float64)
        models = {ModelRecord(m.name, m.version, m.sha256, m.role) for m in results[0].models}
        return probs_BA, models

    def has_models(self, request: ActRequest) -> bool:
        try:
            self.engine.act(_first_row(request))
        except ModelNotFound:
            return False
        return True


class ServerBackend:
    """A running policy server; `client` is an SDK client (`act_batch` over HTTP or gRPC)."""

    def __init__(self, client: Any, description: str) -> None:
        self.client = client
        self.description = description

    def _call(self, request: ActRequest) -> Any:
        """The server's answer as columns (`act_batch_columns`): every field of the request
        sent, the temperature and seed included."""
        return self.client.act_batch_columns(
            request.env,
            request.ego_goal,
            np.asarray(request.observations, dtype=np.float64),
            partners=list(request.partners),
            method=request.method,
            temperature=request.temperature,
            regret_bound=request.regret_bound,
            seed=request.seed,
            alias=request.alias,
            versions=dict(request.versions) or None,
        )

    def probs(self, request: ActRequest) -> tuple[np.ndarray, set[ModelRecord]]:
        if len(request.observations) > MAX_ROWS:
            return _sliced(self.probs, request)
        columns = self._call(request)
        probs_BA = np.asarray(columns.probs, dtype=np.float64)
        models = {ModelRecord(m.name, m.version, m.sha256, m.role) for m in columns.models}
        return probs_BA, models

    def has_models(self, request: ActRequest) -> bool:
        from coexist_client import NotFound

        try:
            self._call(_first_row(request))
        except NotFound:
            return False
        return True


def policy_backend(server: str | None, store: ModelStore | None) -> PolicyBackend:
    """The server at `server` (`server_backend`), else the in-process engine over `store`."""
    if server is not None:
        return server_backend(server)
    if store is None:
        raise ValueError("store: the in-process engine needs a model store (or give a server)")
    return EngineBackend(InferenceEngine(store))


def server_backend(url: str) -> ServerBackend:
    """An SDK client for `url`: `grpc://host:port` speaks gRPC, anything else HTTP."""
    if url.startswith("grpc://"):
        from coexist_client import GrpcCoexistClient

        return ServerBackend(GrpcCoexistClient(url, timeout=120.0), f"gRPC server {url}")
    from coexist_client import CoexistClient

    return ServerBackend(CoexistClient(url, timeout=120.0), f"HTTP server {url}")
