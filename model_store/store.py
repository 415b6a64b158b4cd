"""The model store interface: what the trainer, the inference service and the REST API rely on.

One implementation ships (`model_store.sql.SqlModelStore`, SQLite or PostgreSQL); tests and other
backends implement the same abstract class. All methods are safe to call from several threads and
several processes at once; each is one transaction (all or nothing).

Semantics fixed here, for every backend:

- Versions are numbered 1, 2, 3 ... per model, gaplessly and never reused (a deleted version's
  number is not handed out again).
- `register_version` validates spec and weights, stores them with their sha256, and points the
  given aliases (default: `latest`) at the new version in the same transaction. With an
  `idempotency_key` it is safe to retry: a key the model already has answers its version (same
  spec and weights; aliases untouched) instead of registering another, and a key reused for
  other content is a `Conflict`.
- `resolve(ref)`: `name@alias`, `name/3`, or a bare `name`, which means `name@production`.
  No model name is a path prefix of another (`create_model` refuses it with `Conflict`), so
  `particle/task/4` is unambiguous: version 4 of `particle/task` if that model exists, else the
  model `particle/task/4` at `production` (see `model_store.naming`).
- `load_weights` re-computes the sha256 on every load; a mismatch is `ChecksumMismatch`.
- Archiving keeps a version's data (it can still be resolved by number and loaded) but is refused
  while an alias points at it (`Conflict` listing the aliases): silently dropping `production`
  would take a model out of service. Aliases may not be pointed at an archived version.
- Deleting a version removes its data, and is refused like archiving while an alias points at it
  (`Conflict` listing the aliases; `latest` included: move it first); deleting a model removes
  everything it owns.
- `change_token()` is a short opaque string that changes with every committed write (it is the
  newest event id plus the store's identity); `events(since_id)` lists the changes in commit order.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from contextlib import AbstractContextManager
from typing import Self

from model_store.entities import Event, Lineage, ModelVersion, Page, RegisteredModel


class ModelStore(ABC):
    """Abstract registry of Q-networks. Errors are the classes of `model_store.errors`."""

    # --- registered models -----------------------------------------------------------------
    @abstractmethod
    def create_model(
        self,
        name: str,
        *,
        env: str,
        kind: str,
        goals: Sequence[str],
        obs_dim: int,
        n_actions: int,
        description: str = "",
        tags: Mapping[str, str] | None = None,
        exist_ok: bool = False,
    ) -> RegisteredModel:
        """Register a model name. With `exist_ok`, an existing model with the same env, kind,
        goals and sizes is returned; one that differs is still `AlreadyExists`."""

    @abstractmethod
    def get_model(self, name: str) -> RegisteredModel: ...

    @abstractmethod
    def list_models(
        self,
        *,
        env: str | None = None,
        kind: str | None = None,
        goal: str | None = None,
        tag: str | None = None,
        page_size: int = 50,
        page_token: str | None = None,
    ) -> Page[RegisteredModel]:
        """Models ordered by name. `tag` is `key` (has the tag) or `key=value`."""

    @abstractmethod
    def update_model(
        self,
        name: str,
        *,
        description: str | None = None,
        tags: Mapping[str, str] | None = None,
    ) -> RegisteredModel:
        """Change the description and/or replace the whole tag set (None = leave as is)."""

    @abstractmethod
    def delete_model(self, name: str) -> None: ...

    # --- versions --------------------------------------------------------------------------
    @abstractmethod
    def register_version(
        self,
        name: str,
        *,
        spec: dict,
        weights: bytes,
        lineage: Lineage,
        aliases: Sequence[str] = ("latest",),
        idempotency_key: str | None = None,
    ) -> ModelVersion: ...

    @abstractmethod
    def get_version(self, name: str, version: int) -> ModelVersion: ...

    @abstractmethod
    def list_versions(self, name: str, *, include_archived: bool = True) -> list[ModelVersion]:
        """All versions of a model, newest first."""

    @abstractmethod
    def resolve(self, ref: str) -> ModelVersion: ...

    @abstractmethod
    def load_weights(self, name: str, version: int) -> bytes: ...

    @abstractmethod
    def archive_version(self, name: str, version: int) -> ModelVersion: ...

    @abstractmethod
    def delete_version(self, name: str, version: int) -> None: ...

    # --- aliases ---------------------------------------------------------------------------
    @abstractmethod
    def set_alias(self, name: str, alias: str, version: int) -> None:
        """Point `alias` at `version` (creating or moving it) atomically."""

    @abstractmethod
    def delete_alias(self, name: str, alias: str) -> None: ...

    # --- change feed -----------------------------------------------------------------------
    @abstractmethod
    def change_token(self) -> str: ...

    @abstractmethod
    def events(self, since_id: int = 0, limit: int = 100) -> list[Event]:
        """Events with id > `since_id`, oldest first, at most `limit` (1..1000)."""

    # --- lifecycle -------------------------------------------------------------------------
    def reopen_url(self) -> str | None:
        """The URL by which another process (a training job's subprocess, a Ray worker) opens
        this same store through `model_store.defaults.open_store`, without its password
        (`reopen_password`): it goes into that process's environment, never onto a command
        line, into a log or an answer. None where no other process can reach it (the default:
        an in-process store)."""
        return None

    def reopen_password(self) -> str | None:
        """The database password `reopen_url` leaves out, None if there is none (the default).
        It travels apart from the URL, so that no string holds both: a job's subprocess gets it
        in `PGPASSWORD`, which libpq reads (`trainer.jobs.runner`), a Ray worker inside the
        store's URL object (`trainer.backends.ray_cluster.portable_store_url`)."""
        return None

    def lock(self, key: str) -> AbstractContextManager[None] | None:
        """A lock named `key` that every process opening this store (`reopen_url`) shares, held
        for a `with` block and released when its holder dies; None where the backend offers
        none (the default). coexist's Ray backend holds it while a batch looks for the versions
        an earlier attempt registered and registers the rest (`trainer.backends.once`); on a
        store without it, that lock lives in the store's SQL database."""
        return None

    def close(self) -> None:  # noqa: B027 - optional hook, most stores hold nothing
        """Release connections; the store must not be used afterwards."""

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()
