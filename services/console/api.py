"""The web console's own routes, under `/v1/console` (reads: they follow the read-token setting).

| method | path                   | answers                                                        |
|--------|------------------------|----------------------------------------------------------------|
| GET    | `/v1/console/models`   | every model with its versions (number, status, created) and    |
|        |                        | aliases, and the change feed's last event id: the registry     |
|        |                        | page in one request instead of one per model                   |
| GET    | `/v1/console/episode`  | a live episode (`services.console.episodes`) as NDJSON: a      |
|        |                        | header line, one line per step, an end line                    |

Everything else the page does goes through the public API (`/v1/registry`, `/v1/jobs`,
`/v1/envs`) with the token the user typed, so the page can do nothing the API refuses.

The episode's settings are query parameters, so a URL reproduces an episode. They are checked,
and the first step is played, before the answer starts: bad input is a 4xx JSON error naming
the field (`services.rest.errors`); a failure later in the stream (a network deleted meanwhile,
an environment whose step or drawing raised) is a last line `{"type": "error", "error": {code,
message, field}}`, never a stream that stops without a word. The steps are computed in
the thread pool, one line at a time, while the client reads them.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from typing import Annotated, Any

import orjson
from fastapi import APIRouter, Query, Request
from fastapi.responses import StreamingResponse
from starlette.concurrency import run_in_threadpool

import services.registry  # noqa: F401  (first: importing services.deps first is a cycle)
from model_store.entities import Event
from model_store.store import ModelStore
from services.console.episodes import (
    MAX_STEPS,
    EpisodeSettings,
    LiveEpisode,
    parse_indices,
    parse_list,
)

# isort: split
from services.deps import ReadAuth, StoreDep
from services.engine import EngineError, InferenceEngine, ModelUnavailable
from services.rest.errors import ACT_ERROR_RESPONSES

log = logging.getLogger(__name__)

router = APIRouter(prefix="/v1/console", tags=["console"])
STORE_PAGE = 1000  # the store interface's largest page (models, events)
RECENT_EVENTS = 20  # events the feed starts with


def _engine(request: Request) -> InferenceEngine:
    engine: InferenceEngine | None = getattr(request.app.state, "engine", None)
    if engine is None:
        raise ModelUnavailable(None, "the inference engine is not running")
    return engine


def _line(message: dict[str, Any]) -> bytes:
    return orjson.dumps(message) + b"\n"


def _last_events(store: ModelStore) -> list[Event]:
    """The newest `RECENT_EVENTS` events (the store pages oldest first)."""
    recent: list[Event] = []
    since = 0
    while True:
        page = store.events(since_id=since, limit=STORE_PAGE)
        recent = (recent + page)[-RECENT_EVENTS:]
        if len(page) < STORE_PAGE:
            return recent
        since = page[-1].id


@router.get("/models")
def models_overview(
    store: StoreDep,
    _: ReadAuth,
    env: str | None = None,
    kind: Annotated[str | None, Query(pattern="^(task|impact|joint|monitor)$")] = None,
) -> dict[str, Any]:
    """Every model (up to the store's largest page) with its versions, newest first."""
    page = store.list_models(env=env, kind=kind, page_size=STORE_PAGE)
    models = []
    for model in page.items:
        versions = [
            {"version": v.version, "status": v.status, "created_at": v.created_at.isoformat()}
            for v in store.list_versions(model.name)
        ]
        models.append({**model.to_json(), "versions": versions})
    events = _last_events(store)
    return {
        "models": models,
        "truncated": page.next_page_token is not None,
        "last_event_id": events[-1].id if events else 0,
        "recent_events": [e.to_json() for e in events],
    }


@router.get(
    "/episode",
    responses={**ACT_ERROR_RESPONSES, 200: {"content": {"application/x-ndjson": {}}}},
)
async def live_episode(
    request: Request,
    _: ReadAuth,
    env: str,
    ego_goal: str,
    partners: Annotated[str, Query(description="partner goals: 'b3,c1' (agents 1, 2, ...)")] = "",
    infer: Annotated[str, Query(description="partners whose goal the ego infers: '1,2'")] = "",
    methods: Annotated[str, Query(description="one lane per method: 'sl,aail'")] = "sl,aail",
    seed: Annotated[int, Query(ge=0, lt=2**32)] = 0,
    max_steps: Annotated[int, Query(ge=1, le=MAX_STEPS)] = 200,
    alias: str = "production",
    temperature: Annotated[float | None, Query(gt=0)] = None,
) -> StreamingResponse:
    """Play an episode on the server and stream it, one JSON line per step."""
    settings = EpisodeSettings(
        env=env,
        ego_goal=ego_goal,
        partner_goals=parse_list(partners),
        inferred=parse_indices(infer, "infer"),
        methods=parse_list(methods),
        seed=seed,
        max_steps=max_steps,
        alias=alias,
        temperature=temperature,
    )
    engine = _engine(request)

    def start() -> tuple[dict[str, Any], dict[str, Any], Iterator[dict[str, Any]]]:
        episode = LiveEpisode(engine, settings)
        frames = episode.frames()
        return episode.header(), next(frames), frames

    header, first, rest = await run_in_threadpool(start)

    def lines() -> Iterator[bytes]:
        yield _line(header)
        yield _line(first)
        try:
            for frame in rest:
                yield _line(frame)
        except EngineError as err:
            error = {"code": err.code, "message": str(err), "field": err.field}
            yield _line({"type": "error", "error": error})
        except Exception as exc:  # the env's own code (step, drawing): say so, log the trace
            log.exception("console episode of env %r stopped", settings.env)
            message = f"the episode stopped: env {settings.env!r} raised {type(exc).__name__}"
            yield _line({"type": "error", "error": {"code": "internal", "message": message}})

    return StreamingResponse(lines(), media_type="application/x-ndjson")
