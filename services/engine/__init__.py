"""The inference engine: one per server process, shared by the REST and gRPC transports.

    engine = InferenceEngine(store)               # store: a model_store.ModelStore
    engine.start_refresh_thread()                 # hot reload when aliases move
    [result] = engine.act(ActRequest(env="particle", ego_goal="a2", observations=obs_1D,
                                     partners=(PartnerSpec(index=1, goal="b3"),)))
    result.probs, result.action, result.greedy_action, result.models
    columns = engine.act_columns(batch_request)   # ActColumns: one array per field, B rows
    columns.probs, columns.actions, columns.rows() # rows(): the same as engine.act(batch_request)

| module         | what                                                                   |
|----------------|------------------------------------------------------------------------|
| `engine`       | `InferenceEngine`: the act (check, resolve, forward, blend, sample),   |
|                | envs, refresh (thread), status, stats                                  |
| `validation`   | every field of an `ActRequest` checked, naming the bad one             |
| `planning`     | a request's networks and layout, remembered in one `PlanCache`         |
| `model_cache`  | resolve `name@alias` / pinned versions, load, stack; hot reload        |
| `networks`     | LRU cache, loaded networks, stacked groups and their forward           |
| `messages`     | request / result / status dataclasses (docs/architecture.md contract)  |
| `errors`       | `EngineError`: `InvalidRequest`, `ModelNotFound`, `ModelUnavailable`   |
| `environments` | per-env look-up tables, `GET /v1/envs` info, state -> observation      |
| `goal_inference`| every goal's task net on the partners' views (log-likelihoods, one    |
|                | pass) and partners' actions recovered from consecutive observations    |
"""

from services.engine.engine import InferenceEngine
from services.engine.environments import observations_from_states
from services.engine.errors import EngineError, InvalidRequest, ModelNotFound, ModelUnavailable
from services.engine.messages import (
    DEFAULT_TEMPERATURE,
    METHODS,
    ActColumns,
    ActRequest,
    ActResult,
    EngineStats,
    EngineStatus,
    EnvInfo,
    Method,
    ModelUsed,
    PartnerSpec,
)

__all__ = [
    "DEFAULT_TEMPERATURE",
    "METHODS",
    "ActColumns",
    "ActRequest",
    "ActResult",
    "EngineError",
    "EngineStats",
    "EngineStatus",
    "EnvInfo",
    "InferenceEngine",
    "InvalidRequest",
    "Method",
    "ModelNotFound",
    "ModelUnavailable",
    "ModelUsed",
    "PartnerSpec",
    "observations_from_states",
]
