"""gRPC request ids: the caller's `x-request-id` (or a new one) on every log line written while
a call is served, echoed (a unary call's in its trailing metadata, a stream's in its initial
metadata), and one access line per call with its status."""

from __future__ import annotations

import io
import json
import logging
from collections.abc import Iterator

import grpc
import pytest
from grpc_health.v1 import health_pb2, health_pb2_grpc
from grpc_live_server import LiveServer, live_grpc_server
from test_services_logging import captured_logs

from model_store.sql import SqlModelStore
from services.engine import ActRequest, ActResult
from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb

OBS_2 = [0.1, 0.4, 0.0, 0.0, 0.7, 0.6, 0.1, -0.1]
handler_log = logging.getLogger("coexist.test.grpc_handler")


@pytest.fixture
def live(tiny_zoo_store: SqlModelStore, monkeypatch: pytest.MonkeyPatch) -> Iterator[LiveServer]:
    with live_grpc_server(tiny_zoo_store) as server:
        act = server.engine.act

        def logging_act(request: ActRequest) -> list[ActResult]:
            handler_log.warning("acting for %s", request.ego_goal)  # a line written mid-call
            return act(request)

        monkeypatch.setattr(server.engine, "act", logging_act)
        yield server


def _records(buffer: io.StringIO) -> list[dict]:
    lines = [json.loads(line) for line in buffer.getvalue().splitlines()]
    return [rec for rec in lines if rec["logger"].startswith("coexist.")]


captured = pytest.fixture(captured_logs)  # root logger output as the server formats it


def _request(env: str = "particle") -> pb.ActRequest:
    return pb.ActRequest(
        env=env, ego_goal="a2", observation=OBS_2, partners=[pb.PartnerSpec(index=1, goal="b3")]
    )


def test_a_callers_id_is_echoed_and_on_every_line(live: LiveServer, captured: io.StringIO) -> None:
    _, call = live.stub.Act.with_call(_request(), metadata=(("x-request-id", "robot-7.s:3"),))
    assert ("x-request-id", "robot-7.s:3") in call.trailing_metadata()
    assert "x-request-id" not in dict(call.initial_metadata())  # no write of its own
    records = _records(captured)
    handler = [r for r in records if r["logger"] == "coexist.test.grpc_handler"]
    assert handler and all(r["request_id"] == "robot-7.s:3" for r in handler)
    [access] = [r for r in records if r["logger"] == "coexist.access"]
    assert access["request_id"] == "robot-7.s:3"
    assert access["route"] == "/coexist.v1.PolicyService/Act" and access["status"] == "OK"
    assert access["method"] == "GRPC" and access["duration_ms"] >= 0


def test_a_missing_or_unsafe_id_is_replaced(live: LiveServer, captured: io.StringIO) -> None:
    for metadata in ((), (("x-request-id", "bad id with spaces"),)):
        _, call = live.stub.Act.with_call(_request(), metadata=metadata)
        echoed = dict(call.trailing_metadata())["x-request-id"]
        assert len(echoed) == 32 and int(echoed, 16) >= 0
    ids = [r["request_id"] for r in _records(captured) if r["logger"] == "coexist.access"]
    assert len(ids) == 2 and ids[0] != ids[1]


def test_a_failed_call_logs_its_status_code(live: LiveServer, captured: io.StringIO) -> None:
    with pytest.raises(grpc.RpcError) as info:
        live.stub.Act(_request(env="nowhere"), metadata=(("x-request-id", "bad-env"),))
    assert info.value.code() == grpc.StatusCode.INVALID_ARGUMENT
    trailers = dict(info.value.trailing_metadata())  # the id beside the error's field
    assert trailers["x-request-id"] == "bad-env" and trailers["coexist-field"] == "env"
    [access] = [r for r in _records(captured) if r["logger"] == "coexist.access"]
    assert access["request_id"] == "bad-env" and access["status"] == "INVALID_ARGUMENT"
    assert access["level"] == "INFO"


def test_an_episode_stream_keeps_its_id_over_every_step(
    live: LiveServer, captured: io.StringIO
) -> None:
    settings = pb.EpisodeSettings(
        env="particle", ego_goal="a2", partners=[pb.PartnerSpec(index=1, goal="b3")], seed=1
    )
    steps = [pb.EpisodeStep(settings=settings, observation=OBS_2)]
    steps += [pb.EpisodeStep(observation=OBS_2) for _ in range(2)]
    responses = live.stub.Episode(iter(steps), metadata=(("x-request-id", "episode-1"),))
    assert len(list(responses)) == 3
    assert ("x-request-id", "episode-1") in responses.initial_metadata()
    records = _records(captured)
    handler = [r for r in records if r["logger"] == "coexist.test.grpc_handler"]
    assert len(handler) == 3 and {r["request_id"] for r in handler} == {"episode-1"}
    [access] = [r for r in records if r["logger"] == "coexist.access"]
    assert access["route"] == "/coexist.v1.PolicyService/Episode" and access["status"] == "OK"


def test_health_checks_log_at_debug(live: LiveServer, captured: io.StringIO) -> None:
    health = health_pb2_grpc.HealthStub(live.channel)
    health.Check(health_pb2.HealthCheckRequest(service=""))
    [access] = [r for r in _records(captured) if r["logger"] == "coexist.access"]
    assert access["level"] == "DEBUG" and access["route"] == "/grpc.health.v1.Health/Check"
