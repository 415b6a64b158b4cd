"""Request and response bodies of the registry API (pydantic models; they document OpenAPI)."""

from __future__ import annotations

from datetime import datetime
from typing import Any, Literal

from pydantic import BaseModel, Field

from model_store.entities import Event, ModelVersion, RegisteredModel
from model_store.naming import MAX_SIZE, MAX_VERSION


class ModelCreate(BaseModel):
    name: str = Field(examples=["particle/task/a3"])
    env: str = Field(examples=["particle"])
    kind: Literal["task", "impact", "joint", "monitor"]
    goals: list[str] = Field(min_length=1, examples=[["a3"]])
    obs_dim: int = Field(gt=0, le=MAX_SIZE, examples=[8])
    n_actions: int = Field(gt=0, le=MAX_SIZE, examples=[5])
    description: str = ""
    tags: dict[str, str] = Field(default_factory=dict)


class ModelUpdate(BaseModel):
    description: str | None = None
    tags: dict[str, str] | None = Field(default=None, description="replaces the whole tag set")


class ModelOut(BaseModel):
    name: str
    env: str
    kind: str
    goals: list[str]
    obs_dim: int
    n_actions: int
    description: str
    tags: dict[str, str]
    aliases: dict[str, int]
    created_at: datetime
    updated_at: datetime

    @classmethod
    def of(cls, model: RegisteredModel) -> ModelOut:
        return cls.model_validate(model.to_json())


class LineageOut(BaseModel):
    config: dict[str, Any]
    seed: int | None
    code_version: str
    metrics: dict[str, Any]
    parents: list[str]
    registered_by: str


class VersionOut(BaseModel):
    name: str
    version: int
    spec: dict[str, Any]
    sha256: str
    size_bytes: int
    created_at: datetime
    status: Literal["ready", "archived"]
    lineage: LineageOut

    @classmethod
    def of(cls, version: ModelVersion) -> VersionOut:
        return cls.model_validate(version.to_json())


class ModelDetailOut(ModelOut):
    versions: list[VersionOut] = Field(description="newest first")


class ModelPage(BaseModel):
    models: list[ModelOut]
    next_page_token: str | None = Field(description="pass as page_token for the next page")


class AliasSet(BaseModel):
    version: int = Field(gt=0, le=MAX_VERSION)


class AliasOut(BaseModel):
    name: str
    alias: str
    version: int


class ChangesOut(BaseModel):
    token: str = Field(description="opaque; changes with every write (also the ETag)")


class EventOut(BaseModel):
    id: int
    kind: str
    name: str
    version: int | None
    alias: str | None
    at: datetime

    @classmethod
    def of(cls, event: Event) -> EventOut:
        return cls.model_validate(event.to_json())


class EventsOut(BaseModel):
    events: list[EventOut]
    last_id: int = Field(description="pass as `since` to get only newer events")
