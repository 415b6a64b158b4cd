"""Entities of the model registry: plain frozen dataclasses, the only objects that leave a store.

ORM rows never leave `model_store/sql/`; every store method returns these (or a `Page` of them).

| entity          | identity             | what it holds                                         |
|-----------------|----------------------|-------------------------------------------------------|
| RegisteredModel | name                 | env, kind, goals, obs/action sizes, tags, aliases     |
| ModelVersion    | (name, version >= 1) | spec, sha256 + size of the weights, status, lineage   |
| Lineage         | (part of a version)  | training config, seed, code version, metrics, parents |
| Event           | id (increasing)      | one change: kind, model name, version and/or alias    |
| Page[T]         |                      | items + opaque next-page token (None = last)          |

Event kinds: `model_created`, `model_updated`, `model_deleted`, `version_registered`,
`version_archived`, `version_deleted`, `alias_set`, `alias_deleted`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime
from typing import Any, Generic, Literal, TypeVar

from model_store.errors import InvalidArtifact, brief

ModelKind = Literal["task", "impact", "joint", "monitor"]
MODEL_KINDS: tuple[str, ...] = ("task", "impact", "joint", "monitor")
VersionStatus = Literal["ready", "archived"]
EVENT_KINDS: tuple[str, ...] = (
    "model_created",
    "model_updated",
    "model_deleted",
    "version_registered",
    "version_archived",
    "version_deleted",
    "alias_set",
    "alias_deleted",
)

T = TypeVar("T")


@dataclass(frozen=True)
class Lineage:
    """Where a version came from.

    `parents` are refs "name/version" of the versions it depended on (an impact network names the
    partner task version it was trained against); `registered_by` is who or what registered it.
    """

    config: dict[str, Any] = field(default_factory=dict)
    seed: int | None = None
    code_version: str = "unknown"
    metrics: dict[str, Any] = field(default_factory=dict)
    parents: tuple[str, ...] = ()
    registered_by: str = "unknown"

    def to_json(self) -> dict[str, Any]:
        return {
            "config": self.config,
            "seed": self.seed,
            "code_version": self.code_version,
            "metrics": self.metrics,
            "parents": list(self.parents),
            "registered_by": self.registered_by,
        }

    @classmethod
    def from_json(cls, data: Any) -> Lineage:
        """Build from a JSON object; `InvalidArtifact` (a ValueError) naming the bad field."""

        def bad(field: str, message: str) -> InvalidArtifact:
            return InvalidArtifact(f"{field}: {message}", field=field)

        if not isinstance(data, dict):
            raise bad("lineage", f"expected a JSON object, got {type(data).__name__}")
        unknown = sorted(set(data) - set(cls.__dataclass_fields__))
        if unknown:
            raise bad(f"lineage.{unknown[0]}", "unknown field")
        for key, kind in (("config", dict), ("metrics", dict), ("parents", list)):
            if key in data and not isinstance(data[key], kind):
                raise bad(f"lineage.{key}", f"expected a JSON {kind.__name__}")
        seed = data.get("seed")
        if seed is not None and (not isinstance(seed, int) or isinstance(seed, bool)):
            raise bad("lineage.seed", f"expected an integer or null, got {brief(seed)}")
        for key in ("code_version", "registered_by"):
            if key in data and not isinstance(data[key], str):
                raise bad(f"lineage.{key}", "expected a string")
        parents = data.get("parents", [])
        if not all(isinstance(p, str) for p in parents):
            raise bad("lineage.parents", "expected a list of 'name/version' strings")
        return cls(
            config=dict(data.get("config", {})),
            seed=seed,
            code_version=data.get("code_version", "unknown"),
            metrics=dict(data.get("metrics", {})),
            parents=tuple(parents),
            registered_by=data.get("registered_by", "unknown"),
        )


@dataclass(frozen=True)
class RegisteredModel:
    name: str
    env: str
    kind: str
    goals: tuple[str, ...]
    obs_dim: int
    n_actions: int
    description: str
    tags: dict[str, str]
    aliases: dict[str, int]
    created_at: datetime
    updated_at: datetime

    def to_json(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "env": self.env,
            "kind": self.kind,
            "goals": list(self.goals),
            "obs_dim": self.obs_dim,
            "n_actions": self.n_actions,
            "description": self.description,
            "tags": dict(self.tags),
            "aliases": dict(self.aliases),
            "created_at": self.created_at.isoformat(),
            "updated_at": self.updated_at.isoformat(),
        }


@dataclass(frozen=True)
class ModelVersion:
    name: str
    version: int
    spec: dict[str, Any]
    sha256: str
    size_bytes: int
    created_at: datetime
    status: str
    lineage: Lineage

    @property
    def ref(self) -> str:
        """The canonical reference "name/version"."""
        return f"{self.name}/{self.version}"

    def to_json(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "version": self.version,
            "spec": self.spec,
            "sha256": self.sha256,
            "size_bytes": self.size_bytes,
            "created_at": self.created_at.isoformat(),
            "status": self.status,
            "lineage": self.lineage.to_json(),
        }


@dataclass(frozen=True)
class Event:
    id: int
    kind: str
    name: str
    version: int | None
    alias: str | None
    at: datetime

    def to_json(self) -> dict[str, Any]:
        return {
            "id": self.id,
            "kind": self.kind,
            "name": self.name,
            "version": self.version,
            "alias": self.alias,
            "at": self.at.isoformat(),
        }


@dataclass(frozen=True)
class Page(Generic[T]):
    items: tuple[T, ...]
    next_page_token: str | None = None
