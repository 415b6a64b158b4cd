"""Registered models: list (filters, pages), create, get with versions, update, delete; and the
change feed (`/changes` token with ETag/If-None-Match, `/events`).

Handlers are plain `def`: the store is synchronous, FastAPI runs them in its thread pool.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Header, Query, Response, status

from model_store.sql.sql_store import MAX_EVENT_ID
from services.deps import ReadAuth, StoreDep, WriteAuth
from services.registry.errors import ERROR_RESPONSES
from services.registry.schemas import (
    ChangesOut,
    EventOut,
    EventsOut,
    ModelCreate,
    ModelDetailOut,
    ModelOut,
    ModelPage,
    ModelUpdate,
    VersionOut,
)
from services.rest.json_body import FastJsonRoute

router = APIRouter(responses=ERROR_RESPONSES, route_class=FastJsonRoute)


@router.get("/changes", response_model=ChangesOut, tags=["changes"])
def get_changes(
    store: StoreDep,
    _: ReadAuth,
    response: Response,
    if_none_match: Annotated[str | None, Header()] = None,
) -> ChangesOut | Response:
    """The change token: poll it cheaply; `If-None-Match` with the last ETag answers 304 when
    nothing changed (no alias moved, no version registered, ...)."""
    token = store.change_token()
    etag = f'"{token}"'
    if if_none_match is not None and etag in [t.strip() for t in if_none_match.split(",")]:
        return Response(status_code=status.HTTP_304_NOT_MODIFIED, headers={"ETag": etag})
    response.headers["ETag"] = etag
    return ChangesOut(token=token)


@router.get("/events", response_model=EventsOut, tags=["changes"])
def list_events(
    store: StoreDep,
    _: ReadAuth,
    since: Annotated[
        int, Query(ge=0, le=MAX_EVENT_ID, description="only events with a larger id")
    ] = 0,
    limit: Annotated[int, Query(ge=1, le=1000)] = 100,
) -> EventsOut:
    """Changes in commit order, oldest first."""
    events = store.events(since_id=since, limit=limit)
    return EventsOut(
        events=[EventOut.of(e) for e in events], last_id=events[-1].id if events else since
    )


@router.get("/models", response_model=ModelPage, tags=["models"])
def list_models(
    store: StoreDep,
    _: ReadAuth,
    env: str | None = None,
    kind: Annotated[str | None, Query(pattern="^(task|impact|joint|monitor)$")] = None,
    goal: str | None = None,
    tag: Annotated[str | None, Query(description="`key` or `key=value`")] = None,
    page_size: Annotated[int, Query(ge=1, le=1000)] = 50,
    page_token: str | None = None,
) -> ModelPage:
    page = store.list_models(
        env=env, kind=kind, goal=goal, tag=tag, page_size=page_size, page_token=page_token
    )
    return ModelPage(
        models=[ModelOut.of(m) for m in page.items], next_page_token=page.next_page_token
    )


@router.post(
    "/models", response_model=ModelOut, status_code=status.HTTP_201_CREATED, tags=["models"]
)
def create_model(body: ModelCreate, store: StoreDep, _: WriteAuth, response: Response) -> ModelOut:
    model = store.create_model(
        body.name,
        env=body.env,
        kind=body.kind,
        goals=body.goals,
        obs_dim=body.obs_dim,
        n_actions=body.n_actions,
        description=body.description,
        tags=body.tags,
    )
    response.headers["Location"] = f"/v1/registry/models/{model.name}"
    return ModelOut.of(model)


@router.get("/models/{name:path}", response_model=ModelDetailOut, tags=["models"])
def get_model(name: str, store: StoreDep, _: ReadAuth) -> ModelDetailOut:
    """A model with all its versions (newest first). `name` contains slashes:
    `/v1/registry/models/particle/task/a3`."""
    model = store.get_model(name)
    versions = store.list_versions(name)
    return ModelDetailOut(
        **ModelOut.of(model).model_dump(), versions=[VersionOut.of(v) for v in versions]
    )


@router.patch("/models/{name:path}", response_model=ModelOut, tags=["models"])
def update_model(name: str, body: ModelUpdate, store: StoreDep, _: WriteAuth) -> ModelOut:
    return ModelOut.of(store.update_model(name, description=body.description, tags=body.tags))


@router.delete("/models/{name:path}", status_code=status.HTTP_204_NO_CONTENT, tags=["models"])
def delete_model(name: str, store: StoreDep, _: WriteAuth) -> Response:
    """Delete a model with all its versions and aliases."""
    store.delete_model(name)
    return Response(status_code=status.HTTP_204_NO_CONTENT)
