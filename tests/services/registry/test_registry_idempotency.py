"""An upload whose answer was lost can be retried with the same `Idempotency-Key`: the retry
answers the version the first one registered (201, the same body) instead of registering
another, on SQLite and PostgreSQL; the key with other weights is a 409 naming it."""

from __future__ import annotations

import json
from collections.abc import Iterator
from contextlib import nullcontext
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from pydantic import SecretStr
from replica_cluster import pg_schema_url

from model_store.sql import SqlModelStore
from model_store.testing import qnet_spec, qnet_weights
from services.app import create_app
from services.settings import Settings

TOKEN = "idempotency-test-admin-token"
NAME = "particle/task/a3"
SPEC = qnet_spec(obs_dim=8, n_actions=5, hidden=(16,))
BASE = f"/v1/registry/models/{NAME}/-/versions"


@pytest.fixture(params=["sqlite", pytest.param("postgres", marks=pytest.mark.postgres)])
def client(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[TestClient]:
    settings = Settings(admin_token=SecretStr(TOKEN), grpc_enabled=False, data_dir=tmp_path)
    with (
        (
            pg_schema_url()
            if request.param == "postgres"
            else nullcontext(f"sqlite:///{tmp_path / 'models.db'}")
        ) as url,
        SqlModelStore(url) as store,
    ):
        store.create_model(NAME, env="particle", kind="task", goals=("a3",), obs_dim=8, n_actions=5)
        with TestClient(create_app(settings, store=store)) as test_client:
            yield test_client


def _upload(client: TestClient, seed: int, key: str | None) -> Any:
    headers = {"Authorization": f"Bearer {TOKEN}"}
    if key is not None:
        headers["Idempotency-Key"] = key
    return client.post(
        BASE,
        files={"weights": ("w.safetensors", qnet_weights(SPEC, seed=seed))},
        data={"spec": json.dumps(SPEC), "lineage": json.dumps({"seed": seed})},
        headers=headers,
    )


def test_a_retried_upload_is_registered_once(client: TestClient) -> None:
    first = _upload(client, 0, "upload-7d1f0c")
    assert first.status_code == 201, first.text
    retry = _upload(client, 0, "upload-7d1f0c")
    assert retry.status_code == 201, retry.text
    assert retry.json() == first.json()
    assert [v["version"] for v in client.get(BASE).json()] == [1]
    conflict = _upload(client, 1, "upload-7d1f0c")
    assert conflict.status_code == 409, conflict.text
    assert conflict.json()["field"] == "idempotency_key"
    assert _upload(client, 1, None).json()["version"] == 2  # without a key: a new version
    bad = _upload(client, 1, "not a key")
    assert bad.status_code == 422 and bad.json()["field"] == "idempotency_key"
    assert [v["version"] for v in client.get(BASE).json()] == [2, 1]
