"""The provisioned Grafana dashboard and alert rules are valid, and every metric their queries
read is in a real server's /metrics: REST and gRPC traffic (one error included) through the app
`coexist serve` runs, then one scrape."""

# ruff: noqa: F811  (the fixtures imported from zoo_fixtures are re-bound as test arguments)

from __future__ import annotations

import json
import re
import sys
from pathlib import Path
from typing import Any

import grpc
import pytest
import yaml
from fastapi.testclient import TestClient
from pydantic import SecretStr

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tests" / "services"))  # the tiny zoo's fixtures
from zoo_fixtures import _tiny_zoo_template, tiny_zoo_store  # noqa: E402, F401

from model_store.sql import SqlModelStore  # noqa: E402
from services.app import create_app  # noqa: E402
from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb  # noqa: E402
from services.grpc_api.gen.coexist.v1 import policy_pb2_grpc as pb_grpc  # noqa: E402
from services.settings import Settings  # noqa: E402

GRAFANA = REPO / "docker" / "grafana"
DASHBOARD = json.loads((GRAFANA / "dashboards" / "coexist.json").read_text())
ALERTS = yaml.safe_load((GRAFANA / "provisioning" / "alerting" / "coexist.yaml").read_text())
DATASOURCE = yaml.safe_load(
    (GRAFANA / "provisioning" / "datasources" / "prometheus.yaml").read_text()
)
UID = DATASOURCE["datasources"][0]["uid"]
METRIC = re.compile(r"\b((?:coexist|process)_[a-z_]+)\b")
OBS = [0.1, 0.4, 0.0, 0.0, 0.7, 0.6, 0.0, 0.0]


def _exprs() -> list[str]:
    panels = [t["expr"] for p in DASHBOARD["panels"] for t in p["targets"]]
    rules = [
        query["model"]["expr"]
        for group in ALERTS["groups"]
        for rule in group["rules"]
        for query in rule["data"]
        if query["datasourceUid"] == UID
    ]
    return panels + rules


def test_the_dashboard_is_valid() -> None:
    panels = DASHBOARD["panels"]
    ids = [p["id"] for p in panels]
    assert len(ids) == len(set(ids)), "panel ids repeat"
    cells: set[tuple[int, int]] = set()
    for p in panels:
        assert p["title"] and p["type"] == "timeseries" and p["datasource"]["uid"] == UID
        g = p["gridPos"]
        assert g["x"] >= 0 and g["x"] + g["w"] <= 24 and g["h"] > 0, p["title"]
        mine = {
            (x, y) for x in range(g["x"], g["x"] + g["w"]) for y in range(g["y"], g["y"] + g["h"])
        }
        assert not mine & cells, f"{p['title']} overlaps another panel"
        cells |= mine
        refs = [t["refId"] for t in p["targets"]]
        assert len(refs) == len(set(refs)) and all(t["expr"].strip() for t in p["targets"])
        assert all(t["datasource"]["uid"] == UID for t in p["targets"])
    titles = " ".join(p["title"] for p in panels)
    for wanted in ("gRPC calls", "gRPC error", "gRPC latency", "store reachable", "memory", "file"):
        assert wanted in titles, wanted


def test_the_alert_rules_are_valid() -> None:
    assert ALERTS["apiVersion"] == 1
    rules = [rule for group in ALERTS["groups"] for rule in group["rules"]]
    assert {r["uid"] for r in rules} == {
        "coexist-grpc-error-ratio",
        "coexist-grpc-p99",
        "coexist-store-unavailable",
    }
    for rule in rules:
        refs = {q["refId"]: q for q in rule["data"]}
        assert rule["condition"] in refs and rule["for"] and rule["labels"]["severity"]
        assert {q["datasourceUid"] for q in rule["data"]} == {UID, "__expr__"}
        for query in rule["data"]:
            model = query["model"]
            assert model["refId"] == query["refId"]
            if query["datasourceUid"] == "__expr__":
                assert model["expression"] in refs  # reduces or compares a query of the rule


def _traffic(app: Any, client: TestClient) -> None:
    body = {
        "env": "particle",
        "ego_goal": "a2",
        "observation": OBS,
        "partners": [{"index": 1, "goal": "b3"}],
    }
    assert client.post("/v1/act", json=body).status_code == 200
    good = pb.ActRequest(
        env="particle",
        ego_goal="a2",
        observation=OBS,
        partners=[pb.PartnerSpec(index=1, goal="b3")],
    )
    with grpc.insecure_channel(f"127.0.0.1:{app.state.grpc_port}") as channel:
        stub = pb_grpc.PolicyServiceStub(channel)
        assert len(stub.Act(good, timeout=10).probs) == 5
        with pytest.raises(grpc.RpcError):
            stub.Act(pb.ActRequest(env="particle", ego_goal="a2", observation=OBS[:5]), timeout=10)


def test_every_query_reads_a_metric_the_server_exports(tiny_zoo_store: SqlModelStore) -> None:
    wanted = {name for expr in _exprs() for name in METRIC.findall(expr)}
    assert {"coexist_grpc_requests_total", "coexist_store_reachable", "process_open_fds"} <= wanted
    app = create_app(
        Settings(admin_token=SecretStr("t0ken-for-the-tests-0123"), grpc_port=0),
        store=tiny_zoo_store,
    )
    with TestClient(app) as client:
        _traffic(app, client)
        scrape = client.get("/metrics").text
    exported = {
        line.split("{")[0].split(" ")[0]
        for line in scrape.splitlines()
        if line and not line.startswith("#")
    }
    assert wanted <= exported, sorted(wanted - exported)
    assert re.search(r"^coexist_store_reachable 1\.0$", scrape, re.MULTILINE)
    assert re.search(
        r'^coexist_grpc_request_seconds_bucket\{le="60\.0",method=', scrape, re.MULTILINE
    )
