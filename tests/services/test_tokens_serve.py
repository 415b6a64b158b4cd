"""Tokens on every door of a real `coexist serve` with `COEXIST_REQUIRE_READ_TOKEN=1`: every REST
route but liveness, and every gRPC method but health, refuses a missing token (401 /
UNAUTHENTICATED) and a wrong one (403 / PERMISSION_DENIED) and serves the read token (and the
SDK, given it); `/readyz` tells an anonymous probe its status alone. Sessions are bounded per
client (by address): one client at its limit gets 429 with `Retry-After`, another still gets
a slot."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import grpc
import httpx
import pytest
from coexist_client import CoexistClient, GrpcCoexistClient
from grpc_health.v1 import health_pb2, health_pb2_grpc
from grpc_reflection.v1alpha import reflection_pb2, reflection_pb2_grpc
from live_serve import serving, zoo_copy
from replica_cluster import OBS, Server

from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb
from services.grpc_api.gen.coexist.v1 import policy_pb2_grpc as pb_grpc

READ_TOKEN = "read-token-for-the-tests-0123"
READ = {"Authorization": f"Bearer {READ_TOKEN}"}
WRONG = {"Authorization": "Bearer not-the-token-at-all-0000"}
PER_CLIENT = 2
TTL_S = 120
SETTINGS = {"env": "particle", "ego_goal": "a2", "partners": [{"index": 1, "goal": "b3"}]}
ACT = {**SETTINGS, "observation": OBS}
SESSION = {"env": "particle", "ego_goal": "a2", "partners": [{"index": 1, "infer": True}]}


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory, _tiny_zoo_template: Path) -> Iterator[Server]:
    directory = tmp_path_factory.mktemp("tokens")
    url = zoo_copy(_tiny_zoo_template, directory / "store")
    env = {
        "COEXIST_REQUIRE_READ_TOKEN": "1",
        "COEXIST_READ_TOKEN": READ_TOKEN,
        "COEXIST_MAX_SESSIONS": "10",
        "COEXIST_MAX_SESSIONS_PER_CLIENT": str(PER_CLIENT),
        "COEXIST_SESSION_TTL_S": str(TTL_S),
    }
    with serving(directory, url, **env) as running:
        yield running


ROUTES: list[tuple[str, str, Any, int]] = [  # method, path, JSON body, status with the token
    ("POST", "/v1/act", ACT, 200),
    ("POST", "/v1/act:batch", {**SETTINGS, "observations": [OBS, OBS]}, 200),
    ("GET", "/v1/envs", None, 200),
    ("GET", "/v1/sessions/no-such-session", None, 404),
    ("POST", "/v1/sessions/no-such-session/steps", {"observation": OBS}, 404),
    ("DELETE", "/v1/sessions/no-such-session", None, 404),
    ("GET", "/metrics", None, 200),
    ("GET", "/docs", None, 200),
    ("GET", "/openapi.json", None, 200),
    ("GET", "/v1/registry/models", None, 200),
    ("GET", "/v1/jobs", None, 200),
]


@pytest.mark.parametrize(("method", "path", "body", "status"), ROUTES, ids=[r[1] for r in ROUTES])
def test_every_rest_route_needs_the_token(
    server: Server, method: str, path: str, body: Any, status: int
) -> None:
    with httpx.Client(base_url=server.http_url, timeout=30) as client:
        anonymous = client.request(method, path, json=body)
        assert anonymous.status_code == 401, anonymous.text[:300]
        assert anonymous.json()["code"] == "unauthorized"
        assert anonymous.headers["www-authenticate"] == "Bearer"
        assert anonymous.headers["x-request-id"]
        assert client.request(method, path, json=body, headers=WRONG).status_code == 403
        answer = client.request(method, path, json=body, headers=READ)
        assert answer.status_code == status, answer.text[:300]


def test_liveness_is_open_and_readiness_says_only_its_status(server: Server) -> None:
    assert httpx.get(f"{server.http_url}/healthz").json() == {"status": "ok"}
    anonymous = httpx.get(f"{server.http_url}/readyz")
    assert anonymous.status_code == 200 and anonymous.json() == {"status": "ready"}
    full = httpx.get(f"{server.http_url}/readyz", headers=READ).json()
    assert full["versions_served"] and full["models_loaded"] > 0


def _grpc_calls(channel: grpc.Channel, metadata: Any) -> dict[str, Any]:
    """Each PolicyService method (and reflection), called with `metadata`: the error, or None."""
    stub = pb_grpc.PolicyServiceStub(channel)
    act = pb.ActRequest(env="particle", ego_goal="a2", observation=OBS)
    batch = pb.ActBatchRequest(env="particle", ego_goal="a2", observations=[pb.Vector(values=OBS)])
    episode = pb.EpisodeStep(
        settings=pb.EpisodeSettings(env="particle", ego_goal="a2"), observation=OBS
    )
    reflect = reflection_pb2_grpc.ServerReflectionStub(channel)
    calls = {
        "Act": lambda: stub.Act(act, metadata=metadata, timeout=10),
        "ActBatch": lambda: stub.ActBatch(batch, metadata=metadata, timeout=10),
        "ListEnvs": lambda: stub.ListEnvs(pb.ListEnvsRequest(), metadata=metadata, timeout=10),
        "Episode": lambda: list(stub.Episode(iter([episode]), metadata=metadata, timeout=10)),
        "reflection": lambda: list(
            reflect.ServerReflectionInfo(
                iter([reflection_pb2.ServerReflectionRequest(list_services="")]),
                metadata=metadata,
                timeout=10,
            )
        ),
    }
    outcomes: dict[str, Any] = {}
    for name, call in calls.items():
        try:
            call()
            outcomes[name] = None
        except grpc.RpcError as err:
            outcomes[name] = err.code()
    return outcomes


def test_every_grpc_method_needs_the_token(server: Server) -> None:
    with grpc.insecure_channel(server.grpc_target) as channel:
        anonymous = _grpc_calls(channel, None)
        wrong = _grpc_calls(channel, (("authorization", WRONG["Authorization"]),))
        allowed = _grpc_calls(channel, (("authorization", READ["Authorization"]),))
        health = health_pb2_grpc.HealthStub(channel).Check(
            health_pb2.HealthCheckRequest(service=""), timeout=10
        )
    assert set(anonymous.values()) == {grpc.StatusCode.UNAUTHENTICATED}, anonymous
    assert set(wrong.values()) == {grpc.StatusCode.PERMISSION_DENIED}, wrong
    assert set(allowed.values()) == {None}, allowed
    assert health.status == health_pb2.HealthCheckResponse.SERVING  # probes need no token


def test_the_sdk_sends_its_token_over_both_transports(server: Server) -> None:
    with (
        CoexistClient(server.http_url, token=READ_TOKEN) as rest,
        GrpcCoexistClient(server.grpc_target, token=READ_TOKEN) as fast,
    ):
        a = rest.act("particle", "a2", OBS, partners={1: "b3"}, seed=3)
        b = fast.act("particle", "a2", OBS, partners={1: "b3"}, seed=3)
        with fast.episode("particle", "a2", partners={1: "b3"}, seed=3) as episode:
            stepped = [episode.act(OBS), episode.act(OBS)]
    assert a.probs == pytest.approx(b.probs) and stepped[0].probs == stepped[1].probs


def test_sessions_are_bounded_per_client(server: Server) -> None:
    """The third session of one address is 429 with Retry-After; another address still gets
    one (a client from 127.0.0.2: loopback answers the whole 127/8)."""
    made: list[tuple[httpx.Client, str]] = []
    here = httpx.Client(base_url=server.http_url, headers=READ, timeout=30)
    there = httpx.Client(
        base_url=server.http_url,
        headers=READ,
        timeout=30,
        transport=httpx.HTTPTransport(local_address="127.0.0.2"),
    )
    try:
        for _ in range(PER_CLIENT):
            answer = here.post("/v1/sessions", json=SESSION)
            assert answer.status_code == 201, answer.text
            made.append((here, answer.json()["session_id"]))
        refused = here.post("/v1/sessions", json=SESSION)
        assert refused.status_code == 429, refused.text
        assert refused.json()["code"] == "too_many_sessions"
        assert "this client" in refused.json()["detail"]
        assert 1 <= int(refused.headers["retry-after"]) <= TTL_S
        other = there.post("/v1/sessions", json=SESSION)
        assert other.status_code == 201, other.text
        made.append((there, other.json()["session_id"]))
        here.delete(f"/v1/sessions/{made.pop(0)[1]}")  # a slot of its own frees up
        again = here.post("/v1/sessions", json=SESSION)
        assert again.status_code == 201, again.text
        made.append((here, again.json()["session_id"]))
    finally:
        for client, session_id in made:
            client.delete(f"/v1/sessions/{session_id}")
        here.close()
        there.close()


@pytest.fixture(scope="module")
def open_server(
    tmp_path_factory: pytest.TempPathFactory, _tiny_zoo_template: Path
) -> Iterator[Server]:
    """A server whose reads are open (no read token, none required)."""
    directory = tmp_path_factory.mktemp("open-reads")
    with serving(directory, zoo_copy(_tiny_zoo_template, directory / "store")) as running:
        yield running


def test_a_wrong_token_is_refused_even_while_reads_are_open(open_server: Server) -> None:
    with httpx.Client(base_url=open_server.http_url, timeout=30) as client:
        assert client.post("/v1/act", json=ACT).status_code == 200  # open: no token needed
        wrong = client.post("/v1/act", json=ACT, headers=WRONG)
        assert wrong.status_code == 403, wrong.text[:300]
        assert wrong.json()["code"] == "forbidden"
        assert "the bearer token is not valid for this server" in wrong.json()["detail"]
        assert client.get("/v1/registry/models", headers=WRONG).status_code == 403
        assert client.get("/healthz", headers=WRONG).status_code == 200  # liveness stays open
    with grpc.insecure_channel(open_server.grpc_target) as channel:
        anonymous = _grpc_calls(channel, None)
        wrong_calls = _grpc_calls(channel, (("authorization", WRONG["Authorization"]),))
    assert set(anonymous.values()) == {None}, anonymous
    assert set(wrong_calls.values()) == {grpc.StatusCode.PERMISSION_DENIED}, wrong_calls
