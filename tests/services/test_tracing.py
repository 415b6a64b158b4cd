"""OpenTelemetry traces (services/tracing.py): with a tracer provider, a REST or gRPC act is a
server span whose children are the engine's act and, on a cache miss, the store's weight load;
with tracing off (the default) coexist makes no span, even where a global provider exists."""

from __future__ import annotations

from collections.abc import Iterator

import grpc
import pytest
from fastapi.testclient import TestClient
from opentelemetry.sdk.trace import ReadableSpan, TracerProvider
from opentelemetry.sdk.trace.export import SimpleSpanProcessor
from opentelemetry.sdk.trace.export.in_memory_span_exporter import InMemorySpanExporter
from opentelemetry.trace import SpanKind
from pydantic import SecretStr

from model_store.sql import SqlModelStore
from services.app import create_app
from services.engine import InferenceEngine
from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb
from services.grpc_api.gen.coexist.v1 import policy_pb2_grpc as pb_grpc
from services.settings import Settings
from services.tracing import TRACER_NAME

OBS = [0.1, 0.4, 0.0, 0.0, 0.7, 0.6, 0.0, 0.0]
BODY = {
    "env": "particle",
    "ego_goal": "a2",
    "observation": OBS,
    "partners": [{"index": 1, "goal": "b3"}],
}
SETTINGS = {"admin_token": SecretStr("t0ken-for-the-tests-0123"), "grpc_port": 0}


@pytest.fixture
def exporter() -> InMemorySpanExporter:
    return InMemorySpanExporter()


@pytest.fixture
def traced(
    tiny_zoo_store: SqlModelStore, exporter: InMemorySpanExporter
) -> Iterator[tuple[TestClient, int]]:
    provider = TracerProvider()
    provider.add_span_processor(SimpleSpanProcessor(exporter))
    # an engine that has loaded nothing yet: the first act loads its weights from the store
    engine = InferenceEngine(tiny_zoo_store)
    app = create_app(Settings(**SETTINGS), engine=engine, tracer_provider=provider)  # type: ignore[arg-type]
    with TestClient(app) as client:
        exporter.clear()
        yield client, app.state.grpc_port


def _children(spans: tuple[ReadableSpan, ...], parent: ReadableSpan) -> list[ReadableSpan]:
    assert parent.context is not None
    return [s for s in spans if s.parent is not None and s.parent.span_id == parent.context.span_id]


def test_a_rest_act_traces_into_the_engine_and_the_store(
    traced: tuple[TestClient, int], exporter: InMemorySpanExporter
) -> None:
    client, _ = traced
    answer = client.post("/v1/act", json=BODY, headers={"x-request-id": "trace-me-1"})
    assert answer.status_code == 200, answer.text
    spans = exporter.get_finished_spans()
    [server] = [s for s in spans if s.kind == SpanKind.SERVER]
    assert server.name == "POST /v1/act"
    assert server.instrumentation_scope is not None
    assert server.instrumentation_scope.name == TRACER_NAME
    assert server.attributes is not None
    assert server.attributes["http.route"] == "/v1/act"
    assert server.attributes["http.response.status_code"] == 200
    assert server.attributes["coexist.request_id"] == "trace-me-1"
    [act] = _children(spans, server)
    assert act.name == "engine.act" and act.attributes is not None
    assert act.attributes["coexist.ego_goal"] == "a2"
    loads = _children(spans, act)
    assert loads and all(s.name == "store.load_weights" for s in loads)
    assert {s.attributes["coexist.model"] for s in loads if s.attributes} == {
        "particle/task/a2",
        "particle/impact/b3",
    }
    assert len({s.context.trace_id for s in spans if s.context}) == 1  # one trace

    exporter.clear()  # the weights are cached now: an act without loads
    assert client.post("/v1/act", json=BODY).status_code == 200
    names = sorted(s.name for s in exporter.get_finished_spans())
    assert names == ["POST /v1/act", "engine.act"]


def test_a_grpc_act_traces_into_the_engine(
    traced: tuple[TestClient, int], exporter: InMemorySpanExporter
) -> None:
    _, port = traced
    request = pb.ActRequest(
        env="particle",
        ego_goal="a2",
        observation=OBS,
        partners=[pb.PartnerSpec(index=1, goal="b3")],
    )
    with grpc.insecure_channel(f"127.0.0.1:{port}") as channel:
        pb_grpc.PolicyServiceStub(channel).Act(request, timeout=10)
        with pytest.raises(grpc.RpcError):
            pb_grpc.PolicyServiceStub(channel).Act(pb.ActRequest(env="nowhere"), timeout=10)
    spans = exporter.get_finished_spans()
    servers = [s for s in spans if s.kind == SpanKind.SERVER]
    assert [s.name for s in servers] == ["/coexist.v1.PolicyService/Act"] * 2
    good, bad = servers
    assert good.attributes is not None and bad.attributes is not None
    assert good.attributes["rpc.grpc.status_code"] == "OK"
    assert bad.attributes["rpc.grpc.status_code"] == "INVALID_ARGUMENT"
    [act] = _children(spans, good)
    assert act.name == "engine.act"
    assert {s.name for s in _children(spans, act)} == {"store.load_weights"}


def test_without_a_provider_nothing_is_traced(
    tiny_zoo_store: SqlModelStore, exporter: InMemorySpanExporter
) -> None:
    from opentelemetry import trace

    provider = TracerProvider()
    provider.add_span_processor(SimpleSpanProcessor(exporter))
    settings = Settings(**{**SETTINGS, "grpc_enabled": False})  # type: ignore[arg-type]
    app = create_app(settings, store=tiny_zoo_store)
    with TestClient(app) as client, pytest.MonkeyPatch.context() as patch:
        patch.setattr(trace, "get_tracer_provider", lambda: provider)
        assert client.post("/v1/act", json=BODY).status_code == 200
        engine = app.state.engine
        assert not hasattr(engine.act_checked, "coexist_traced")
    # nor does FastAPI's own telemetry (off: `services.app._without_fastapi_telemetry`)
    assert exporter.get_finished_spans() == ()


def test_with_a_global_provider_a_request_is_one_server_span(
    tiny_zoo_store: SqlModelStore, exporter: InMemorySpanExporter
) -> None:
    """Tracing on with the operator's global provider: coexist's span, not FastAPI's as well."""
    from opentelemetry import trace

    provider = TracerProvider()
    provider.add_span_processor(SimpleSpanProcessor(exporter))
    settings = Settings(**{**SETTINGS, "grpc_enabled": False, "otel_enabled": True})  # type: ignore[arg-type]
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(trace, "get_tracer_provider", lambda: provider)
        app = create_app(settings, store=tiny_zoo_store)
        with TestClient(app) as client:
            exporter.clear()
            assert client.post("/v1/act", json=BODY).status_code == 200
    spans = exporter.get_finished_spans()
    [server] = [s for s in spans if s.kind == SpanKind.SERVER]
    assert server.instrumentation_scope is not None
    assert server.instrumentation_scope.name == TRACER_NAME
    assert {s.instrumentation_scope.name for s in spans if s.instrumentation_scope} == {TRACER_NAME}
