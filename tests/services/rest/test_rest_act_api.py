"""The inference REST routes, happy paths: /v1/act, /v1/act:batch, /v1/envs, against the engine."""

from __future__ import annotations

import inspect
from typing import Any

import numpy as np
import pytest

from services.engine import ActRequest, PartnerSpec

OBS = [0.1, 0.4, 0.0, 0.0, 0.7, 0.6, 0.0, 0.0]
BODY: dict[str, Any] = {
    "env": "particle",
    "ego_goal": "a2",
    "observation": OBS,
    "partners": [{"index": 1, "goal": "b3"}],
    "method": "aail",
    "temperature": None,
    "seed": 7,
    "alias": "production",
    "versions": {},
}


def _engine_result(client, **kw):
    fields: dict[str, Any] = {
        "env": "particle",
        "ego_goal": "a2",
        "observations": np.array([OBS]),
        "seed": 7,
        "method": BODY["method"],
    }
    fields["partners"] = (PartnerSpec(1, goal="b3"),)
    fields.update(kw)
    [result] = client.app.state.engine.act(ActRequest(**fields))
    return result


def test_act_returns_the_contract_shape(act_client) -> None:
    response = act_client.post("/v1/act", json=BODY)
    assert response.status_code == 200, response.text
    assert response.headers["content-type"] == "application/json"
    body = response.json()
    assert set(body) == {
        "probs",
        "action",
        "greedy_action",
        "action_meaning",
        "method",
        "diagnostics",
        "models",
    }
    expected = _engine_result(act_client)
    assert body["probs"] == pytest.approx(expected.probs, abs=1e-12)
    assert sum(body["probs"]) == pytest.approx(1.0)
    assert (body["action"], body["greedy_action"]) == (expected.action, expected.greedy_action)
    assert body["action_meaning"] == ("rest", "up", "down", "left", "right")[body["action"]]
    assert body["method"] == "aail"
    assert body["diagnostics"] == {
        "task_entropy": pytest.approx(expected.task_entropy),
        "task_weight": pytest.approx(expected.task_weight),
        "partner_weights": [{"index": 1, "weight": pytest.approx(1.0)}],
    }
    task, impact = body["models"]
    assert task == {
        "role": "task",
        "name": "particle/task/a2",
        "version": 1,
        "sha256": expected.models[0].sha256,
        "partner_index": None,
        "goal": "a2",
    }
    assert (impact["role"], impact["name"], impact["partner_index"]) == (
        "impact",
        "particle/impact/b3",
        1,
    )


def test_act_defaults_and_options(act_client) -> None:
    minimal = {"env": "particle", "ego_goal": "c1", "observation": OBS[:4]}
    body = act_client.post("/v1/act", json=minimal).json()
    assert body["method"] == "aail_bounded" and body["diagnostics"]["partner_weights"] == []
    sl = act_client.post("/v1/act", json={**BODY, "method": "sl", "temperature": 0.5}).json()
    assert sl["probs"] == pytest.approx(
        _engine_result(act_client, method="sl", temperature=0.5).probs
    )
    assert [m["role"] for m in sl["models"]] == ["task"]
    latest = act_client.post("/v1/act", json={**BODY, "alias": "latest"}).json()
    pinned = act_client.post("/v1/act", json={**BODY, "versions": {"particle/task/a2": 2}}).json()
    assert latest["models"][0]["version"] == pinned["models"][0]["version"] == 2
    jl = act_client.post("/v1/act", json={**BODY, "method": "jl"}).json()
    assert [m["name"] for m in jl["models"]] == ["particle/joint/a2+b3"]
    mixed = {**BODY, "partners": [{"index": 1, "goal_probs": {"b3": 0.7, "c": 0.3}}]}
    body = act_client.post("/v1/act", json=mixed).json()
    assert [(m["goal"], m["partner_index"]) for m in body["models"][1:]] == [("b3", 1), ("c", 1)]


def test_act_seed_reproducible(act_client) -> None:
    body = {**BODY, "temperature": 5.0}
    actions = {act_client.post("/v1/act", json=body).json()["action"] for _ in range(5)}
    assert len(actions) == 1
    unseeded = {**body, "seed": None}
    assert len({act_client.post("/v1/act", json=unseeded).json()["action"] for _ in range(40)}) > 1


def test_act_from_global_state(act_client) -> None:
    state = [[0.7, 0.6, 0.0, 0.0], [0.1, 0.4, 0.0, 0.0], [0.9, 0.1, 0.2, 0.0]]
    body = {
        **BODY,
        "observation": None,
        "state": state,
        "ego_index": 1,
        "partners": [{"index": 2, "goal": "b3"}],
    }
    from_state = act_client.post("/v1/act", json=body).json()
    ego_view = np.array([state[1] + state[0] + state[2]])  # ego first, the others in agent order
    expected = _engine_result(
        act_client, observations=ego_view, partners=(PartnerSpec(2, goal="b3"),)
    )
    assert from_state["probs"] == pytest.approx(expected.probs, abs=1e-12)


def test_act_batch_equals_single_requests(act_client) -> None:
    rng = np.random.default_rng(1)
    rows = rng.random((5, 12)).round(4).tolist()
    common = {
        "env": "particle",
        "ego_goal": "e0",
        "partners": [{"index": 2, "goal": "c"}, {"index": 1, "goal": "a2"}],
    }
    response = act_client.post("/v1/act:batch", json={**common, "observations": rows, "seed": 3})
    assert response.status_code == 200, response.text
    results = response.json()["results"]
    assert len(results) == 5
    for row, result in zip(rows, results, strict=True):
        single = act_client.post("/v1/act", json={**common, "observation": row}).json()
        assert result["probs"] == pytest.approx(single["probs"], rel=1e-5, abs=1e-9)
        assert result["greedy_action"] == single["greedy_action"]
        assert result["models"] == single["models"]
        assert [w["index"] for w in result["diagnostics"]["partner_weights"]] == [2, 1]
    again = act_client.post(
        "/v1/act:batch", json={**common, "observations": rows, "seed": 3}
    ).json()
    assert [r["action"] for r in again["results"]] == [r["action"] for r in results]


def test_act_batch_from_states(act_client) -> None:
    states = np.random.default_rng(2).random((3, 2, 4)).round(4).tolist()
    body = {
        "env": "particle",
        "ego_goal": "a2",
        "states": states,
        "ego_index": 0,
        "partners": [{"index": 1, "goal": "b3"}],
    }
    results = act_client.post("/v1/act:batch", json=body).json()["results"]
    by_obs = {
        **body,
        "states": None,
        "ego_index": None,
        "observations": [s[0] + s[1] for s in states],
    }
    expected = act_client.post("/v1/act:batch", json=by_obs).json()["results"]
    assert [r["probs"] for r in results] == [r["probs"] for r in expected]


def test_envs(act_client) -> None:
    response = act_client.get("/v1/envs")
    assert response.status_code == 200
    [env] = [e for e in response.json()["envs"] if e["name"] == "particle"]
    assert env["name"] == "particle"
    assert env["goals"][:3] == ["a0", "a1", "a2"] and len(env["goals"]) == 35
    assert env["action_meanings"] == ["rest", "up", "down", "left", "right"]
    assert env["max_agents"] == 5 and env["pair_obs_dim"] == 8
    assert env["obs_dims"] == {"1": 4, "2": 8, "3": 12, "4": 16, "5": 20}
    assert env["observation_layouts"]["1"] == ["self.x", "self.y", "self.vx", "self.vy"]
    assert len(env["observation_layouts"]["5"]) == 20
    assert env["state_layout"] == ["x", "y", "vx", "vy"]
    assert env["methods"] == ["aail_bounded", "aail_budget", "aail", "nail", "sl", "jl"]


def test_openapi_documents_the_routes(act_client) -> None:
    spec = act_client.get("/openapi.json").json()
    assert {"/v1/act", "/v1/act:batch", "/v1/envs"} <= set(spec["paths"])
    act = spec["paths"]["/v1/act"]["post"]
    assert {"200", "404", "422", "503"} <= set(act["responses"])


def test_handlers_run_on_the_event_loop() -> None:
    """`async def` handlers: no thread-pool hop per request (PERF-NOTES: ~70 µs)."""
    from services.rest import act_api

    for handler in (act_api.act, act_api.act_batch, act_api.envs):
        assert inspect.iscoroutinefunction(handler)
