"""Networks the engine cannot serve never register and never become what an alias serves.

The attack: finite weights whose Q-values overflow float32 (every `layers.0.weight` = 3e38), and
a spec of 201 layers, uploaded to a real `coexist serve` over PostgreSQL. Both are refused at
upload (422 naming the part and the reason); an alias move to such a version (registered behind
the server's back, straight into the store) is refused (409) and `production` keeps serving the
last good version, also when the store's alias is moved directly (hot reload keeps the old one).
A server that must load such a version answers 503 naming the networks, never a 422 that blames
the client's valid observation.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import httpx
import numpy as np
import pytest
import torch
from replica_cluster import (
    ADMIN_TOKEN,
    SPEC,
    Server,
    act_body,
    pg_schema_url,
    running,
    seed_zoo,
    server_env,
    start_server,
)

from model_store.entities import Lineage
from model_store.sql import SqlModelStore
from policy.qnet import MAX_LAYERS, QNetSpec, QNetwork, weights_to_safetensors
from services.engine.errors import InvalidRequest, ModelUnavailable
from services.engine.networks import (
    PROBE_SCALE,
    UnservableNetwork,
    build_group,
    check_servable,
    overflow_error,
)

AUTH = {"Authorization": f"Bearer {ADMIN_TOKEN}"}
NAME = "particle/task/a2"
VERSIONS = f"/v1/registry/models/{NAME}/-/versions"


def overflowing_weights(spec: QNetSpec = SPEC) -> bytes:
    """Finite weights (every one a float32) whose first layer overflows on any observation."""
    net = QNetwork(spec)
    first = net.layers[0]
    assert isinstance(first, torch.nn.Linear)
    with torch.no_grad():
        first.weight.fill_(3e38)
    return weights_to_safetensors(net)


def good_weights(spec: QNetSpec = SPEC) -> bytes:
    torch.manual_seed(5)
    return weights_to_safetensors(QNetwork(spec))


def upload(base: str, spec: dict, weights: bytes) -> httpx.Response:
    return httpx.post(
        f"{base}{VERSIONS}",
        files={"weights": ("w.safetensors", weights)},
        data={"spec": json.dumps(spec)},
        headers=AUTH,
        timeout=30,
    )


def act_version(base: str) -> int:
    answer = httpx.post(f"{base}/v1/act", json=act_body(), timeout=30)
    assert answer.status_code == 200, answer.text
    return int(next(m["version"] for m in answer.json()["models"] if m["name"] == NAME))


def test_the_probe_refuses_overflowing_weights_and_keeps_good_ones() -> None:
    check_servable(SPEC.to_json(), good_weights())
    with pytest.raises(UnservableNetwork, match="overflow float32"):
        check_servable(SPEC.to_json(), overflowing_weights())
    # weights that are merely large (a ReLU net scaled up) still serve
    net = QNetwork(SPEC)
    first = net.layers[0]
    assert isinstance(first, torch.nn.Linear)
    with torch.no_grad():
        first.weight.mul_(1e6)
    check_servable(SPEC.to_json(), weights_to_safetensors(net))


def test_specs_deeper_than_the_serving_forward_are_refused() -> None:
    QNetSpec(obs_dim=8, n_actions=5, hidden=(4,) * (MAX_LAYERS - 1))  # the deepest it serves
    with pytest.raises(ValueError, match=f"at most {MAX_LAYERS - 1} hidden layers"):
        QNetSpec(obs_dim=8, n_actions=5, hidden=(4,) * 200)
    # the limit is the compiled forward's own (policy/_row_forward.c)
    source = (Path(__file__).resolve().parents[3] / "policy" / "_row_forward.c").read_text()
    assert f"#define MAX_LAYERS {MAX_LAYERS}\n" in source


def test_an_overflow_blames_the_observation_only_beyond_the_probed_range() -> None:
    from services.engine.networks import _net_of

    net = _net_of(NAME, 3, "", SPEC, good_weights(), None)
    group = build_group([net])
    huge = np.full((1, 8), 1e30, dtype=np.float32)
    ordinary = np.full((1, 8), 0.5, dtype=np.float32)
    client = overflow_error(group, huge, "observations")
    assert isinstance(client, InvalidRequest) and client.field == "observations"
    ours = overflow_error(group, ordinary, "observations")
    assert isinstance(ours, ModelUnavailable) and f"{NAME}/3" in ours.message
    assert "observation" not in (ours.field or "") and f"±{PROBE_SCALE:g}" in ours.message


@pytest.fixture
def served(tmp_path: Path) -> Iterator[tuple[str, Server]]:
    with pg_schema_url() as url:
        seed_zoo(url)  # a2: version 1 at production, version 2 at latest
        server = start_server("admission", server_env(url, tmp_path / "data"), tmp_path)
        with running([server]):
            yield url, server


@pytest.mark.postgres
@pytest.mark.slow
def test_unservable_networks_are_refused_and_production_keeps_serving(
    served: tuple[str, Server], tmp_path: Path
) -> None:
    url, server = served
    base = server.http_url
    assert act_version(base) == 1

    refused = upload(base, SPEC.to_json(), overflowing_weights())
    assert refused.status_code == 422, refused.text
    error = refused.json()
    assert error["field"] == "weights" and "overflow" in error["detail"]
    deep = QNetSpec(obs_dim=8, n_actions=5, hidden=(4,) * 14).to_json()
    deep["hidden"] = [4] * 200  # 201 layers
    refused = upload(base, deep, b"not even read")
    assert refused.status_code == 422, refused.text
    assert refused.json()["field"] == "spec"
    assert "at most 15 hidden layers" in refused.json()["detail"]
    listed = httpx.get(f"{base}{VERSIONS}", headers=AUTH).json()
    assert [v["version"] for v in listed] == [2, 1]  # nothing registered
    assert upload(base, SPEC.to_json(), good_weights()).status_code == 201  # still open: v3

    # A bad version that reached the store another way (an older server, direct access) ...
    with SqlModelStore(url) as store:
        bad = store.register_version(
            NAME,
            spec=SPEC.to_json(),
            weights=overflowing_weights(),
            lineage=Lineage(registered_by="pytest"),
            aliases=(),
        ).version
    assert bad == 4
    moved = httpx.put(
        f"{base}/v1/registry/models/{NAME}/-/aliases/production",
        json={"version": bad},
        headers=AUTH,
    )
    assert moved.status_code == 409, moved.text  # ... is never what production serves
    assert moved.json()["field"] == "version" and "overflow" in moved.text
    assert (
        httpx.get(f"{base}/v1/registry/models/{NAME}", headers=AUTH).json()["aliases"]["production"]
        == 1
    )
    assert act_version(base) == 1

    # Moved behind the registry's back: hot reload cannot load it and keeps version 1.
    with SqlModelStore(url) as store:
        store.set_alias(NAME, "production", bad)
    for _ in range(20):  # several refresh intervals (0.3 s)
        assert act_version(base) == 1
    server.stop()

    # A fresh server has no good version loaded: 503 naming the network, not the observation.
    fresh = start_server("fresh", server_env(url, tmp_path / "data"), tmp_path)
    with running([fresh]):
        answer = httpx.post(f"{fresh.http_url}/v1/act", json=act_body(), timeout=30)
        assert answer.status_code == 503, answer.text
        assert answer.json()["field"] != "observation"
        assert f"{NAME}/{bad}" in answer.text and "overflow" in answer.text
