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
| `messages`     | request / result / status dataclasses (docs/architecture.md contract)  |
| `errors`       | `EngineError`: `InvalidRequest`, `ModelNotFound`, `ModelUnavailable`   |
| `validation`   | every field of an `ActRequest` checked, naming the bad one             |
| `environments` | per-env look-up tables, `GET /v1/envs` info, state -> observation      |
| `networks`     | LRU cache, loaded networks, stacked groups and their numpy forward     |
| `model_cache`  | resolve `name@alias` / pinned versions, load, stack; hot reload        |
| `assembly`     | member input rows from the views, impact Q per partner, sampling       |
| `fastpath`     | the single-row act: row layouts, Python-float reduce, blend and sample |
| `gathers`      | a row's network inputs as one proven gather of the observation         |
| `goal_inference`| every goal's task net on the partners' views (log-likelihoods, one pass)|
|                | and partners' actions recovered from consecutive observations           |
| `engine`       | `InferenceEngine`: act, envs, refresh (thread), status, stats          |
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
