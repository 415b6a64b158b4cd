"""Out-of-range numbers through the HTTP API, on SQLite and PostgreSQL: versions past 2^31-1 and
event ids past 2^63-1 are 422 naming the field, the largest valid version is 404, never a 500
or a 503; a job log read from past its end is empty, not a 500. And an error nothing handled is
still a JSON 500 with the request's id, on a connection that stays open."""

from __future__ import annotations

import socket
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi import APIRouter
from fastapi.testclient import TestClient
from http_live_server import live_http_server
from pydantic import SecretStr
from replica_cluster import pg_schema_url

from model_store.sql import SqlModelStore
from model_store.testing import qnet_spec, qnet_weights, test_lineage
from services.app import create_app
from services.settings import Settings
from trainer.jobs import JobSpec, JobTable

TOKEN = "numbers-test-admin-token"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
NAME = "particle/task/a2"
SPEC = qnet_spec(obs_dim=8, n_actions=5, hidden=(4,))
OBS = [0.1, 0.4, 0.0, 0.0, 0.7, 0.6, 0.0, 0.0]
PAST_64_BITS, PAST_POSTGRES, LARGEST = 2**63, 2**31, 2**31 - 1


@pytest.fixture(params=["sqlite", pytest.param("postgres", marks=pytest.mark.postgres)])
def store_url(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[str]:
    if request.param == "sqlite":
        yield f"sqlite:///{tmp_path / 'models.db'}"
        return
    with pg_schema_url() as url:
        yield url


@pytest.fixture
def client(store_url: str, tmp_path: Path) -> Iterator[TestClient]:
    settings = Settings(admin_token=SecretStr(TOKEN), grpc_enabled=False, data_dir=tmp_path)
    with SqlModelStore(store_url) as store:
        store.create_model(NAME, env="particle", kind="task", goals=("a2",), obs_dim=8, n_actions=5)
        store.register_version(
            NAME,
            spec=SPEC,
            weights=qnet_weights(SPEC),
            lineage=test_lineage(),
            aliases=("latest", "production"),
        )
        with TestClient(create_app(settings, store=store)) as test_client:
            yield test_client


def _error(response: Any, status: int, field: str | None) -> None:
    assert response.status_code == status, response.text
    assert response.json()["field"] == field, response.json()


@pytest.mark.parametrize("version", [PAST_POSTGRES, PAST_64_BITS])
def test_versions_past_the_range_are_422(client: TestClient, version: int) -> None:
    base = f"/v1/registry/models/{NAME}/-"
    _error(client.get(f"/v1/registry/resolve?ref={NAME}/{version}"), 422, "ref")
    _error(client.get(f"{base}/versions/{version}"), 422, "version")
    _error(client.get(f"{base}/versions/{version}/weights"), 422, "version")
    put = client.put(f"{base}/aliases/production", json={"version": version}, headers=AUTH)
    _error(put, 422, "version")
    act = {"env": "particle", "ego_goal": "a2", "observation": OBS, "versions": {NAME: version}}
    _error(client.post("/v1/act", json=act), 422, f"versions[{NAME}]")


def test_the_largest_version_is_404(client: TestClient) -> None:
    _error(client.get(f"/v1/registry/resolve?ref={NAME}/{LARGEST}"), 404, "version")
    _error(client.get(f"/v1/registry/models/{NAME}/-/versions/{LARGEST}"), 404, "version")
    act = {"env": "particle", "ego_goal": "a2", "observation": OBS, "versions": {NAME: LARGEST}}
    _error(client.post("/v1/act", json=act), 404, f"versions[{NAME}]")


def test_event_ids_past_64_bits_are_422(client: TestClient) -> None:
    _error(client.get(f"/v1/registry/events?since={PAST_64_BITS}"), 422, "since")
    answer = client.get(f"/v1/registry/events?since={PAST_64_BITS - 1}")
    assert answer.status_code == 200 and answer.json()["events"] == []


def test_model_sizes_past_the_columns_are_422(client: TestClient) -> None:
    body = {
        "name": "particle/task/b3",
        "env": "particle",
        "kind": "task",
        "goals": ["b3"],
        "obs_dim": PAST_POSTGRES,
        "n_actions": 5,
    }
    _error(client.post("/v1/registry/models", json=body, headers=AUTH), 422, "obs_dim")


def test_a_log_read_past_its_end_is_empty(client: TestClient, store_url: str, tmp_path: Path):
    table = JobTable(store_url)
    try:
        job = table.submit(JobSpec("task", goals="a2"), str(tmp_path / "jobs"))
    finally:
        table.close()
    (Path(job.run_dir)).mkdir(parents=True)
    (Path(job.run_dir) / "log.txt").write_text("one line\n")
    for offset in (4611686018427387904, PAST_64_BITS - 1):
        answer = client.get(f"/v1/jobs/{job.id}/logs?offset={offset}")
        assert answer.status_code == 200, answer.text
        assert answer.json()["log"] == "" and answer.json()["next_offset"] == offset
    _error(client.get(f"/v1/jobs/{job.id}/logs?offset={PAST_64_BITS}"), 422, "offset")


def _exchange(sock: socket.socket, request: bytes) -> tuple[int, dict[str, str], bytes]:
    sock.sendall(request)
    data = b""
    while b"\r\n\r\n" not in data:
        chunk = sock.recv(65536)
        assert chunk, "the server closed the connection"
        data += chunk
    head, _, body = data.partition(b"\r\n\r\n")
    status_line, *lines = head.decode("latin-1").split("\r\n")
    headers = {k.strip().lower(): v.strip() for k, v in (h.split(":", 1) for h in lines)}
    while len(body) < int(headers["content-length"]):
        body += sock.recv(65536)
    return int(status_line.split()[1]), headers, body


def test_an_unhandled_error_is_a_500_with_its_id_on_a_kept_connection(tmp_path: Path) -> None:
    broken = APIRouter()

    @broken.get("/broken")
    async def fail() -> None:
        raise RuntimeError("a bug")

    settings = Settings(admin_token=SecretStr(TOKEN), grpc_enabled=False, data_dir=tmp_path)
    with SqlModelStore(f"sqlite:///{tmp_path / 'models.db'}") as store:
        app = create_app(settings, store=store, routers=[broken])
        with live_http_server(app) as url:
            host, port = url.removeprefix("http://").split(":")
            with socket.create_connection((host, int(port)), timeout=10) as sock:
                get = "GET {} HTTP/1.1\r\nHost: x\r\nX-Request-ID: req-500\r\n\r\n"
                status, headers, body = _exchange(sock, get.format("/broken").encode())
                assert status == 500 and headers.get("x-request-id") == "req-500"
                assert b'"code":"internal"' in body
                status, _, _ = _exchange(sock, get.format("/healthz").encode())
                assert status == 200  # the same connection still serves
