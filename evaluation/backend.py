"""Where the evaluation gets its action distributions: the inference engine in-process, or a
running policy server through the SDK (HTTP or gRPC). Both answer the same `ActRequest`.

| backend         | built from                                   | one call                         |
|-----------------|----------------------------------------------|----------------------------------|
| `EngineBackend` | an `InferenceEngine` over a model store       | `engine.act(request)`            |
| `ServerBackend` | `CoexistClient` (http://...) or              | `client.act_batch(...)`          |
|                 | `GrpcCoexistClient` (grpc://host:port)       |                                  |

`answer(request)` returns the blended action distributions, shape (B, A), the models the
server reports it used (name, version, sha256) and, for `aail_budget`, each row's episode budget
state to carry to its next step (`policy.regret_budget`); `probs(request)` the first two. The evaluation samples actions itself from these
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


@dataclass(frozen=True, eq=False)
class Answer:
    """What a backend answered for B rows."""

    probs_BA: np.ndarray
    models: set[ModelRecord]
    budget_spent_B: np.ndarray | None = None  # aail_budget: S after this step
    budget_total_B: np.ndarray | None = None  # aail_budget: the episode's budget B
    budget_value_B: np.ndarray | None = None  # aail_budget: the ego's task value V here


class PolicyBackend(Protocol):
    description: str

    def answer(self, request: ActRequest) -> Answer: ...

    def probs(self, request: ActRequest) -> tuple[np.ndarray, set[ModelRecord]]: ...

    def has_models(self, request: ActRequest) -> bool: ...


MAX_ROWS = 4096  # the engine's and the server's default batch limit


def _rows(request: ActRequest, start: int, stop: int) -> ActRequest:
    def part(values: Any) -> Any:
        return None if values is None else np.asarray(values)[start:stop]

    return replace(
        request,
        observations=np.asarray(request.observations)[start:stop],
        budget_spent=part(request.budget_spent),
        budget_total=part(request.budget_total),
        budget_value=part(request.budget_value),
    )


def _first_row(request: ActRequest) -> ActRequest:
    return _rows(request, 0, 1)


def _sliced(answer: Any, request: ActRequest) -> Answer:
    """`answer(slice)` over consecutive slices of at most `MAX_ROWS` rows, concatenated."""
    n_rows = len(request.observations)
    parts: list[Answer] = [
        answer(_rows(request, start, start + MAX_ROWS))
        for start in range(0, max(n_rows, 1), MAX_ROWS)
    ]

    def joined(values: list[np.ndarray | None]) -> np.ndarray | None:
        return None if values[0] is None else np.concatenate(values)  # type: ignore[arg-type]

    return Answer(
        np.concatenate([p.probs_BA for p in parts]),
        set().union(*(p.models for p in parts)),
        joined([p.budget_spent_B for p in parts]),
        joined([p.budget_total_B for p in parts]),
        joined([p.budget_value_B for p in parts]),
    )


def _models(models: Any) -> set[ModelRecord]:
    return {ModelRecord(m.name, m.version, m.sha256, m.role) for m in models}


class EngineBackend:
    """The inference engine in-process: the code the REST and gRPC servers run."""

    def __init__(self, engine: InferenceEngine, description: str = "in-process engine") -> None:
        self.engine = engine
        self.description = description

    def answer(self, request: ActRequest) -> Answer:
        if len(request.observations) > MAX_ROWS:
            return _sliced(self.answer, request)
        columns = self.engine.act_columns(request)
        return Answer(
            columns.probs,
            _models(columns.models),
            columns.budget_spent,
            columns.budget_total,
            columns.budget_value,
        )

    def probs(self, request: ActRequest) -> tuple[np.ndarray, set[ModelRecord]]:
        answer = self.answer(request)
        return answer.probs_BA, answer.models

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
            budget=request.budget,
            budget_spent=_listed(request.budget_spent),
            budget_total=_listed(request.budget_total),
            budget_value=_listed(request.budget_value),
            seed=request.seed,
            alias=request.alias,
            versions=dict(request.versions) or None,
        )

    def answer(self, request: ActRequest) -> Answer:
        if len(request.observations) > MAX_ROWS:
            return _sliced(self.answer, request)
        columns = self._call(request)

        def column(values: Any) -> np.ndarray | None:
            return None if values is None else np.asarray(values, dtype=np.float64)

        return Answer(
            np.asarray(columns.probs, dtype=np.float64),
            _models(columns.models),
            column(columns.budget_spent),
            column(columns.budget_total),
            column(columns.budget_value),
        )

    def probs(self, request: ActRequest) -> tuple[np.ndarray, set[ModelRecord]]:
        answer = self.answer(request)
        return answer.probs_BA, answer.models

    def has_models(self, request: ActRequest) -> bool:
        from coexist_client import NotFound

        try:
            self._call(_first_row(request))
        except NotFound:
            return False
        return True


def _listed(values: Any) -> list[float] | None:
    return None if values is None else np.asarray(values, dtype=np.float64).tolist()


def policy_backend(
    server: str | None,
    store: ModelStore | None,
    *,
    goal_oracle: bool = True,
    goal_monitors: bool = True,
) -> PolicyBackend:
    """The server at `server` (`server_backend`), else the in-process engine over `store`;
    `goal_oracle` False: the engine's AAIL-B asks the environment nothing, and with
    `goal_monitors` False no goal monitor either (in process only, `InferenceEngine`)."""
    if server is not None:
        if not (goal_oracle and goal_monitors):
            raise ValueError("goal_oracle: only the in-process engine can be told not to ask")
        return server_backend(server)
    if store is None:
        raise ValueError("store: the in-process engine needs a model store (or give a server)")
    engine = InferenceEngine(store, goal_oracle=goal_oracle, goal_monitors=goal_monitors)
    return EngineBackend(engine, _ENGINE_DESCRIPTIONS[(goal_oracle, goal_monitors)])


# how the in-process engine's AAIL-B gets R2-R4, by (goal_oracle, goal_monitors)
_ENGINE_DESCRIPTIONS = {
    (True, True): "in-process engine",
    (True, False): "in-process engine without goal monitors (AAIL-B's R2-R4: the environment's "
    "answers where it gives them, else R1 on every row)",
    (False, True): "in-process engine without the goal oracle (AAIL-B's R2-R4: the goal "
    "monitors where registered, else R1 on every row)",
    (False, False): "in-process engine without the goal oracle and without goal monitors "
    "(AAIL-B's R2-R4: neither: R1 on every row)",
}


def server_backend(url: str) -> ServerBackend:
    """An SDK client for `url`: `grpc://host:port` speaks gRPC, anything else HTTP."""
    if url.startswith("grpc://"):
        from coexist_client import GrpcCoexistClient

        return ServerBackend(GrpcCoexistClient(url, timeout=120.0), f"gRPC server {url}")
    from coexist_client import CoexistClient

    return ServerBackend(CoexistClient(url, timeout=120.0), f"HTTP server {url}")
