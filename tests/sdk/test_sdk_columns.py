"""The SDK's batches over the columnar format, all four clients: `act_batch` returns exactly what
the rows format gave, `act_batch_columns` the same as arrays; errors still name `observations`."""

from __future__ import annotations

import asyncio
from collections.abc import Iterator
from typing import Any

import httpx
import numpy as np
import pytest
from coexist_client import (
    Action,
    ActionColumns,
    AsyncCoexistClient,
    AsyncGrpcCoexistClient,
    CoexistClient,
    GrpcCoexistClient,
    InvalidArgument,
    proto,
)
from coexist_client.bodies import act_batch_body
from grpc_live_server import LiveServer, live_grpc_server
from http_live_server import inference_app, live_http_server

from model_store.sql import SqlModelStore
from services.engine import ActRequest, InferenceEngine, PartnerSpec
from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb

OBS_BD = np.random.default_rng(7).random((6, 12)) * 0.9
PARTNERS: dict[int, Any] = {2: {"b3": 0.6, "c": 0.4}, 1: "d4"}
ENGINE_PARTNERS = (PartnerSpec(2, goal_probs={"b3": 0.6, "c": 0.4}), PartnerSpec(1, goal="d4"))
MEANINGS = ("rest", "up", "down", "left", "right")


@pytest.fixture(scope="module")
def engine(_tiny_zoo_template: Any) -> Iterator[InferenceEngine]:
    with SqlModelStore(f"sqlite:///{_tiny_zoo_template}") as store:  # read-only use
        yield InferenceEngine(store)


@pytest.fixture(scope="module")
def base_url(engine: InferenceEngine) -> Iterator[str]:
    with live_http_server(inference_app(engine)) as url:
        yield url


@pytest.fixture(scope="module")
def live(_tiny_zoo_template: Any) -> Iterator[LiveServer]:
    with SqlModelStore(f"sqlite:///{_tiny_zoo_template}") as store, live_grpc_server(store) as live:
        yield live


def rows_format_actions(base_url: str, live: LiveServer, **kw: Any) -> tuple[list[Action], ...]:
    """What `act_batch` returned before the columnar format: the rows answers, typed."""
    body = act_batch_body("particle", "c1", OBS_BD, partners=PARTNERS, seed=3, **kw)
    http = [
        Action.from_json(r)
        for r in httpx.post(f"{base_url}/v1/act:batch", json=body).json()["results"]
    ]
    message = proto.act_batch_request(body)
    vectors = pb.ActBatchRequest(  # the repeated Vector form the SDK used to send
        env=message.env,
        ego_goal=message.ego_goal,
        partners=message.partners,
        seed=message.seed,
        method=message.method,
        alias=message.alias,
        observations=[pb.Vector(values=r) for r in OBS_BD],
    )
    grpc_ = [proto.action_from_proto(r) for r in live.stub.ActBatch(vectors).results]
    return http, grpc_


def test_act_batch_is_unchanged_for_all_four_clients(
    engine: InferenceEngine, base_url: str, live: LiveServer
) -> None:
    http_rows, grpc_rows = rows_format_actions(base_url, live)
    assert http_rows == grpc_rows and len(http_rows) == 6

    async def both_async() -> tuple[list[Action], list[Action]]:
        transport = httpx.ASGITransport(app=inference_app(engine))
        async with AsyncCoexistClient("http://asgi", transport=transport) as ahttp:
            http_batch = await ahttp.act_batch("particle", "c1", OBS_BD, partners=PARTNERS, seed=3)
        async with AsyncGrpcCoexistClient(live.target) as agrpc:
            grpc_batch = await agrpc.act_batch("particle", "c1", OBS_BD, partners=PARTNERS, seed=3)
        return http_batch, grpc_batch

    with CoexistClient(base_url) as http, GrpcCoexistClient(live.target) as grpc_client:
        assert http.act_batch("particle", "c1", OBS_BD, partners=PARTNERS, seed=3) == http_rows
        assert (
            grpc_client.act_batch("particle", "c1", OBS_BD, partners=PARTNERS, seed=3) == http_rows
        )
    assert asyncio.run(both_async()) == (http_rows, http_rows)
    expected = engine.act(ActRequest("particle", "c1", OBS_BD, ENGINE_PARTNERS, seed=3))
    assert [a.probs for a in http_rows] == [tuple(r.probs) for r in expected]
    assert [a.action for a in http_rows] == [r.action for r in expected]


def assert_columns_match(columns: ActionColumns, actions: list[Action]) -> None:
    assert len(columns) == len(actions) == 6
    assert columns.probs.shape == (6, 5) and columns.probs.dtype == np.float64
    assert columns.actions.dtype == np.int64 and columns.greedy_actions.shape == (6,)
    assert columns.partner_indices == (2, 1) and columns.partner_weights.shape == (6, 2)
    assert columns.action_meanings == tuple(MEANINGS[a] for a in columns.actions)
    assert [m.role for m in columns.models] == ["task", "impact", "impact", "impact"]
    assert columns.to_actions() == actions


def test_act_batch_columns_on_all_four_clients(
    engine: InferenceEngine, base_url: str, live: LiveServer
) -> None:
    http_rows, _ = rows_format_actions(base_url, live)

    async def both_async() -> list[ActionColumns]:
        transport = httpx.ASGITransport(app=inference_app(engine))
        async with AsyncCoexistClient("http://asgi", transport=transport) as ahttp:
            a = await ahttp.act_batch_columns("particle", "c1", OBS_BD, partners=PARTNERS, seed=3)
        async with AsyncGrpcCoexistClient(live.target) as agrpc:
            b = await agrpc.act_batch_columns("particle", "c1", OBS_BD, partners=PARTNERS, seed=3)
        return [a, b]

    with CoexistClient(base_url) as http, GrpcCoexistClient(live.target) as grpc_client:
        answers = [
            http.act_batch_columns("particle", "c1", OBS_BD, partners=PARTNERS, seed=3),
            grpc_client.act_batch_columns("particle", "c1", OBS_BD, partners=PARTNERS, seed=3),
        ]
    for columns in answers + asyncio.run(both_async()):
        assert isinstance(columns, ActionColumns)
        assert_columns_match(columns, http_rows)


def test_states_and_no_partners(base_url: str, live: LiveServer) -> None:
    states = OBS_BD[:3, :8].reshape(3, 2, 4)
    with CoexistClient(base_url) as http, GrpcCoexistClient(live.target) as grpc_client:
        for client in (http, grpc_client):
            by_state = client.act_batch_columns(
                "particle", "a2", states=states, ego_index=0, seed=1
            )
            by_obs = client.act_batch("particle", "a2", OBS_BD[:3, :8], seed=1)  # ego first
            assert by_state.partner_weights.shape == (3, 0) and by_state.partner_indices == ()
            assert by_state.to_actions() == by_obs


def test_errors_still_name_observations(base_url: str, live: LiveServer) -> None:
    with CoexistClient(base_url) as http, GrpcCoexistClient(live.target) as grpc_client:
        for client in (http, grpc_client):
            with pytest.raises(InvalidArgument) as info:
                client.act_batch("particle", "a2", OBS_BD[:, :7])
            assert info.value.field == "observations"
            assert info.value.message.startswith("observations: ")
            with pytest.raises(InvalidArgument) as info:
                client.act_batch_columns("particle", "a2", [[0.1, 0.2, 0, 0], [1e300, 0, 0, 0]])
            assert info.value.field == "observations[1]"
            with pytest.raises(InvalidArgument) as info:
                client.act_batch("particle", "a2", OBS_BD[:2, :8], partners={3: "b3"})
            assert info.value.field == "partners[0].index"


def test_blame_observations_renames_only_the_matrix() -> None:
    err = InvalidArgument(
        "invalid_argument", "observation_matrix[4]: holds NaN", "observation_matrix[4]"
    )
    renamed = proto.blame_observations(err)
    assert (renamed.field, renamed.message) == ("observations[4]", "observations[4]: holds NaN")
    assert type(renamed) is InvalidArgument
    shape = InvalidArgument(
        "invalid_argument", "observation_matrix.rows: expected >= 1", "observation_matrix.rows"
    )
    assert proto.blame_observations(shape).field == "observations"
    other = InvalidArgument("invalid_argument", "states[1]: bad", "states[1]")
    assert proto.blame_observations(other) is other
