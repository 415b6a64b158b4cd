"""The assembled server: REST + gRPC in one process, health, readiness, metrics, warm-up."""

from __future__ import annotations

from pathlib import Path

import grpc
from fastapi.testclient import TestClient
from grpc_health.v1 import health_pb2, health_pb2_grpc
from pydantic import SecretStr

from model_store.sql import SqlModelStore
from services.app import create_app
from services.settings import Settings

OBS = [0.1, 0.4, 0.0, 0.0, 0.7, 0.6, 0.0, 0.0]


def _settings(**extra: object) -> Settings:
    return Settings(admin_token=SecretStr("t0ken-for-the-tests-0123"), grpc_port=0, **extra)  # type: ignore[arg-type]


def test_server_answers_rest_and_grpc_and_reports_metrics(tiny_zoo_store: SqlModelStore) -> None:
    app = create_app(_settings(), store=tiny_zoo_store)
    with TestClient(app) as client:
        assert client.get("/healthz").json() == {"status": "ok"}
        ready = client.get("/readyz")
        assert ready.status_code == 200, ready.text
        assert ready.json()["models_loaded"] > 0  # warm-up loaded the production networks

        body = {
            "env": "particle",
            "ego_goal": "a2",
            "observation": OBS,
            "partners": [{"index": 1, "goal": "b3"}],
            "seed": 1,
        }
        act = client.post("/v1/act", json=body)
        assert act.status_code == 200, act.text
        assert abs(sum(act.json()["probs"]) - 1.0) < 1e-9
        bad = client.post("/v1/act", json={**body, "observation": OBS[:5]})
        assert bad.status_code == 422 and bad.json()["field"] == "observation"

        assert client.get("/v1/registry/models").status_code == 200
        metrics = client.get("/metrics").text
        assert 'route="/v1/registry/models",status="200"' in metrics
        assert (
            'coexist_http_requests_total{method="POST",route="/v1/act",status="200"} 1.0' in metrics
        )
        assert 'route="/v1/act",status="422"' in metrics
        assert "coexist_engine_rows_total" in metrics
        assert 'coexist_model_version_served{model="particle/task/a2@production"}' in metrics

        port = app.state.grpc_port
        assert port
        with grpc.insecure_channel(f"127.0.0.1:{port}") as channel:
            health = health_pb2_grpc.HealthStub(channel).Check(health_pb2.HealthCheckRequest())
            assert health.status == health_pb2.HealthCheckResponse.SERVING

        paths = client.get("/openapi.json").json()["paths"]
        assert {"/v1/act", "/v1/act:batch", "/v1/envs", "/readyz", "/metrics"} <= set(paths)
    assert app.state.engine is None  # the lifespan stopped the engine it created


def test_empty_store_is_alive_but_not_ready(tmp_path: Path) -> None:
    settings = _settings(
        store_url=f"sqlite:///{tmp_path / 'empty.db'}", grpc_enabled=False, create_store=True
    )
    with TestClient(create_app(settings)) as client:
        assert client.get("/healthz").status_code == 200
        ready = client.get("/readyz")
        assert ready.status_code == 503
        assert ready.json()["store_reachable"] is True and ready.json()["models_loaded"] == 0
