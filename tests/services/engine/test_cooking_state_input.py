"""The kitchen takes observations only: a `state` / `states` body for env cooking is a 422 that
names the field and says what to send (its state is not one row per agent)."""

from __future__ import annotations

from fastapi.testclient import TestClient

from services.engine import environments

STATE = [[1.0, 7.0, 0.0, 0.0], [2.0, 8.0, 0.0, 0.0]]


def test_cooking_has_no_state_adapter() -> None:
    assert environments.env_runtime("cooking").state_adapter is None
    assert environments.env_runtime("particle").state_adapter is not None


def test_a_cooking_state_is_refused_with_a_clear_message(act_client: TestClient) -> None:
    body = {"env": "cooking", "ego_goal": "CarrotBanana", "state": STATE, "ego_index": 0}
    response = act_client.post("/v1/act", json=body)
    assert response.status_code == 422, response.text
    error = response.json()
    assert error["field"] == "state" and error["code"] == "invalid_request"
    assert "takes observations only" in error["detail"] and "not one row" in error["detail"]
    batch = {"env": "cooking", "ego_goal": "CarrotBanana", "states": [STATE], "ego_index": 0}
    response = act_client.post("/v1/act:batch", json=batch)
    assert response.status_code == 422 and response.json()["field"] == "states"
    envs = act_client.get("/v1/envs").json()["envs"]
    assert next(e for e in envs if e["name"] == "cooking")["state_layout"] is None
