"""The model registry of a running server as `coexist models` sees a store (`--server URL`).

`RemoteRegistry` answers the store methods the registry commands use (`list_models`,
`get_model`, `list_versions`, `get_version`, `resolve`, `set_alias`, `archive_version`,
`load_weights`, `create_model`, `register_version`) through the server's registry API
(`coexist_client.RegistryClient`), with the store's own entities, so every command prints the
same whichever it talks to. The token comes from the environment: `COEXIST_ADMIN_TOKEN` (needed
to write), else `COEXIST_READ_TOKEN`.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from datetime import datetime
from typing import Any

from coexist_client import ModelInfo, RegistryClient, VersionInfo

from model_store.entities import Lineage, ModelVersion, Page, RegisteredModel


def _time(value: str) -> datetime:
    return datetime.fromisoformat(value) if value else datetime.fromtimestamp(0)


def _model(info: ModelInfo) -> RegisteredModel:
    return RegisteredModel(
        name=info.name,
        env=info.env,
        kind=info.kind,
        goals=tuple(info.goals),
        obs_dim=info.obs_dim,
        n_actions=info.n_actions,
        description=info.description,
        tags=dict(info.tags),
        aliases=dict(info.aliases),
        created_at=_time(info.created_at),
        updated_at=_time(info.updated_at),
    )


def _version(info: VersionInfo) -> ModelVersion:
    return ModelVersion(
        name=info.name,
        version=info.version,
        spec=dict(info.spec),
        sha256=info.sha256,
        size_bytes=info.size_bytes,
        created_at=_time(info.created_at),
        status=info.status,
        lineage=Lineage.from_json(dict(info.lineage)),
    )


class RemoteRegistry:
    """A server's registry behind the store methods `cli.models` calls; see the module docstring."""

    def __init__(self, server: str, token: str | None = None) -> None:
        token = (
            token or os.environ.get("COEXIST_ADMIN_TOKEN") or os.environ.get("COEXIST_READ_TOKEN")
        )
        self.client = RegistryClient(server, token=token)

    def list_models(self, *, page_size: int = 50, **filters: Any) -> Page[RegisteredModel]:
        page = self.client.list(page_size=page_size, **filters)
        return Page(tuple(_model(m) for m in page.models), page.next_page_token)

    def get_model(self, name: str) -> RegisteredModel:
        return _model(self.client.show(name))

    def list_versions(self, name: str) -> list[ModelVersion]:
        return [_version(v) for v in self.client.show(name).versions]

    def get_version(self, name: str, version: int) -> ModelVersion:
        return _version(self.client.version(name, version))

    def resolve(self, ref: str) -> ModelVersion:
        return _version(self.client.resolve(ref))

    def set_alias(self, name: str, alias: str, version: int) -> None:
        self.client.promote(name, version, alias=alias)

    def archive_version(self, name: str, version: int) -> ModelVersion:
        return _version(self.client.archive(name, version))

    def load_weights(self, name: str, version: int) -> bytes:
        return self.client.download(name, version)  # sha256 checked

    def create_model(self, name: str, **fields: Any) -> RegisteredModel:
        return _model(self.client.create_model(name, **fields))

    def register_version(
        self,
        name: str,
        *,
        spec: dict[str, Any],
        weights: bytes,
        lineage: Lineage,
        aliases: Sequence[str] = (),
    ) -> ModelVersion:
        extra = [a for a in aliases if a != "latest"]  # the server points latest itself
        return _version(
            self.client.upload(name, spec, weights, lineage=lineage.to_json(), aliases=extra)
        )

    def close(self) -> None:
        self.client.close()

    def __repr__(self) -> str:
        return f"RemoteRegistry({self.client.transport.http.base_url})"
