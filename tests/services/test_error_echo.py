"""Error answers quote a bounded prefix of what was sent (`model_store.errors.brief`, and the
transports' clipping): a megabyte goal, model name, alias or session id gives a short 4xx naming
its field over REST, and a 16 KB goal over gRPC is INVALID_ARGUMENT naming `ego_goal`, not
RESOURCE_EXHAUSTED (an echo beyond grpcio's trailer limit)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import grpc
import pytest
from fastapi.testclient import TestClient
from grpc_live_server import live_grpc_server
from pydantic import SecretStr

from model_store.sql import SqlModelStore
from services.app import create_app
from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb
from services.settings import Settings

OBS = [0.1, 0.4, 0.0, 0.0, 0.7, 0.6, 0.0, 0.0]
LONG = "g" * (1 << 20)
TOKEN = "echo-test-admin-token"


@pytest.fixture
def client(tiny_zoo_store: SqlModelStore, tmp_path: Path) -> Iterator[TestClient]:
    settings = Settings(admin_token=SecretStr(TOKEN), grpc_enabled=False, data_dir=tmp_path)
    with TestClient(create_app(settings, store=tiny_zoo_store)) as test_client:
        yield test_client


def _short_error(response: Any, status: int, field: str) -> str:
    assert response.status_code == status, response.text[:300]
    assert len(response.content) < 4096, f"a {len(response.content)}-byte answer"
    error = response.json()
    assert error["field"] == field, error
    message: str = error["detail"]
    return message


ACT = {"env": "particle", "ego_goal": "a2", "observation": OBS}
REST_CASES: list[tuple[str, str, str, dict[str, Any], int, str, str]] = [
    # (case, method, path, JSON body, status, field, the message's start)
    (
        "goal",
        "POST",
        "/v1/act",
        {**ACT, "ego_goal": LONG},
        422,
        "ego_goal",
        "ego_goal: unknown goal 'ggg",
    ),
    (
        "partner goal",
        "POST",
        "/v1/act",
        {**ACT, "partners": [{"index": 1, "goal": LONG}]},
        422,
        "partners[0].goal",
        "partners[0].goal: unknown goal 'ggg",
    ),
    (
        "pinned name",
        "POST",
        "/v1/act",
        {**ACT, "versions": {LONG: 1}},
        422,
        "versions",
        "versions: ",
    ),
    ("alias", "POST", "/v1/act", {**ACT, "alias": LONG}, 422, "alias", "alias: alias 'ggg"),
    (
        "session id",
        "GET",
        f"/v1/sessions/{'s' * 20000}",
        {},
        404,
        "session_id",
        "session_id: session 'sss",
    ),
    (
        "ref",
        "GET",
        f"/v1/registry/resolve?ref=particle/task/a2@{'a' * 20000}",
        {},
        422,
        "ref",
        "ref: alias 'aaa",
    ),
]


@pytest.mark.parametrize(
    ("method", "path", "body", "status", "field", "start"),
    [case[1:] for case in REST_CASES],
    ids=[case[0] for case in REST_CASES],
)
def test_rest_errors_quote_a_short_prefix(
    client: TestClient,
    method: str,
    path: str,
    body: dict[str, Any],
    status: int,
    field: str,
    start: str,
) -> None:
    response = client.request(method, path, json=body or None)
    assert _short_error(response, status, field).startswith(start)


def test_grpc_errors_quote_a_short_prefix(tiny_zoo_store: SqlModelStore) -> None:
    with live_grpc_server(tiny_zoo_store) as live:
        request = pb.ActRequest(env="particle", ego_goal="g" * 16384, observation=OBS)
        with pytest.raises(grpc.RpcError) as caught:
            live.stub.Act(request, timeout=10)
        long_name = pb.ActRequest(
            env="particle", ego_goal="a2", observation=OBS, versions={"m" * 20000: 1}
        )
        with pytest.raises(grpc.RpcError) as pinned:
            live.stub.Act(long_name, timeout=10)
    err: Any = caught.value
    assert err.code() == grpc.StatusCode.INVALID_ARGUMENT, err.details()
    assert dict(err.trailing_metadata() or ()).get("coexist-field") == "ego_goal"
    assert len(err.details()) < 1024 and err.details().startswith("ego_goal: unknown goal 'ggg")
    err = pinned.value
    assert err.code() == grpc.StatusCode.INVALID_ARGUMENT, err.details()
    assert dict(err.trailing_metadata() or ()).get("coexist-field") == "versions"
    assert len(err.details()) < 1024
