"""The HTTP SDK clients against the inference REST routes: the sync client over a real uvicorn
server, the async client over `httpx.ASGITransport`; results equal the engine's, errors typed."""

from __future__ import annotations

import asyncio
from collections.abc import Iterator
from typing import Any

import httpx
import numpy as np
import pytest
from coexist_client import (
    Action,
    AsyncCoexistClient,
    CoexistClient,
    CoexistError,
    InvalidArgument,
    NotFound,
    Unavailable,
)
from http_live_server import inference_app, live_http_server

from model_store.sql import SqlModelStore
from services.engine import ActRequest, ActResult, InferenceEngine, PartnerSpec

OBS_2 = [0.1, 0.4, 0.0, 0.0, 0.7, 0.6, 0.1, -0.1]


@pytest.fixture(scope="module")
def engine(_tiny_zoo_template: Any) -> Iterator[InferenceEngine]:
    with SqlModelStore(f"sqlite:///{_tiny_zoo_template}") as store:
        yield InferenceEngine(store)


@pytest.fixture(scope="module")
def base_url(engine: InferenceEngine) -> Iterator[str]:
    with live_http_server(inference_app(engine)) as url:
        yield url


@pytest.fixture
def client(base_url: str) -> Iterator[CoexistClient]:
    with CoexistClient(base_url) as client:
        yield client


def assert_action_is(action: Action, expected: ActResult, partner_indices: list[int]) -> None:
    assert action.probs == pytest.approx(expected.probs, abs=1e-12)
    assert (action.action, action.greedy_action) == (expected.action, expected.greedy_action)
    assert action.method == expected.method
    assert action.diagnostics.task_weight == pytest.approx(expected.task_weight, abs=1e-12)
    weights = [(w.index, w.weight) for w in action.diagnostics.partner_weights]
    assert [i for i, _ in weights] == partner_indices
    assert [w for _, w in weights] == pytest.approx(expected.partner_weights, abs=1e-12)
    got = [(m.role, m.name, m.version, m.sha256, m.partner_index, m.goal) for m in action.models]
    want = [(m.role, m.name, m.version, m.sha256, m.partner_index, m.goal) for m in expected.models]
    assert got == want


def test_act_batch_state_and_partner_forms(engine: InferenceEngine, client: CoexistClient) -> None:
    action = client.act("particle", "a2", OBS_2, partners={1: "b3"}, seed=5)
    request = ActRequest("particle", "a2", np.array([OBS_2]), (PartnerSpec(1, goal="b3"),), seed=5)
    [expected] = engine.act(request)
    assert_action_is(action, expected, [1])
    assert action.action_meaning == ("rest", "up", "down", "left", "right")[action.action]
    for form in ([PartnerSpec(1, goal="b3")], [{"index": 1, "goal": "b3"}], {1: {"b3": 1.0}}):
        assert client.act("particle", "a2", OBS_2, partners=form, seed=5).probs == action.probs
    by_state = client.act(
        "particle", "a2", state=[OBS_2[4:], OBS_2[:4]], ego_index=1, partners={1: "b3"}, seed=5
    )
    assert by_state == action

    obs_BD = np.random.default_rng(0).random((6, 12)) * 0.9
    partners = {2: {"b3": 0.6, "c": 0.4}, 1: "d4"}
    actions = client.act_batch("particle", "c1", obs_BD, partners=partners, seed=3)
    expected_rows = engine.act(
        ActRequest(
            "particle",
            "c1",
            obs_BD,
            (PartnerSpec(2, goal_probs={"b3": 0.6, "c": 0.4}), PartnerSpec(1, goal="d4")),
            seed=3,
        )
    )
    assert len(actions) == 6
    for got, want in zip(actions, expected_rows, strict=True):
        assert_action_is(got, want, [2, 1])


def test_envs_health_and_episode(client: CoexistClient, engine: InferenceEngine) -> None:
    particle = {e.name: e for e in client.envs()}["particle"]
    assert particle.obs_dims == {n: 4 * n for n in range(1, 6)}
    assert particle.observation_layouts[1] == ("self.x", "self.y", "self.vx", "self.vy")
    assert particle.methods == ("aail_bounded", "aail_budget", "aail", "nail", "sl", "jl")
    health = client.health()
    assert health.live and health.ready

    obs_TD = np.random.default_rng(1).random((3, 8)) * 0.9
    with client.episode("particle", "a2", partners={1: "b3"}, seed=20) as episode:
        steps = [episode.act(obs) for obs in obs_TD]
    for t, action in enumerate(steps):
        request = ActRequest(
            "particle", "a2", obs_TD[t : t + 1], (PartnerSpec(1, goal="b3"),), seed=20 + t
        )
        assert_action_is(action, engine.act(request)[0], [1])


def test_errors_are_typed_and_name_the_field(client: CoexistClient) -> None:
    with pytest.raises(InvalidArgument) as info:
        client.act("particle", "a2", OBS_2[:7])
    assert (info.value.code, info.value.field) == ("invalid_argument", "observation")
    with pytest.raises(InvalidArgument) as info:
        client.act("particle", "a2", OBS_2, partners={1: "b3"}, temperature=-1.0)
    assert info.value.field == "temperature" and "temperature" in str(info.value)
    with pytest.raises(InvalidArgument) as info:
        client.act_batch("particle", "a2", [OBS_2, OBS_2], partners={3: "b3"})
    assert info.value.field == "partners[0].index"
    with pytest.raises(NotFound) as not_found:
        client.act("particle", "a2", OBS_2, versions={"particle/task/a2": 7})
    assert not_found.value.field == "versions[particle/task/a2]"
    with pytest.raises(InvalidArgument) as info:
        client.act("particle", "a2", OBS_2, state=[OBS_2[:4]])
    assert info.value.field == "observation"


# The same refusal in the server's two shapes: RFC 9457 problem details, and the shape before
# them (`{"error": {...}}`), which the SDK reads for one release more.
MESSAGE = "observation: 7 numbers, the env's observations have 8"
PROBLEM = {
    "type": "/problems/invalid_request",
    "title": "Invalid request",
    "status": 422,
    "detail": MESSAGE,
    "instance": "/v1/act",
    "code": "invalid_request",
    "field": "observation",
}
OLDER = {"error": {"code": "invalid_request", "message": MESSAGE, "field": "observation"}}


@pytest.mark.parametrize("body", [PROBLEM, OLDER], ids=["problem details", "older shape"])
def test_both_error_shapes_give_the_message_and_the_field(body: dict[str, Any]) -> None:
    with _mock_client(422, body) as client, pytest.raises(InvalidArgument) as info:
        client.act("particle", "a2", OBS_2)
    assert (info.value.message, info.value.field) == (MESSAGE, "observation")
    assert info.value.code == "invalid_argument"


def test_the_server_answers_problem_details_the_sdk_reads(base_url: str) -> None:
    answer = httpx.post(f"{base_url}/v1/act", json={"env": "particle", "ego_goal": "a2"})
    assert answer.status_code == 422
    assert answer.headers["content-type"] == "application/problem+json"
    problem = answer.json()
    assert problem["type"] == "/problems/invalid_request" and problem["status"] == 422
    assert problem["field"] == "observation" and "error" not in problem
    with CoexistClient(base_url) as client, pytest.raises(InvalidArgument) as info:
        client.act("particle", "a2", OBS_2[:7])
    assert info.value.field == "observation" and info.value.message.startswith("observation: ")


def _mock_client(status: int, body: Any) -> CoexistClient:
    def handler(request: httpx.Request) -> httpx.Response:
        if isinstance(body, bytes):
            return httpx.Response(status, content=body)
        return httpx.Response(status, json=body)

    return CoexistClient("http://mock", transport=httpx.MockTransport(handler))


@pytest.mark.parametrize(
    ("status", "body", "error", "code"),
    [
        (
            503,
            {"error": {"code": "model_unavailable", "message": "store down", "field": None}},
            Unavailable,
            "unavailable",
        ),
        (
            503,
            {"type": "/problems/store_unavailable", "status": 503, "detail": "store down"},
            Unavailable,
            "unavailable",
        ),
        (500, b"<html>oops</html>", CoexistError, "internal"),
        (
            413,
            {"error": {"code": "too_large", "message": "body: too large", "field": "body"}},
            InvalidArgument,
            "invalid_argument",
        ),
        (
            413,
            {"type": "/problems/body_too_large", "detail": "body: too large", "field": "body"},
            InvalidArgument,
            "invalid_argument",
        ),
    ],
)
def test_error_responses_map_to_classes(
    status: int, body: Any, error: type[CoexistError], code: str
) -> None:
    with _mock_client(status, body) as client, pytest.raises(error) as info:
        client.act("particle", "a2", OBS_2)
    assert type(info.value) is error and info.value.code == code


def test_connection_refused_is_unavailable() -> None:
    def refuse(request: httpx.Request) -> httpx.Response:
        raise httpx.ConnectError("connection refused", request=request)

    client = CoexistClient("http://mock", transport=httpx.MockTransport(refuse))
    with client, pytest.raises(Unavailable):
        client.envs()


def test_async_client_over_asgi_matches_the_sync_client(
    engine: InferenceEngine, client: CoexistClient
) -> None:
    obs_BD = np.random.default_rng(2).random((3, 8)) * 0.9

    async def main() -> tuple[Action, list[Action], str | None, bool]:
        transport = httpx.ASGITransport(app=inference_app(engine))
        async with AsyncCoexistClient("http://asgi", transport=transport) as aclient:
            single = await aclient.act("particle", "a2", OBS_2, partners={1: "b3"}, seed=4)
            batch = await aclient.act_batch("particle", "a2", obs_BD, partners={1: "b3"}, seed=4)
            ready = (await aclient.health()).ready and bool(await aclient.envs())
            try:
                await aclient.act("particle", "zz", OBS_2)
            except InvalidArgument as err:
                return single, batch, err.field, ready
            return single, batch, None, ready

    single, batch, field, ready = asyncio.run(main())
    assert single == client.act("particle", "a2", OBS_2, partners={1: "b3"}, seed=4)
    assert batch == client.act_batch("particle", "a2", obs_BD, partners={1: "b3"}, seed=4)
    assert field == "ego_goal" and ready
