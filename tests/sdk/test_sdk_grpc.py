"""The gRPC SDK clients (sync and grpc.aio) against a real server: typed results equal the engine's,
partner forms, episodes, errors."""

from __future__ import annotations

import asyncio
import socket
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from coexist_client import (
    Action,
    AsyncGrpcCoexistClient,
    CoexistError,
    GrpcCoexistClient,
    InvalidArgument,
    NotFound,
    Unavailable,
)
from grpc_live_server import LiveServer, live_grpc_server

from model_store.sql import SqlModelStore
from services.engine import ActRequest, ActResult, PartnerSpec

OBS_2 = [0.1, 0.4, 0.0, 0.0, 0.7, 0.6, 0.1, -0.1]


@pytest.fixture(scope="module")
def live(_tiny_zoo_template: Any) -> Iterator[LiveServer]:
    with SqlModelStore(f"sqlite:///{_tiny_zoo_template}") as store, live_grpc_server(store) as live:
        yield live


@pytest.fixture
def client(live: LiveServer) -> Iterator[GrpcCoexistClient]:
    with GrpcCoexistClient(f"grpc://{live.target}") as client:
        yield client


def assert_action_is(action: Action, expected: ActResult, partner_indices: list[int]) -> None:
    assert action.probs == tuple(expected.probs)
    assert (action.action, action.greedy_action) == (expected.action, expected.greedy_action)
    assert action.action_meaning == ("rest", "up", "down", "left", "right")[expected.action]
    assert action.method == expected.method
    assert action.diagnostics.task_weight == expected.task_weight
    assert action.diagnostics.task_entropy == expected.task_entropy
    weights = [(w.index, w.weight) for w in action.diagnostics.partner_weights]
    assert weights == list(zip(partner_indices, expected.partner_weights, strict=True))
    got = [(m.role, m.name, m.version, m.sha256, m.partner_index, m.goal) for m in action.models]
    want = [(m.role, m.name, m.version, m.sha256, m.partner_index, m.goal) for m in expected.models]
    assert got == want


def engine_act(live: LiveServer, obs: Any, partners: tuple[PartnerSpec, ...], **kw: Any) -> Any:
    return live.engine.act(ActRequest("particle", "a2", np.atleast_2d(obs), partners, **kw))


def test_act_returns_the_engine_result_typed(live: LiveServer, client: GrpcCoexistClient) -> None:
    action = client.act("particle", "a2", OBS_2, partners={1: "b3"}, seed=5)
    [expected] = engine_act(live, OBS_2, (PartnerSpec(1, goal="b3"),), seed=5)
    assert_action_is(action, expected, [1])
    assert [m.role for m in action.models] == ["task", "impact"]
    assert action.models[1].partner_index == 1 and action.models[0].partner_index is None


@pytest.mark.parametrize(
    "partners",
    [
        {1: "b3"},
        [PartnerSpec(1, goal="b3")],
        [{"index": 1, "goal": "b3"}],
        {1: {"b3": 1.0}},
    ],
    ids=["mapping", "specs", "dicts", "probs"],
)
def test_partner_forms_are_equivalent(client: GrpcCoexistClient, partners: Any) -> None:
    reference = client.act("particle", "a2", OBS_2, partners={1: "b3"}, seed=2)
    assert client.act("particle", "a2", OBS_2, partners=partners, seed=2).probs == reference.probs


def test_goal_probabilities(live: LiveServer, client: GrpcCoexistClient) -> None:
    action = client.act("particle", "a2", OBS_2, partners={1: {"b3": 0.7, "c": 0.3}}, seed=1)
    action_reversed = client.act(
        "particle", "a2", OBS_2, partners={1: {"c": 0.3, "b3": 0.7}}, seed=1
    )
    assert action_reversed == action  # a proto map has no order: the server sorts by goal
    probs = (PartnerSpec(1, goal_probs={"b3": 0.7, "c": 0.3}),)
    [expected] = engine_act(live, OBS_2, probs, seed=1)
    assert_action_is(action, expected, [1])


def test_state_input_and_batch(live: LiveServer, client: GrpcCoexistClient) -> None:
    state = [[0.7, 0.6, 0.1, -0.1], [0.1, 0.4, 0.0, 0.0]]
    by_state = client.act("particle", "a2", state=state, ego_index=1, partners={1: "b3"}, seed=0)
    by_obs = client.act("particle", "a2", [*state[1], *state[0]], partners={1: "b3"}, seed=0)
    assert by_state == by_obs

    obs_BD = np.random.default_rng(3).random((5, 8)) * 0.9
    actions = client.act_batch(
        "particle", "a2", obs_BD, partners={1: "c"}, method="sl", temperature=0.5, seed=9
    )
    expected = engine_act(
        live, obs_BD, (PartnerSpec(1, goal="c"),), method="sl", temperature=0.5, seed=9
    )
    assert len(actions) == 5
    for action, want in zip(actions, expected, strict=True):
        assert_action_is(action, want, [1])


def test_envs_and_health(client: GrpcCoexistClient) -> None:
    envs = {e.name: e for e in client.envs()}
    particle = envs["particle"]
    assert particle.max_agents == 5 and particle.obs_dims[2] == 8 and len(particle.goals) == 35
    assert particle.observation_layouts[2][4] == "other1.x"
    assert particle.state_layout == ("x", "y", "vx", "vy")
    health = client.health()
    assert health.live and health.ready and health.detail["status"] == "SERVING"


def test_episode_session_seeds_step_t_with_seed_plus_t(
    live: LiveServer, client: GrpcCoexistClient
) -> None:
    obs_TD = np.random.default_rng(4).random((3, 8)) * 0.9
    with client.episode("particle", "a2", partners={1: "b3"}, seed=100) as episode:
        actions = [episode.act(obs) for obs in obs_TD]
    for t, action in enumerate(actions):
        [expected] = engine_act(live, obs_TD[t], (PartnerSpec(1, goal="b3"),), seed=100 + t)
        assert_action_is(action, expected, [1])


def test_errors_are_typed_and_name_the_field(client: GrpcCoexistClient) -> None:
    with pytest.raises(InvalidArgument) as info:
        client.act("particle", "a2", OBS_2[:6], partners={1: "b3"})
    assert info.value.field == "observation" and isinstance(info.value, ValueError)
    assert info.value.code == "invalid_argument"
    with pytest.raises(InvalidArgument) as info:
        client.act("particle", "a2", OBS_2, partners={1: {"b3": 0.5}})
    assert info.value.field == "partners[0].goal_probs"
    with pytest.raises(NotFound) as not_found:
        client.act("particle", "e4", OBS_2)
    assert not_found.value.field == "ego_goal" and isinstance(not_found.value, LookupError)
    with pytest.raises(InvalidArgument) as info:  # caught before sending: JSON/proto agnostic
        client.act("particle", "a2", [*OBS_2[:3], float("nan"), *OBS_2[4:]])
    assert info.value.field == "observation[3]"
    with pytest.raises(InvalidArgument) as info, client.episode("particle", "a2") as episode:
        episode.act(OBS_2[:5])
    assert info.value.field == "observation" and "step[0]" in info.value.message


def _closed_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def test_no_server_is_unavailable() -> None:
    client = GrpcCoexistClient(f"127.0.0.1:{_closed_port()}", timeout=2.0)
    with client, pytest.raises(Unavailable) as info:
        client.act("particle", "a2", OBS_2)
    assert isinstance(info.value, CoexistError) and isinstance(info.value, ConnectionError)


def test_async_client_matches_the_sync_client(live: LiveServer, client: GrpcCoexistClient) -> None:
    obs_TD = np.random.default_rng(5).random((2, 8)) * 0.9

    async def main() -> tuple[Action, list[Action], list[Action], str | None]:
        async with AsyncGrpcCoexistClient(live.target) as aclient:
            single = await aclient.act("particle", "a2", OBS_2, partners={1: "b3"}, seed=3)
            batch = await aclient.act_batch("particle", "a2", obs_TD, partners={1: "b3"}, seed=3)
            async with aclient.episode("particle", "a2", partners={1: "b3"}, seed=7) as episode:
                steps = [await episode.act(obs) for obs in obs_TD]
            assert (await aclient.health()).ready
            assert "particle" in {e.name for e in await aclient.envs()}
            try:
                await aclient.act("particle", "a2", OBS_2, partners={2: "b3"})
            except InvalidArgument as err:
                return single, batch, steps, err.field
            return single, batch, steps, None

    single, batch, steps, field = asyncio.run(main())
    assert single == client.act("particle", "a2", OBS_2, partners={1: "b3"}, seed=3)
    assert batch == client.act_batch("particle", "a2", obs_TD, partners={1: "b3"}, seed=3)
    with client.episode("particle", "a2", partners={1: "b3"}, seed=7) as episode:
        assert steps == [episode.act(obs) for obs in obs_TD]
    assert field == "partners[0].index"


def test_aail_budget_state_round_trips_over_grpc(
    live: LiveServer, client: GrpcCoexistClient
) -> None:
    """The episode's budget comes back with each act and, sent back, gives the engine's answer
    for the carried state; a batch carries one budget per row; an episode stream carries it
    itself and agrees with the stateless calls."""
    rng = np.random.default_rng(3)
    observations = [rng.uniform(0, 1, 8) for _ in range(6)]
    state = None
    stream = client.episode("particle", "a2", partners={1: "b3"}, method="aail_budget", seed=5)
    try:
        for t, obs in enumerate(observations):
            a = client.act(
                "particle",
                "a2",
                obs,
                partners={1: "b3"},
                method="aail_budget",
                seed=5 + t,
                budget_state=state,
            )
            spent: list[float] | None = None if state is None else [state.spent]
            total: list[float] | None = None if state is None else [state.total]
            value: list[float] | None = None if state is None else [state.value]
            expected = engine_act(
                live,
                obs,
                (PartnerSpec(1, goal="b3"),),
                method="aail_budget",
                seed=5 + t,
                budget_spent=spent,
                budget_total=total,
                budget_value=value,
            )[0]
            assert a.budget is not None
            assert a.budget.spent == pytest.approx(expected.budget_spent)
            assert a.budget.total == pytest.approx(expected.budget_total)
            assert a.budget.value == pytest.approx(expected.budget_value)
            assert a.probs == pytest.approx(expected.probs)
            step = stream.act(obs)
            assert step.budget == a.budget and step.probs == pytest.approx(a.probs)
            state = a.budget
    finally:
        stream.close()
    columns = client.act_batch_columns(
        "particle",
        "a2",
        np.array(observations[:2]),
        partners={1: "b3"},
        method="aail_budget",
        budget_spent=[0.0, 0.5],
        budget_total=[1.0, 0.5],
        budget_value=[-0.1, -0.2],
    )
    assert columns.budget_total is not None and columns.budget_spent is not None
    assert columns.budget_value is not None and len(columns.budget_value) == 2
    assert columns.budget_total.tolist() == [1.0, 0.5]
    assert columns.budget_spent[1] == pytest.approx(0.5)  # nothing left to spend
