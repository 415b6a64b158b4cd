"""One client may hold at most `episodes_per_client` open `Episode` streams, fewer than all
clients together may: the next stream is RESOURCE_EXHAUSTED, and a closed stream frees its slot
(each open stream holds a thread of the sync server, so one client could otherwise take them
all). The bound shared by all clients: test_grpc_idle_streams.py."""

from __future__ import annotations

import queue
from collections.abc import Iterator
from typing import Any

import grpc
import pytest
from grpc_live_server import live_grpc_server

from model_store.sql import SqlModelStore
from services.grpc_api.episode_slots import client_of
from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb

OBS = [0.1, 0.4, 0.0, 0.0, 0.7, 0.6, 0.0, 0.0]
FIRST = pb.EpisodeStep(
    settings=pb.EpisodeSettings(
        env="particle", ego_goal="a2", partners=[pb.PartnerSpec(index=1, goal="b3")]
    ),
    observation=OBS,
)


class OpenEpisode:
    """A stream whose first step was answered and that stays open until `close`."""

    def __init__(self, stub: Any) -> None:
        self._outbox: queue.SimpleQueue[pb.EpisodeStep | None] = queue.SimpleQueue()
        self._outbox.put(FIRST)
        self.responses = stub.Episode(self._drain(), timeout=30)
        self.first = next(self.responses)

    def _drain(self) -> Iterator[pb.EpisodeStep]:
        while (step := self._outbox.get()) is not None:
            yield step

    def close(self) -> None:
        self._outbox.put(None)
        list(self.responses)


def test_a_client_holds_at_most_its_own_bound(tiny_zoo_store: SqlModelStore) -> None:
    with live_grpc_server(
        tiny_zoo_store, max_workers=4, max_episodes=3, episodes_per_client=2
    ) as live:
        held = [OpenEpisode(live.stub) for _ in range(2)]
        with pytest.raises(grpc.RpcError) as caught:
            OpenEpisode(live.stub)
        err: Any = caught.value
        assert err.code() == grpc.StatusCode.RESOURCE_EXHAUSTED, err.details()
        assert "this client holds its maximum of 2 open Episode streams" in err.details()
        assert "/v1/" not in err.details()  # a gRPC client is told a gRPC remedy, not a route
        assert live.stub.Act(pb.ActRequest(env="particle", ego_goal="a2", observation=OBS))
        held.pop().close()
        held.append(OpenEpisode(live.stub))  # a slot came free
        for episode in held:
            episode.close()


@pytest.mark.parametrize(
    ("peer", "client"),
    [
        ("ipv4:10.0.0.7:5123", "10.0.0.7"),
        ("ipv6:[::1]:5123", "::1"),
        ("unix:/tmp/s", "unix:/tmp/s"),
    ],
)
def test_clients_are_told_apart_by_address(peer: str, client: str) -> None:
    assert client_of(peer) == client
