"""The gRPC transport against a real server on 127.0.0.1: results equal the engine's, Episode
streams, health checking, reflection, graceful shutdown and the shape of ListEnvs."""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Iterator

import grpc
import numpy as np
import pytest
from grpc_health.v1 import health_pb2, health_pb2_grpc
from grpc_live_server import LiveServer, live_grpc_server
from grpc_reflection.v1alpha.proto_reflection_descriptor_database import (
    ProtoReflectionDescriptorDatabase,
)

from envs.particle.world import observations
from model_store.sql import SqlModelStore
from services.engine import ActRequest, ActResult, PartnerSpec
from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb

OBS_2 = [0.1, 0.4, 0.0, 0.0, 0.7, 0.6, 0.1, -0.1]  # ego, partner: [x, y, vx, vy] each


@pytest.fixture
def live(tiny_zoo_store: SqlModelStore) -> Iterator[LiveServer]:
    with live_grpc_server(tiny_zoo_store) as server:
        yield server


def assert_same(response: pb.ActResponse, expected: ActResult, partner_indices: list[int]) -> None:
    assert list(response.probs) == expected.probs
    assert response.action == expected.action
    assert response.greedy_action == expected.greedy_action
    assert response.method == expected.method
    assert response.action_meaning == ("rest", "up", "down", "left", "right")[expected.action]
    d = response.diagnostics
    assert d.task_entropy == expected.task_entropy and d.task_weight == expected.task_weight
    assert [(w.index, w.weight) for w in d.partner_weights] == list(
        zip(partner_indices, expected.partner_weights, strict=True)
    )
    got = [
        (
            m.role,
            m.name,
            m.version,
            m.sha256,
            m.goal,
            m.partner_index if m.HasField("partner_index") else None,
        )
        for m in response.models
    ]
    want = [(m.role, m.name, m.version, m.sha256, m.goal, m.partner_index) for m in expected.models]
    assert got == want


def test_act_equals_engine(live: LiveServer) -> None:
    request = pb.ActRequest(
        env="particle",
        ego_goal="a2",
        observation=OBS_2,
        partners=[pb.PartnerSpec(index=1, goal="b3")],
        seed=7,
    )
    response = live.stub.Act(request)
    [expected] = live.engine.act(
        ActRequest("particle", "a2", np.array([OBS_2]), (PartnerSpec(1, goal="b3"),), seed=7)
    )
    assert_same(response, expected, [1])
    assert response.method == "aail_bounded" and len(response.models) == 2  # task a2 + impact b3
    assert abs(sum(response.probs) - 1.0) < 1e-9


def test_act_from_state_equals_act_from_observation(live: LiveServer) -> None:
    state_N4 = np.array([[0.7, 0.6, 0.1, -0.1], [0.1, 0.4, 0.0, 0.0], [0.5, 0.9, 0.0, 0.2]])
    ego_obs = observations(state_N4)[1]  # agent 1's own view
    partners = [pb.PartnerSpec(index=1, goal_probs={"b3": 0.25, "c": 0.75})]
    by_obs = live.stub.Act(
        pb.ActRequest(env="particle", ego_goal="c1", observation=ego_obs, partners=partners, seed=3)
    )
    state = pb.State(agents=[pb.Vector(values=row) for row in state_N4])
    by_state = live.stub.Act(
        pb.ActRequest(
            env="particle", ego_goal="c1", state=state, ego_index=1, partners=partners, seed=3
        )
    )
    assert by_state == by_obs
    assert len(by_obs.models) == 3  # task c1 + impact b3 + impact c, both for partner 1


def test_act_batch_equals_engine_row_by_row(live: LiveServer) -> None:
    rng = np.random.default_rng(0)
    obs_BD = rng.random((16, 12)) * np.tile([1.0, 1.0, 0.2, 0.2], 3)
    partners = [pb.PartnerSpec(index=2, goal="c"), pb.PartnerSpec(index=1, goal="d4")]
    response = live.stub.ActBatch(
        pb.ActBatchRequest(
            env="particle",
            ego_goal="b3",
            observations=[pb.Vector(values=r) for r in obs_BD],
            partners=partners,
            method="nail",
            temperature=0.3,
            seed=11,
        )
    )
    expected = live.engine.act(
        ActRequest(
            "particle",
            "b3",
            obs_BD,
            (PartnerSpec(2, goal="c"), PartnerSpec(1, goal="d4")),
            method="nail",
            temperature=0.3,
            seed=11,
        )
    )
    assert len(response.results) == 16
    for got, want in zip(response.results, expected, strict=True):
        assert_same(got, want, [2, 1])


def test_episode_stream_seeds_step_t_with_seed_plus_t(live: LiveServer) -> None:
    rng = np.random.default_rng(1)
    obs_TD = rng.random((4, 8)) * [1, 1, 0, 0, 1, 1, 0, 0]
    settings = pb.EpisodeSettings(
        env="particle", ego_goal="a2", partners=[pb.PartnerSpec(index=1, goal="b3")], seed=40
    )
    new_settings = pb.EpisodeSettings(
        env="particle", ego_goal="a2", partners=[pb.PartnerSpec(index=1, goal="e0")], seed=40
    )
    steps = [pb.EpisodeStep(settings=settings, observation=obs_TD[0])]
    steps += [pb.EpisodeStep(observation=obs_TD[t]) for t in (1, 2)]
    steps += [pb.EpisodeStep(settings=new_settings, observation=obs_TD[3])]  # a new goal
    responses = list(live.stub.Episode(iter(steps)))
    assert len(responses) == 4
    for t, response in enumerate(responses):
        goal = "b3" if t < 3 else "e0"
        [expected] = live.engine.act(
            ActRequest(
                "particle", "a2", obs_TD[t : t + 1], (PartnerSpec(1, goal=goal),), seed=40 + t
            )
        )
        assert_same(response, expected, [1])


def test_list_envs_describes_the_particle_world(live: LiveServer) -> None:
    envs = {e.name: e for e in live.stub.ListEnvs(pb.ListEnvsRequest()).envs}
    env = envs["particle"]
    assert env.name == "particle" and len(env.goals) == 35 and "a2" in env.goals
    assert list(env.action_meanings) == ["rest", "up", "down", "left", "right"]
    assert (
        env.max_agents == 5
        and env.pair_obs_dim == 8
        and list(env.state_layout)
        == [
            "x",
            "y",
            "vx",
            "vy",
        ]
    )
    assert [(layout.n_agents, layout.obs_dim) for layout in env.observation_layouts] == [
        (n, 4 * n) for n in range(1, 6)
    ]
    assert list(env.observation_layouts[1].features)[:5] == [
        "self.x",
        "self.y",
        "self.vx",
        "self.vy",
        "other1.x",
    ]
    assert set(env.methods) == {"aail_bounded", "aail_budget", "aail", "nail", "sl", "jl"}


def test_health_is_serving_and_follows_readiness(tiny_zoo_store: SqlModelStore) -> None:
    ready = threading.Event()
    with live_grpc_server(tiny_zoo_store, ready=ready.is_set, health_recheck_s=0.0) as live:
        health = health_pb2_grpc.HealthStub(live.channel)
        for service in ("", "coexist.v1.PolicyService"):
            request = health_pb2.HealthCheckRequest(service=service)
            assert health.Check(request).status == health_pb2.HealthCheckResponse.NOT_SERVING
        ready.set()
        for service in ("", "coexist.v1.PolicyService"):
            request = health_pb2.HealthCheckRequest(service=service)
            assert health.Check(request).status == health_pb2.HealthCheckResponse.SERVING
        with pytest.raises(grpc.RpcError) as info:
            health.Check(health_pb2.HealthCheckRequest(service="no.such.Service"))
        assert info.value.code() == grpc.StatusCode.NOT_FOUND


def test_default_readiness_is_the_engine_store(live: LiveServer) -> None:
    health = health_pb2_grpc.HealthStub(live.channel)
    status = health.Check(health_pb2.HealthCheckRequest(service="coexist.v1.PolicyService"))
    assert status.status == health_pb2.HealthCheckResponse.SERVING


def test_reflection_lists_and_describes_the_service(live: LiveServer) -> None:
    database = ProtoReflectionDescriptorDatabase(live.channel)
    services = set(database.get_services())
    assert {"coexist.v1.PolicyService", "grpc.health.v1.Health"} <= services
    assert "inference.GRPCInferenceService" in services  # the v2 service, for grpcurl & co.
    from google.protobuf.descriptor_pool import DescriptorPool

    pool = DescriptorPool(database)
    service = pool.FindServiceByName("coexist.v1.PolicyService")
    assert [m.name for m in service.methods] == ["Act", "ActBatch", "ListEnvs", "Episode"]
    episode = service.methods_by_name["Episode"]
    assert episode.input_type.full_name == "coexist.v1.EpisodeStep"


def test_graceful_stop_finishes_in_flight_calls(
    tiny_zoo_store: SqlModelStore, monkeypatch: pytest.MonkeyPatch
) -> None:
    with live_grpc_server(tiny_zoo_store) as live:
        real_act = live.engine.act

        def slow_act(request: ActRequest) -> list[ActResult]:
            time.sleep(0.3)
            return real_act(request)

        monkeypatch.setattr(live.engine, "act", slow_act)
        request = pb.ActRequest(env="particle", ego_goal="a2", observation=OBS_2)
        future = live.stub.Act.future(request)
        time.sleep(0.1)  # the call is in the engine now
        stopped = live.server.stop(grace=5.0)
        assert future.result(timeout=5).method == "aail_bounded"  # answered, not cancelled
        assert stopped.wait(timeout=5)


def test_cancelled_episodes_free_their_worker_threads(tiny_zoo_store: SqlModelStore) -> None:
    with live_grpc_server(tiny_zoo_store, max_workers=2) as live:
        settings = pb.EpisodeSettings(env="particle", ego_goal="a2")
        for _ in range(4):  # twice the pool: leaked threads would block the Act below
            outbox: queue.SimpleQueue[pb.EpisodeStep] = queue.SimpleQueue()
            responses = live.stub.Episode(iter(outbox.get, None))
            outbox.put(pb.EpisodeStep(settings=settings, observation=OBS_2))
            assert next(responses).method == "aail_bounded"
            responses.cancel()  # the client goes away mid-episode
        request = pb.ActRequest(env="particle", ego_goal="a2", observation=OBS_2)
        assert live.stub.Act(request, timeout=5).method == "aail_bounded"
