"""The inference routes: `POST /v1/act`, `POST /v1/act:batch`, `GET /v1/envs`.

    app.include_router(router)
    app.state.engine = InferenceEngine(store)     # the routes read the engine from here
    install_error_handlers(app)                   # services.rest.errors

The handlers are `async def` and call the engine directly (no thread-pool hop: a forward takes
microseconds); they only translate JSON to an `ActRequest` and the results back, written with
orjson; a valid JSON body comes straight from the app's `DirectJson` middleware, without
FastAPI's router and dependency solving (`direct_route`; its share of an act: docs/performance.md).
A batch with `"format": "columns"` is answered from `engine.act_columns`: one array per field,
written by orjson straight from numpy, and the models once, not per row.
Field names in errors follow the body: a single request's `observation` (or `state`), a batch's
`observations[i]` (or `states[i]`). A `state` is turned into the ego's observation by the
environment's perspective transform (`services.engine.observations_from_states`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, TypeVar

import numpy as np
import orjson
from fastapi import APIRouter, Request, Response

from services.engine import (
    ActColumns,
    ActRequest,
    ActResult,
    EngineError,
    InferenceEngine,
    InvalidRequest,
    ModelUnavailable,
    ModelUsed,
    PartnerSpec,
    observations_from_states,
)
from services.engine.environments import env_runtime
from services.rest.errors import ACT_ERROR_RESPONSES
from services.rest.json_body import FastJsonRoute
from services.rest.schemas import (
    ActBatchBody,
    ActBatchResponse,
    ActBody,
    ActColumnsResponse,
    ActFields,
    ActResponse,
    EnvsResponse,
)

router = APIRouter(prefix="/v1", tags=["inference"], route_class=FastJsonRoute)


def _engine(request: Request) -> InferenceEngine:
    engine: InferenceEngine | None = getattr(request.app.state, "engine", None)
    if engine is None:
        raise ModelUnavailable(None, "the inference engine is not running")
    return engine


def _json(body: Any) -> Response:
    # OPT_SERIALIZE_NUMPY: arrays (C-contiguous, float64 / int64) written without a list copy
    return Response(
        orjson.dumps(body, option=orjson.OPT_SERIALIZE_NUMPY), media_type="application/json"
    )


def _rename(field: str | None, source: str, single: bool) -> str | None:
    """Engine field names -> body field names (`observations[0]` -> `observation`)."""
    if field is None:
        return None
    for prefix in ("observations", "states", "state"):
        if field == prefix or field.startswith(prefix + "["):
            return source if single else source + field[len(prefix) :]
    return field


Encoder = Callable[[ActResult, Any], dict[str, Any]]  # (result, its `models` JSON) -> answer
Answer = TypeVar("Answer", list[ActResult], ActColumns)


def _act(
    run: Callable[[ActRequest], Answer], body: ActFields, rows: Any, states: Any, single: bool
) -> tuple[Answer, tuple[PartnerSpec, ...]]:
    """`run` (`engine.act` or `engine.act_columns`) on the body's observations or states, and the
    partners; errors name the body's fields."""
    obs_name, state_name = ("observation", "state") if single else ("observations", "states")
    if (rows is None) == (states is None):
        message = f"give exactly one of {obs_name} and {state_name} (with ego_index)"
        raise InvalidRequest(obs_name, message)
    source = obs_name if states is None else state_name
    try:
        if states is None:
            if body.ego_index is not None:
                raise InvalidRequest("ego_index", f"only used with {state_name}")
            obs = np.asarray([rows] if single else rows, dtype=np.float64)
        else:
            if body.ego_index is None:
                raise InvalidRequest("ego_index", f"required with {state_name}")
            obs = observations_from_states(
                body.env, [states] if single else states, body.ego_index, field=state_name
            )
        partners = tuple(PartnerSpec(p.index, p.goal, p.goal_probs) for p in body.partners)
        request = ActRequest(
            env=body.env,
            ego_goal=body.ego_goal,
            observations=obs,
            partners=partners,
            method=body.method,
            temperature=body.temperature,
            regret_bound=body.regret_bound,
            budget=body.budget,
            budget_spent=_budget_rows(getattr(body, "budget_spent", None), single),
            budget_total=_budget_rows(getattr(body, "budget_total", None), single),
            budget_value=_budget_rows(getattr(body, "budget_value", None), single),
            seed=body.seed,
            alias=body.alias,
            versions=body.versions,
        )
        answer = run(request)
    except EngineError as exc:
        raise exc.renamed(_rename(exc.field, source, single)) from None
    except ValueError as exc:  # ragged rows: np.asarray refuses them
        raise InvalidRequest(source, f"expected rows of equal length ({exc})") from None
    return answer, partners


def _budget_rows(values: Any, single: bool) -> Any:
    """A body's carried budget state as the engine's per-row form."""
    if values is None or not single:
        return values
    return [values]


def encoder(env: str, partner_indices: Sequence[int]) -> Encoder:
    """The `ActResponse` JSON of a result (also the first fields of a session step's answer)."""
    meanings = env_runtime(env).info.action_meanings

    def encode(result: ActResult, models: Any) -> dict[str, Any]:
        weights = [
            {"index": index, "weight": w}
            for index, w in zip(partner_indices, result.partner_weights, strict=True)
        ]
        answer = {
            "probs": result.probs,
            "action": result.action,
            "greedy_action": result.greedy_action,
            "action_meaning": meanings[result.action],
            "method": result.method,
            "diagnostics": {
                "task_entropy": result.task_entropy,
                "task_weight": result.task_weight,
                "partner_weights": weights,
            },
            "models": models,
        }
        if result.budget_total is not None:
            answer["budget"] = {
                "spent": result.budget_spent,
                "total": result.budget_total,
                "value": result.budget_value,
            }
        return answer

    return encode


def model_dicts(models: Sequence[ModelUsed]) -> list[dict[str, Any]]:
    """The `models` JSON of an answer."""
    return [
        {
            "role": m.role,
            "name": m.name,
            "version": m.version,
            "sha256": m.sha256,
            "partner_index": m.partner_index,
            "goal": m.goal,
        }
        for m in models
    ]


def _columns(env: str, partners: Sequence[PartnerSpec], columns: ActColumns) -> dict[str, Any]:
    """The `ActColumnsResponse` JSON; the arrays stay numpy (`_json` writes them)."""
    meanings = env_runtime(env).info.action_meanings
    return {
        "format": "columns",
        "method": columns.method,
        "models": model_dicts(columns.models),
        "probs": np.ascontiguousarray(columns.probs),
        "actions": np.ascontiguousarray(columns.actions),
        "greedy_actions": np.ascontiguousarray(columns.greedy_actions),
        "action_meanings": [meanings[a] for a in columns.actions.tolist()],
        "task_entropies": np.ascontiguousarray(columns.task_entropies),
        "task_weights": np.ascontiguousarray(columns.task_weights),
        "partner_indices": [p.index for p in partners],
        "partner_weights": np.ascontiguousarray(columns.partner_weights),
        **(
            {}
            if columns.budget_total is None
            or columns.budget_spent is None
            or columns.budget_value is None
            else {
                "budget_spent": np.ascontiguousarray(columns.budget_spent),
                "budget_total": np.ascontiguousarray(columns.budget_total),
                "budget_value": np.ascontiguousarray(columns.budget_value),
            }
        ),
    }


@router.post("/act", response_model=ActResponse, responses=ACT_ERROR_RESPONSES)
async def act(body: ActBody, request: Request) -> Response:
    """The blended action distribution for one ego observation (or global state + ego index)."""
    engine = _engine(request)
    results, partners = _act(engine.act, body, body.observation, body.state, single=True)
    encode = encoder(body.env, [p.index for p in partners])
    return _json(encode(results[0], model_dicts(results[0].models)))


@router.post(
    "/act:batch",
    response_model=ActBatchResponse | ActColumnsResponse,
    responses=ACT_ERROR_RESPONSES,
)
async def act_batch(body: ActBatchBody, request: Request) -> Response:
    """One result per observation (or state), evaluated in one vectorised pass; with
    `"format": "columns"` one array per field instead (`ActColumnsResponse`)."""
    engine, rows, states = _engine(request), body.observations, body.states
    if body.format == "columns":
        columns, partners = _act(engine.act_columns, body, rows, states, single=False)
        return _json(_columns(body.env, partners, columns))
    results, partners = _act(engine.act, body, rows, states, single=False)
    encode = encoder(body.env, [p.index for p in partners])
    models = model_dicts(results[0].models)  # the same networks serve every row
    return _json({"results": [encode(r, models) for r in results]})


@router.get("/envs", response_model=EnvsResponse)
async def envs(request: Request) -> Response:
    """Every environment: goals, action meanings, observation layouts, methods."""
    return _json(
        {
            "envs": [
                {
                    "name": info.name,
                    "goals": list(info.goals),
                    "action_meanings": list(info.action_meanings),
                    "max_agents": info.max_agents,
                    "obs_dims": {str(n): d for n, d in info.obs_dims.items()},
                    "observation_layouts": {
                        str(n): layout for n, layout in info.observation_layouts.items()
                    },
                    "state_layout": None if info.state_layout is None else list(info.state_layout),
                    "pair_obs_dim": info.pair_obs_dim,
                    "methods": list(info.methods),
                }
                for info in _engine(request).envs()
            ]
        }
    )
