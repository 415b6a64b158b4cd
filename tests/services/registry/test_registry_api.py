"""The registry REST API, happy paths: models, upload/download, aliases, change feed."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from pydantic import SecretStr

from model_store.sql import SqlModelStore
from model_store.testing import qnet_spec, qnet_weights
from services.app import create_app
from services.settings import Settings

TOKEN = "s3cret-admin-token-0123"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
BASE = "/v1/registry"
NAME = "particle/task/a3"
SPEC = qnet_spec(obs_dim=8, n_actions=5, hidden=(16,))


@pytest.fixture
def client(tmp_path: Path) -> Iterator[TestClient]:
    with SqlModelStore(f"sqlite:///{tmp_path / 'models.db'}") as store:
        yield TestClient(create_app(Settings(admin_token=SecretStr(TOKEN)), store=store))


def _create(client: TestClient, name: str = NAME, **kw) -> dict:
    env, kind, goals = name.split("/")
    body = {
        "name": name,
        "env": env,
        "kind": kind,
        "goals": goals.split("+"),
        "obs_dim": 8,
        "n_actions": 5,
        **kw,
    }
    response = client.post(f"{BASE}/models", json=body, headers=AUTH)
    assert response.status_code == 201, response.text
    return response.json()


def _upload(client: TestClient, name: str = NAME, *, seed: int = 0, params=None, lineage=None):
    return client.post(
        f"{BASE}/models/{name}/-/versions",
        files={"weights": ("w.safetensors", qnet_weights(SPEC, seed=seed))},
        data={"spec": json.dumps(SPEC), "lineage": json.dumps(lineage or {"seed": seed})},
        params=params,
        headers=AUTH,
    )


def test_create_get_update_list_delete(client: TestClient) -> None:
    made = _create(client, tags={"team": "rl"}, description="reach a3")
    assert made["name"] == NAME and made["goals"] == ["a3"] and made["tags"] == {"team": "rl"}
    _create(client, "particle/joint/a2+b3")
    got = client.get(f"{BASE}/models/{NAME}").json()
    assert got["description"] == "reach a3" and got["versions"] == []
    patched = client.patch(f"{BASE}/models/{NAME}", json={"tags": {"team": "x"}}, headers=AUTH)
    assert patched.json()["tags"] == {"team": "x"} and patched.json()["description"] == "reach a3"
    listed = client.get(f"{BASE}/models", params={"kind": "joint"}).json()
    assert [m["name"] for m in listed["models"]] == ["particle/joint/a2+b3"]
    assert [m["name"] for m in client.get(f"{BASE}/models?tag=team=x").json()["models"]] == [NAME]
    assert client.delete(f"{BASE}/models/{NAME}", headers=AUTH).status_code == 204
    assert client.get(f"{BASE}/models/{NAME}").status_code == 404


def test_pagination(client: TestClient) -> None:
    names = [f"particle/task/g{i}" for i in range(5)]
    for name in names:
        _create(client, name)
    seen, token = [], None
    while True:
        params = {"page_size": 2, **({"page_token": token} if token else {})}
        page = client.get(f"{BASE}/models", params=params).json()
        seen += [m["name"] for m in page["models"]]
        token = page["next_page_token"]
        if token is None:
            break
    assert seen == names


def test_upload_download_round_trip_with_checksum(client: TestClient) -> None:
    _create(client)
    response = _upload(
        client,
        seed=4,
        lineage={"seed": 4, "config": {"lr": 0.001}, "metrics": {"final_return": 3.5}},
    )
    assert response.status_code == 201, response.text
    version = response.json()
    blob = qnet_weights(SPEC, seed=4)
    assert version["version"] == 1 and version["sha256"] == hashlib.sha256(blob).hexdigest()
    assert version["lineage"]["registered_by"] == "rest-api"
    assert version["lineage"]["metrics"] == {"final_return": 3.5}
    assert response.headers["location"].endswith(f"{NAME}/-/versions/1")

    download = client.get(f"{BASE}/models/{NAME}/-/versions/1/weights")
    assert download.status_code == 200
    assert download.content == blob
    assert download.headers["content-type"] == "application/octet-stream"
    assert download.headers["x-checksum-sha256"] == hashlib.sha256(download.content).hexdigest()
    etag = download.headers["etag"]
    again = client.get(
        f"{BASE}/models/{NAME}/-/versions/1/weights", headers={"If-None-Match": etag}
    )
    assert again.status_code == 304 and again.content == b""

    meta = client.get(f"{BASE}/models/{NAME}/-/versions/1").json()
    assert meta["spec"] == SPEC and meta["lineage"]["config"] == {"lr": 0.001}
    assert [v["version"] for v in client.get(f"{BASE}/models/{NAME}/-/versions").json()] == [1]


def test_alias_move_resolve_archive_delete(client: TestClient) -> None:
    _create(client)
    _upload(client, seed=1)
    _upload(client, seed=2, params={"alias": ["candidate"]})
    assert client.get(f"{BASE}/models/{NAME}").json()["aliases"] == {"candidate": 2, "latest": 2}
    for version in (1, 2):
        moved = client.put(
            f"{BASE}/models/{NAME}/-/aliases/production", json={"version": version}, headers=AUTH
        )
        assert moved.json() == {"name": NAME, "alias": "production", "version": version}
        resolved = client.get(f"{BASE}/resolve", params={"ref": NAME}).json()
        assert resolved["version"] == version
    assert client.get(f"{BASE}/resolve", params={"ref": f"{NAME}/1"}).json()["version"] == 1
    assert (
        client.delete(f"{BASE}/models/{NAME}/-/aliases/candidate", headers=AUTH).status_code == 204
    )
    archived = client.post(f"{BASE}/models/{NAME}/-/versions/1/archive", headers=AUTH)
    assert archived.status_code == 200 and archived.json()["status"] == "archived"
    assert client.delete(f"{BASE}/models/{NAME}/-/versions/1", headers=AUTH).status_code == 204
    assert [v["version"] for v in client.get(f"{BASE}/models/{NAME}").json()["versions"]] == [2]


def test_change_token_304_and_events(client: TestClient) -> None:
    first = client.get(f"{BASE}/changes")
    etag = first.headers["etag"]
    assert etag == f'"{first.json()["token"]}"'
    assert client.get(f"{BASE}/changes", headers={"If-None-Match": etag}).status_code == 304
    _create(client)
    changed = client.get(f"{BASE}/changes", headers={"If-None-Match": etag})
    assert changed.status_code == 200 and changed.headers["etag"] != etag
    _upload(client)
    feed = client.get(f"{BASE}/events", params={"since": 1}).json()
    assert [(e["kind"], e["version"], e["alias"]) for e in feed["events"]] == [
        ("version_registered", 1, None),
        ("alias_set", 1, "latest"),
    ]
    assert feed["last_id"] == feed["events"][-1]["id"]
    assert client.get(f"{BASE}/events", params={"since": feed["last_id"]}).json()["events"] == []


def test_healthz_and_openapi(client: TestClient) -> None:
    assert client.get("/healthz").json() == {"status": "ok"}
    schema = client.get("/openapi.json").json()
    upload = schema["paths"]["/v1/registry/models/{name}/-/versions"]["post"]
    assert "multipart/form-data" in upload["requestBody"]["content"]
    assert "/v1/registry/changes" in schema["paths"]
