"""Every bad input to the inference routes is a 4xx JSON error naming the field, never a 500."""

from __future__ import annotations

import json
from typing import Any

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from services.rest import install_error_handlers, router

OBS = [0.1, 0.4, 0.0, 0.0, 0.7, 0.6, 0.0, 0.0]
BODY: dict[str, Any] = {
    "env": "particle",
    "ego_goal": "a2",
    "observation": OBS,
    "partners": [{"index": 1, "goal": "b3"}],
}
BATCH: dict[str, Any] = {
    "env": "particle",
    "ego_goal": "a2",
    "observations": [OBS, OBS],
    "partners": [{"index": 1, "goal": "b3"}],
}
JSON = {"content-type": "application/json"}
STATE = [[0.1, 0.4, 0.0, 0.0], [0.7, 0.6, 0.0, 0.0]]

ACT_CASES: list[tuple[str, dict[str, Any], int, str]] = [
    ("unknown env", {"env": "atari"}, 422, "env"),
    ("missing env", {"env": None}, 422, "env"),
    ("unknown ego goal", {"ego_goal": "zz"}, 422, "ego_goal"),
    ("wrong length", {"observation": OBS[:7]}, 422, "observation"),
    ("too many agents", {"observation": OBS * 3}, 422, "observation"),
    ("empty observation", {"observation": []}, 422, "observation"),
    ("string in observation", {"observation": ["x", *OBS[1:]]}, 422, "observation[0]"),
    ("neither observation nor state", {"observation": None}, 422, "observation"),
    ("both observation and state", {"state": STATE, "ego_index": 0}, 422, "observation"),
    ("ego_index without state", {"ego_index": 0}, 422, "ego_index"),
    ("state without ego_index", {"observation": None, "state": STATE}, 422, "ego_index"),
    (
        "ego_index out of range",
        {"observation": None, "state": STATE, "ego_index": 2},
        422,
        "ego_index",
    ),
    (
        "ragged state",
        {"observation": None, "state": [[0.1, 0.2, 0, 0], [0.1]], "ego_index": 0},
        422,
        "state",
    ),
    (
        "state with 3 features",
        {"observation": None, "state": [[0.1, 0.2, 0]], "ego_index": 0},
        422,
        "state",
    ),
    (
        "partner index out of range",
        {"partners": [{"index": 2, "goal": "b3"}]},
        422,
        "partners[0].index",
    ),
    ("partner index 0", {"partners": [{"index": 0, "goal": "b3"}]}, 422, "partners[0].index"),
    (
        "duplicated partner",
        {
            "observation": OBS + OBS[:4],
            "partners": [{"index": 1, "goal": "b3"}, {"index": 1, "goal": "c"}],
        },
        422,
        "partners[1].index",
    ),
    (
        "partner index not an int",
        {"partners": [{"index": "one", "goal": "b3"}]},
        422,
        "partners[0].index",
    ),
    ("unknown partner goal", {"partners": [{"index": 1, "goal": "zz"}]}, 422, "partners[0].goal"),
    (
        "goal and goal_probs",
        {"partners": [{"index": 1, "goal": "b3", "goal_probs": {"b3": 1}}]},
        422,
        "partners[0].goal",
    ),
    ("no goal", {"partners": [{"index": 1}]}, 422, "partners[0].goal"),
    (
        "probs not summing to 1",
        {"partners": [{"index": 1, "goal_probs": {"b3": 0.5, "c": 0.4}}]},
        422,
        "partners[0].goal_probs",
    ),
    (
        "negative prob",
        {"partners": [{"index": 1, "goal_probs": {"b3": 1.5, "c": -0.5}}]},
        422,
        "partners[0].goal_probs",
    ),
    (
        "unknown partner field",
        {"partners": [{"index": 1, "goal": "b3", "weight": 2}]},
        422,
        "partners[0].weight",
    ),
    ("unknown top-level field", {"observations": [OBS]}, 422, "observations"),
    ("negative temperature", {"temperature": -0.1}, 422, "temperature"),
    ("zero temperature", {"temperature": 0}, 422, "temperature"),
    (
        "negative regret bound",
        {"method": "aail_bounded", "regret_bound": -0.1},
        422,
        "regret_bound",
    ),
    (
        "regret bound not a number",
        {"method": "aail_bounded", "regret_bound": "tight"},
        422,
        "regret_bound",
    ),
    ("regret bound with aail", {"method": "aail", "regret_bound": 0.1}, 422, "regret_bound"),
    ("regret bound with sl", {"method": "sl", "regret_bound": 0.1}, 422, "regret_bound"),
    ("unknown method", {"method": "best"}, 422, "method"),
    ("negative seed", {"seed": -3}, 422, "seed"),
    ("bad alias", {"alias": "NOT AN ALIAS"}, 422, "alias"),
    (
        "bad pinned version",
        {"versions": {"particle/task/a2": 0}},
        422,
        "versions[particle/task/a2]",
    ),
    (
        "huge pinned version",
        {"versions": {"particle/task/a2": 10**30}},
        422,
        "versions[particle/task/a2]",
    ),
    ("missing alias", {"alias": "staging"}, 404, "ego_goal"),
    ("missing task network", {"ego_goal": "a0"}, 404, "ego_goal"),
    ("missing impact network", {"partners": [{"index": 1, "goal": "a1"}]}, 404, "partners[0].goal"),
    (
        "missing pinned version",
        {"versions": {"particle/impact/b3": 5}},
        404,
        "versions[particle/impact/b3]",
    ),
    (
        "jl without a joint network",
        {"method": "jl", "partners": [{"index": 1, "goal": "c"}]},
        404,
        "method",
    ),
    ("jl without partners", {"method": "jl", "partners": []}, 422, "partners"),
]


def _check_error(response, status: int, field: str) -> dict:
    assert response.status_code == status, response.text
    error = response.json()
    assert error["field"] == field, error
    assert error["detail"].startswith(f"{field}: ") and len(error["detail"]) > len(field) + 4
    assert error["code"] == {404: "model_not_found", 422: "invalid_request"}[status]
    return error


@pytest.mark.parametrize(
    ("change", "status", "field"), [c[1:] for c in ACT_CASES], ids=[c[0] for c in ACT_CASES]
)
def test_act_errors(act_client, change, status: int, field: str) -> None:
    _check_error(act_client.post("/v1/act", json={**BODY, **change}), status, field)


BATCH_CASES: list[tuple[str, dict[str, Any], int, str]] = [
    ("empty batch", {"observations": []}, 422, "observations"),
    ("row of wrong length", {"observations": [OBS, OBS[:4]]}, 422, "observations"),
    ("all rows of wrong length", {"observations": [OBS[:6], OBS[:6]]}, 422, "observations"),
    ("oversized batch", {"observations": [OBS] * 9}, 422, "observations"),
    ("NaN row", {"observations": [OBS, [float("nan"), *OBS[1:]]]}, 422, "observations[1]"),
    ("states and observations", {"states": [STATE], "ego_index": 0}, 422, "observations"),
    (
        "state row with inf",
        {
            "observations": None,
            "states": [STATE, [[0, 0, 0, float("inf")], STATE[1]]],
            "ego_index": 0,
        },
        422,
        "states[1]",
    ),
    (
        "states of unequal agents",
        {"observations": None, "states": [STATE, STATE[:1]], "ego_index": 0},
        422,
        "states",
    ),
    ("nested wrongly", {"observations": OBS}, 422, "observations[0]"),
]


@pytest.mark.parametrize(
    ("change", "status", "field"), [c[1:] for c in BATCH_CASES], ids=[c[0] for c in BATCH_CASES]
)
def test_act_batch_errors(act_client, change, status: int, field: str) -> None:
    act_client.app.state.engine.max_batch = 8
    content = json.dumps({**BATCH, **change})  # json.dumps writes NaN and Infinity literals
    response = act_client.post("/v1/act:batch", content=content, headers=JSON)
    _check_error(response, status, field)


@pytest.mark.parametrize(
    "content",
    [
        '{"env": "particle", "ego_goal": "a2", "observation": [0.1,',
        "",
        "not json",
        "[1, 2]",
        "null",
        '"x"',
    ],
    ids=["truncated", "empty", "garbage", "array", "null", "string"],
)
def test_malformed_json_is_422_on_body(act_client, content: str) -> None:
    for path in ("/v1/act", "/v1/act:batch"):
        response = act_client.post(path, content=content, headers=JSON)
        _check_error(response, 422, "body")


def test_nan_literal_in_json(act_client) -> None:
    content = (
        '{"env": "particle", "ego_goal": "a2", "observation": [NaN, 0.4, 0, 0, 0.7, 0.6, 0, 0]}'
    )
    response = act_client.post("/v1/act", content=content, headers=JSON)
    assert "NaN" in _check_error(response, 422, "observation")["detail"]


def test_missing_engine_is_503() -> None:
    app = FastAPI()
    app.include_router(router)
    install_error_handlers(app)
    response = TestClient(app).post("/v1/act", json=BODY)
    assert response.status_code == 503
    assert response.json()["code"] == "model_unavailable"


def test_store_outage_is_503(act_client, monkeypatch) -> None:
    from model_store.errors import StoreUnavailable

    def down(ref: str):
        raise StoreUnavailable("database is gone")

    monkeypatch.setattr(act_client.app.state.engine.store, "resolve", down)
    response = act_client.post("/v1/act", json=BODY)
    assert response.status_code == 503
    assert "database is gone" in response.json()["detail"]
