"""gRPC calls in `/metrics`: the server built by `create_app` counts every call by method and
status code and observes its latency, next to the HTTP requests (`services.metrics.GrpcMetrics`)."""

from __future__ import annotations

import re

import grpc
import pytest
from fastapi.testclient import TestClient
from grpc_health.v1 import health_pb2, health_pb2_grpc
from pydantic import SecretStr

from model_store.sql import SqlModelStore
from services.app import create_app
from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb
from services.grpc_api.gen.coexist.v1 import policy_pb2_grpc as pb_grpc
from services.settings import Settings

OBS = [0.1, 0.4, 0.0, 0.0, 0.7, 0.6, 0.0, 0.0]
ACT = "/coexist.v1.PolicyService/Act"
HEALTH = "/grpc.health.v1.Health/Check"


def _value(metrics: str, sample: str) -> float:
    found = re.search(rf"^{re.escape(sample)} ([0-9.e+-]+)$", metrics, re.MULTILINE)
    assert found is not None, f"{sample} not in /metrics"
    return float(found.group(1))


def test_grpc_calls_are_counted_and_timed(tiny_zoo_store: SqlModelStore) -> None:
    settings = Settings(admin_token=SecretStr("t0ken-for-the-tests-0123"), grpc_port=0)
    app = create_app(settings, store=tiny_zoo_store)
    good = pb.ActRequest(
        env="particle",
        ego_goal="a2",
        observation=OBS,
        partners=[pb.PartnerSpec(index=1, goal="b3")],
    )
    bad = pb.ActRequest(env="particle", ego_goal="a2", observation=OBS[:5])
    with TestClient(app) as client:
        with grpc.insecure_channel(f"127.0.0.1:{app.state.grpc_port}") as channel:
            stub = pb_grpc.PolicyServiceStub(channel)
            for _ in range(3):
                assert len(stub.Act(good, timeout=10).probs) == 5
            with pytest.raises(grpc.RpcError) as refused:
                stub.Act(bad, timeout=10)
            assert refused.value.code() == grpc.StatusCode.INVALID_ARGUMENT
            health = health_pb2_grpc.HealthStub(channel)
            health.Check(health_pb2.HealthCheckRequest(), timeout=10)
        metrics = client.get("/metrics").text
    assert _value(metrics, f'coexist_grpc_requests_total{{code="OK",method="{ACT}"}}') == 3
    assert (
        _value(metrics, f'coexist_grpc_requests_total{{code="INVALID_ARGUMENT",method="{ACT}"}}')
        == 1
    )
    assert _value(metrics, f'coexist_grpc_requests_total{{code="OK",method="{HEALTH}"}}') == 1
    assert _value(metrics, f'coexist_grpc_request_seconds_count{{method="{ACT}"}}') == 4
    assert _value(metrics, f'coexist_grpc_request_seconds_sum{{method="{ACT}"}}') > 0
    # every call is in the histogram, each within its 1 s bucket
    assert _value(metrics, f'coexist_grpc_request_seconds_bucket{{le="1.0",method="{ACT}"}}') == 4
