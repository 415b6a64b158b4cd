"""A `versions` pin must name a model the request uses (or, for a session, one it could use):
a pin of an unknown model, or of one the request does not load, is a 422 / INVALID_ARGUMENT
naming `versions[<name>]` instead of being ignored, over REST, gRPC and the session routes."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import grpc
import pytest
from fastapi.testclient import TestClient
from grpc_live_server import live_grpc_server
from pydantic import SecretStr
from session_zoo import session_zoo_template

from model_store.sql import SqlModelStore
from services.app import create_app
from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb
from services.settings import Settings

OBS = [0.1, 0.4, 0.0, 0.0, 0.7, 0.6, 0.0, 0.0]
ACT: dict[str, Any] = {
    "env": "particle",
    "ego_goal": "a2",
    "observation": OBS,
    "partners": [{"index": 1, "goal": "b3"}],
}
UNUSED = [
    ("unknown model", "particle/task/zz"),
    ("another env", "cooking/task/a2"),
    ("not loaded by this request", "particle/impact/c1"),
]


@pytest.fixture
def client(tiny_zoo_store: SqlModelStore, tmp_path: Path) -> Iterator[TestClient]:
    settings = Settings(
        admin_token=SecretStr("pins-test-admin-token"), grpc_enabled=False, data_dir=tmp_path
    )
    with TestClient(create_app(settings, store=tiny_zoo_store)) as test_client:
        yield test_client


@pytest.mark.parametrize("name", [n for _, n in UNUSED], ids=[c for c, _ in UNUSED])
def test_rest_refuses_a_pin_the_request_does_not_use(client: TestClient, name: str) -> None:
    answer = client.post("/v1/act", json={**ACT, "versions": {"particle/task/a2": 2, name: 1}})
    assert answer.status_code == 422, answer.text
    assert answer.json()["field"] == f"versions[{name}]"
    assert "uses no model" in answer.json()["detail"]
    used = client.post("/v1/act", json={**ACT, "versions": {"particle/task/a2": 2}})
    assert used.status_code == 200 and used.json()["models"][0]["version"] == 2


@pytest.mark.parametrize("name", [n for _, n in UNUSED], ids=[c for c, _ in UNUSED])
def test_grpc_refuses_a_pin_the_request_does_not_use(
    tiny_zoo_store: SqlModelStore, name: str
) -> None:
    request = pb.ActRequest(
        env="particle",
        ego_goal="a2",
        observation=OBS,
        versions={name: 1},
        partners=[pb.PartnerSpec(index=1, goal="b3")],
    )
    with live_grpc_server(tiny_zoo_store) as live, pytest.raises(grpc.RpcError) as caught:
        live.stub.Act(request, timeout=10)
    err: Any = caught.value
    assert err.code() == grpc.StatusCode.INVALID_ARGUMENT, err.details()
    assert dict(err.trailing_metadata() or ()).get("coexist-field") == f"versions[{name}]"


def test_a_session_refuses_a_pin_it_could_never_use(
    tmp_path: Path, tmp_path_factory: pytest.TempPathFactory
) -> None:
    """A session may pin any task or impact network of its env (its beliefs weigh every goal),
    nothing else."""
    settings = Settings(
        admin_token=SecretStr("pins-test-admin-token"), grpc_enabled=False, data_dir=tmp_path
    )
    url = f"sqlite:///{session_zoo_template(tmp_path_factory)}"
    body = {"env": "particle", "ego_goal": "a2", "partners": [{"index": 1, "infer": True}]}
    with SqlModelStore(url) as store, TestClient(create_app(settings, store=store)) as client:
        refused = client.post("/v1/sessions", json={**body, "versions": {"cooking/task/a2": 1}})
        assert refused.status_code == 422, refused.text
        assert refused.json()["field"] == "versions[cooking/task/a2]"
        usable = client.post("/v1/sessions", json={**body, "versions": {"particle/task/c1": 1}})
        assert usable.status_code == 201, usable.text
