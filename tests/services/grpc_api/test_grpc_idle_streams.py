"""Idle `Episode` streams cannot take the gRPC server down: against a real `coexist serve`,
streams from two client addresses that send one step and then nothing leave `Act` from a third
address and health `Check` answering within a second (the streams are bounded by a limit all
clients share, below the worker count, and health has threads of its own); a silent stream is
ended with DEADLINE_EXCEEDED and frees its slot."""

from __future__ import annotations

import contextlib
import queue
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import grpc
import pytest
from grpc_health.v1 import health_pb2, health_pb2_grpc
from grpc_live_server import live_grpc_server
from live_serve import serving, zoo_copy
from source_proxy import SourceProxy

from model_store.sql import SqlModelStore
from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb
from services.grpc_api.gen.coexist.v1 import policy_pb2_grpc as pb_grpc
from services.settings import Settings

OBS = [0.1, 0.4, 0.0, 0.0, 0.7, 0.6, 0.0, 0.0]
FIRST = pb.EpisodeStep(
    settings=pb.EpisodeSettings(
        env="particle", ego_goal="a2", partners=[pb.PartnerSpec(index=1, goal="b3")]
    ),
    observation=OBS,
)
ACT = pb.ActRequest(env="particle", ego_goal="a2", observation=OBS)


class SilentEpisode:
    """A stream that sends its first step, then nothing until `close` (the attack)."""

    def __init__(self, stub: Any) -> None:
        self._outbox: queue.SimpleQueue[pb.EpisodeStep | None] = queue.SimpleQueue()
        self._outbox.put(FIRST)
        self.call = stub.Episode(self._steps(), timeout=60)

    def _steps(self) -> Iterator[pb.EpisodeStep]:
        while (step := self._outbox.get()) is not None:
            yield step

    def close(self) -> None:
        self._outbox.put(None)
        self.call.cancel()


def _open_silent(stub: Any, opened: list[SilentEpisode]) -> None:
    episode = SilentEpisode(stub)
    opened.append(episode)
    with contextlib.suppress(grpc.RpcError):  # refused past the bound: it stays silent too
        next(episode.call)


@pytest.mark.slow
def test_idle_streams_from_two_addresses_leave_act_and_health_answering(
    tmp_path: Path, _tiny_zoo_template: Path
) -> None:
    url = zoo_copy(_tiny_zoo_template, tmp_path / "store")
    with serving(tmp_path, url) as server:
        host, port = server.grpc_target.split(":")
        upstream = (host, int(port))
        with (
            SourceProxy("127.0.0.2", upstream) as second,
            SourceProxy("127.0.0.3", upstream) as third,
            grpc.insecure_channel(server.grpc_target) as first_channel,
            grpc.insecure_channel(second.target) as second_channel,
            grpc.insecure_channel(third.target) as probe_channel,
        ):
            opened: list[SilentEpisode] = []
            attackers = [
                threading.Thread(target=_open_silent, args=(pb_grpc.PolicyServiceStub(c), opened))
                for c in [first_channel] * 4 + [second_channel] * 4
            ]
            for attacker in attackers:
                attacker.start()
            for attacker in attackers:
                attacker.join(timeout=30)
            assert len(opened) == 8
            policy = pb_grpc.PolicyServiceStub(probe_channel)
            health = health_pb2_grpc.HealthStub(probe_channel)
            try:
                for _ in range(3):
                    start = time.monotonic()
                    checked = health.Check(health_pb2.HealthCheckRequest(), timeout=1.0)
                    assert checked.status == health_pb2.HealthCheckResponse.SERVING
                    assert policy.Act(ACT, timeout=1.0).probs
                    assert time.monotonic() - start < 1.0
            finally:
                for episode in opened:
                    episode.close()


def test_a_silent_stream_is_ended_and_frees_its_slot(tiny_zoo_store: SqlModelStore) -> None:
    with live_grpc_server(tiny_zoo_store, max_workers=2, episode_idle_s=0.5) as live:
        episode = SilentEpisode(live.stub)
        assert next(episode.call).probs
        start = time.monotonic()
        with pytest.raises(grpc.RpcError) as caught:
            next(episode.call)
        err: Any = caught.value
        assert err.code() == grpc.StatusCode.DEADLINE_EXCEEDED, err.details()
        assert "no step for 0.5 s" in err.details()
        assert "COEXIST_EPISODE_IDLE_TIMEOUT_S" in err.details()
        assert time.monotonic() - start < 5.0
        episode.close()
        again = SilentEpisode(live.stub)  # the only slot (2 workers: 1 stream) came free
        assert next(again.call).probs
        again.close()


def test_streams_are_bounded_across_clients_below_the_workers(
    tiny_zoo_store: SqlModelStore,
) -> None:
    with live_grpc_server(tiny_zoo_store, max_workers=4, episodes_per_client=4) as live:
        held = [SilentEpisode(live.stub) for _ in range(2)]
        for episode in held:
            assert next(episode.call).probs
        refused = SilentEpisode(live.stub)
        with pytest.raises(grpc.RpcError) as caught:
            next(refused.call)
        err: Any = caught.value
        assert err.code() == grpc.StatusCode.RESOURCE_EXHAUSTED, err.details()
        assert "the server holds its maximum of 2" in err.details()
        assert live.stub.Act(ACT, timeout=2.0).probs  # two workers are left for unary calls
        for episode in held:
            episode.close()


def test_streams_must_leave_workers_to_unary_calls() -> None:
    with pytest.raises(ValueError, match="COEXIST_MAX_EPISODES"):
        Settings(grpc_workers=4, max_episodes=4)
    assert Settings(grpc_workers=4, max_episodes=3).max_episodes == 3
