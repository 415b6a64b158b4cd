"""The session routes: a partner's goal inferred online over REST.

| route                              | what                                            | answer |
|------------------------------------|-------------------------------------------------|--------|
| `POST /v1/sessions`                | settings checked, beliefs at their priors       | 201    |
| `POST /v1/sessions/{id}/steps`     | update beliefs with `observed`, act on o_t      | 200    |
| `GET /v1/sessions/{id}`            | settings, next step, beliefs, expiry            | 200    |
| `DELETE /v1/sessions/{id}`         | forget the session                              | 204    |

Step semantics are `services.sessions.session`'s. The sessions live in `app.state.sessions` (a
`SessionStore` the app's lifespan creates over the engine; created on first use with defaults
when an app did not set one): a `SharedSessionStore` over Redis or PostgreSQL with
`settings.session_store_url` (every worker and replica serves every session), else a
`SessionStore` in this process's memory, which with `settings.workers` > 1 (`coexist serve
--workers N`) refuses to create one (501: a step could reach another worker); see
docs/architecture.md "Sessions". Errors: those of `/v1/act` (422 naming the field, 404 model
not found, 503) plus 404 `session_not_found`, 409 `step_conflict`, 429 `too_many_sessions` (the
server's `max_sessions`, or the creating client's `max_sessions_per_client`: clients are told
apart by address; a `Retry-After` says when the first slot could free up), 501
`sessions_unavailable`, and with a shared store 410 `session_state_invalid` (its stored record
fails its signature or format) and 503 `session_store_unavailable`.

Speed (a step is the hot route): a valid step or create body reaches its handler without
FastAPI's router and dependency solving (`services.rest.direct_route`, the app's `DirectJson`
middleware); a step's answer is
/v1/act's `ActResponse` written here, its `models` list (36 entries when the whole belief is
blended) written once per set of networks (`_models_fragment`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import orjson
from fastapi import APIRouter, Request, Response
from starlette.background import BackgroundTask

from policy.belief import BeliefConfig
from services.engine import (
    EngineError,
    InferenceEngine,
    InvalidRequest,
    ModelUnavailable,
    ModelUsed,
    observations_from_states,
)
from services.rest.act_api import encoder, model_dicts
from services.rest.errors import SESSION_ERROR_RESPONSES
from services.rest.json_body import FastJsonRoute
from services.rest.session_schemas import (
    SessionBody,
    SessionOut,
    SessionStepBody,
    SessionStepOut,
)
from services.sessions import (
    Observed,
    PartnerBelief,
    SessionInfo,
    SessionPartner,
    SessionSettings,
    SessionStepResult,
    SessionStore,
    SessionsUnavailable,
    SharedSessionStore,
)
from services.sessions.backends import open_backend
from services.sessions.codec import SessionCodec
from services.settings import Settings

router = APIRouter(prefix="/v1/sessions", tags=["sessions"], route_class=FastJsonRoute)


AnyStore = SessionStore | SharedSessionStore


def open_session_store(engine: InferenceEngine, settings: Settings | None) -> AnyStore:
    """The sessions' store for `settings`: shared (Redis or PostgreSQL) with
    `session_store_url`, else this process's memory. `ValueError` for an unusable URL."""
    if settings is None:
        return SessionStore(engine)
    bounds: dict[str, Any] = {
        "max_sessions": settings.max_sessions,
        "max_per_client": settings.max_sessions_per_client,
        "ttl_s": settings.session_ttl_s,
        "prefetch": settings.session_prefetch,
    }
    if not settings.session_store_url:
        return SessionStore(engine, **bounds)
    if settings.session_secret is None:  # check_secure refuses this first
        raise ValueError("COEXIST_SESSION_SECRET: required with COEXIST_SESSION_STORE_URL")
    codec = SessionCodec(settings.session_secret.get_secret_value().encode())
    backend = open_backend(settings.session_store_url, codec.namespace())
    return SharedSessionStore(engine, backend, codec, **bounds)


def session_store(request: Request) -> AnyStore:
    """The app's session store (made on first use over the app's engine if none was set)."""
    state = request.app.state
    store: AnyStore | None = getattr(state, "sessions", None)
    engine: InferenceEngine | None = getattr(state, "engine", None)
    if engine is None:  # as /v1/act answers then
        raise ModelUnavailable(None, "the inference engine is not running")
    if store is None or store.engine is not engine:
        store = open_session_store(engine, getattr(state, "settings", None))
        request.app.state.sessions = store
    return store


def _json(body: Any, status_code: int = 200, headers: Mapping[str, str] | None = None) -> Response:
    return Response(
        orjson.dumps(body), status_code=status_code, media_type="application/json", headers=headers
    )


def _settings(body: SessionBody) -> SessionSettings:
    b = body.belief
    return SessionSettings(
        env=body.env,
        ego_goal=body.ego_goal,
        partners=tuple(
            SessionPartner(p.index, p.goal, p.goal_probs, p.infer) for p in body.partners
        ),
        method=body.method,
        temperature=body.temperature,
        regret_bound=body.regret_bound,
        budget=body.budget,
        seed=body.seed,
        alias=body.alias,
        versions=body.versions,
        belief=BeliefConfig(
            forgetting=b.forgetting,
            floor=b.floor,
            temperature=b.temperature,
            noise=b.noise,
            prune_below=b.prune_below,
            prune_error=b.prune_error,
        ),
        blend_mass=b.blend_mass,
        blend_max_goals=b.blend_max_goals,
    )


# A step's models are the engine's remembered `ModelUsed` objects, the same ones at every step
# while the networks are: their JSON (36 entries for a whole-belief blend) is written once per
# set. Keyed by the objects' ids; the entry holds the objects, so an id is not reused meanwhile.
MODELS_JSON_MAX = 256
_models_json: dict[tuple[int, ...], tuple[tuple[ModelUsed, ...], orjson.Fragment]] = {}


def _models_fragment(models: Sequence[ModelUsed]) -> orjson.Fragment:
    """The answer's `models` list (as /v1/act writes it), as pre-written JSON."""
    key = tuple(map(id, models))
    entry = _models_json.get(key)
    if entry is None:
        if len(_models_json) >= MODELS_JSON_MAX:
            _models_json.clear()
        written = orjson.Fragment(orjson.dumps(model_dicts(models)))
        entry = _models_json[key] = (tuple(models), written)
    return entry[1]


def _step_json(settings: SessionSettings, answer: SessionStepResult) -> dict[str, Any]:
    """`SessionStepOut`: /v1/act's answer (`ActResponse`), then the session's step and beliefs."""
    encode = encoder(settings.env, [p.index for p in settings.partners])
    return {
        **encode(answer.result, _models_fragment(answer.result.models)),
        "session_id": answer.session_id,
        "step": answer.step,
        "beliefs": _beliefs(answer.beliefs),
    }


def _beliefs(beliefs: tuple[PartnerBelief, ...]) -> list[dict[str, Any]]:
    return [
        {
            "index": b.index,
            "top": [{"goal": goal, "prob": prob} for goal, prob in b.top],
            "entropy": b.entropy,
            "observed_action": b.observed_action,
            "updates": b.updates,
        }
        for b in beliefs
    ]


def _session_json(info: SessionInfo) -> dict[str, Any]:
    s = info.settings
    partners = [
        {
            "index": p.index,
            "goal": p.goal,
            "goal_probs": None if p.goal_probs is None else dict(p.goal_probs),
            "infer": p.inferred,
        }
        for p in s.partners
    ]
    belief = {
        "forgetting": s.belief.forgetting,
        "floor": s.belief.floor,
        "temperature": s.belief.temperature,
        "noise": s.belief.noise,
        "blend_mass": s.blend_mass,
        "blend_max_goals": s.blend_max_goals,
        "prune_below": s.belief.prune_below,
        "prune_error": s.belief.prune_error,
    }
    return {
        "session_id": info.session_id,
        "step": info.step,
        "expires_in_s": info.expires_in_s,
        "beliefs": _beliefs(info.beliefs),
        "settings": {
            "env": s.env,
            "ego_goal": s.ego_goal,
            "partners": partners,
            "method": s.method,
            "temperature": s.temperature,
            "regret_bound": s.regret_bound,
            "budget": s.budget,
            "seed": s.seed,
            "alias": s.alias,
            "versions": dict(s.versions),
            "belief": belief,
        },
    }


def _observation(
    settings: SessionSettings | None, body: SessionStepBody
) -> tuple[np.ndarray | list[float], bool]:
    """The step's ego observation and whether it came as a state (`settings` given then)."""
    if (body.observation is None) == (body.state is None):
        raise InvalidRequest(
            "observation", "give exactly one of observation and state (with ego_index)"
        )
    if body.state is None:
        if body.ego_index is not None:
            raise InvalidRequest("ego_index", "only used with state")
        return body.observation or [], False
    if body.ego_index is None:
        raise InvalidRequest("ego_index", "required with state")
    assert settings is not None
    env = settings.env
    return observations_from_states(env, [body.state], body.ego_index, field="state")[0], True


# first: the hot route, matched before the others (each failed match costs time)
@router.post(
    "/{session_id}/steps", response_model=SessionStepOut, responses=SESSION_ERROR_RESPONSES
)
async def step_session(session_id: str, body: SessionStepBody, request: Request) -> Response:
    """One step: the partners' actions since the previous step update the beliefs, then the
    blended action for this observation."""
    store = session_store(request)
    # the settings before the step only for a state (its env turns it into an observation):
    # after it, a shared store has them from the session it just stepped, with no round trip
    settings = store.settings(session_id) if body.state is not None else None
    observation, from_state = _observation(settings, body)
    observed = [Observed(o.index, o.action) for o in body.observed]
    try:
        answer = store.step(session_id, observation, observed, body.expected_step)
    except EngineError as err:
        if from_state and err.field == "observation":
            raise err.renamed("state") from None
        raise
    response = _json(_step_json(settings or store.settings(session_id), answer))
    if store.prefetch:  # after the answer is sent, on this event loop (no thread hop)
        response.background = BackgroundTask(_prepare_next, store, session_id)
    return response


async def _prepare_next(store: AnyStore, session_id: str) -> None:
    """The next step's evidence scored ahead (`Session.prepare_next`): runs once the step's
    answer is on the socket, while the client reads it and sends its next step."""
    store.prepare_next(session_id)


@router.post("", status_code=201, response_model=SessionOut, responses=SESSION_ERROR_RESPONSES)
async def create_session(body: SessionBody, request: Request) -> Response:
    """A new session; its beliefs start at the partners' priors. Expires when idle."""
    store = session_store(request)
    settings = getattr(request.app.state, "settings", None)
    if settings is not None and settings.workers > 1 and isinstance(store, SessionStore):
        raise SessionsUnavailable(
            None,
            f"this server runs {settings.workers} worker processes and keeps sessions in the "
            "memory of one: set COEXIST_SESSION_STORE_URL (Redis or PostgreSQL) and "
            "COEXIST_SESSION_SECRET so that every worker serves every session, run one worker "
            "(coexist serve --workers 1), or use the gRPC Episode stream, which is a session "
            "on one connection",
        )
    client = request.client.host if request.client is not None else ""
    info = store.create(_settings(body), client)
    location = f"/v1/sessions/{info.session_id}"
    return _json(_session_json(info), status_code=201, headers={"Location": location})


@router.get("/{session_id}", response_model=SessionOut, responses=SESSION_ERROR_RESPONSES)
async def get_session(session_id: str, request: Request) -> Response:
    """The session's settings, next step, beliefs and idle time left (does not extend it)."""
    return _json(_session_json(session_store(request).get(session_id)))


@router.delete("/{session_id}", status_code=204, responses=SESSION_ERROR_RESPONSES)
async def delete_session(session_id: str, request: Request) -> Response:
    """Forget the session now (rather than at expiry)."""
    session_store(request).delete(session_id)
    return Response(status_code=204)
