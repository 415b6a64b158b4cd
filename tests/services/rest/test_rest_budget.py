"""aail_budget over REST: a stateless client that sends each answer's budget back with its next
`/v1/act` gets the very answers (and budget) of a session, which carries the budget itself; a
batch carries one budget per row; every new field refuses bad values with a 422 naming it."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient
from session_zoo import random_observation, session_zoo_template

from model_store.sql import SqlModelStore
from services.engine import InferenceEngine
from services.rest import install_error_handlers, router, sessions_router

SETTINGS = {"env": "particle", "ego_goal": "a2", "method": "aail_budget", "budget": 0.5}
PARTNERS = [{"index": 1, "goal": "b3"}]


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    with SqlModelStore(f"sqlite:///{session_zoo_template(tmp_path_factory)}") as store:
        app = FastAPI()
        app.include_router(router)
        app.include_router(sessions_router)
        install_error_handlers(app)
        app.state.engine = InferenceEngine(store)
        with TestClient(app) as client:
            yield client


def test_a_stateless_client_carrying_the_budget_gets_the_sessions_answers(
    client: TestClient,
) -> None:
    created = client.post("/v1/sessions", json={**SETTINGS, "partners": PARTNERS, "seed": 9})
    assert created.status_code == 201, created.text
    sid = created.json()["session_id"]
    rng = np.random.default_rng(2)
    carried: dict[str, Any] = {}
    spent = []
    for t in range(12):
        obs = random_observation(rng).tolist()
        body = {**SETTINGS, "partners": PARTNERS, "observation": obs, "seed": 9 + t, **carried}
        stateless = client.post("/v1/act", json=body)
        session = client.post(f"/v1/sessions/{sid}/steps", json={"observation": obs})
        assert stateless.status_code == 200 and session.status_code == 200, stateless.text
        a, s = stateless.json(), session.json()
        assert a["probs"] == pytest.approx(s["probs"], abs=1e-12)
        assert a["action"] == s["action"]
        assert a["budget"] == pytest.approx(s["budget"], abs=1e-12)
        carried = {f"budget_{key}": a["budget"][key] for key in ("spent", "total", "value")}
        spent.append(a["budget"]["spent"])
    assert min(spent) >= 0  # a CUSUM: never below 0 ...
    assert max(spent) > 0  # ... and these random networks do spend


def test_a_batch_carries_one_budget_per_row(client: TestClient) -> None:
    rng = np.random.default_rng(4)
    rows = [random_observation(rng).tolist() for _ in range(3)]
    body = {**SETTINGS, "partners": PARTNERS, "observations": rows, "format": "columns"}
    first = client.post("/v1/act:batch", json=body).json()
    keys = ("budget_spent", "budget_total", "budget_value")
    assert all(len(first[key]) == 3 for key in keys)
    carried = {key: first[key] for key in keys}
    second = client.post("/v1/act:batch", json={**body, **carried}).json()
    assert second["budget_total"] == first["budget_total"]
    # the same observations again: the value did not move, so only B1's cost can add
    assert second["budget_value"] == pytest.approx(first["budget_value"])
    rows_answer = client.post("/v1/act:batch", json={**body, "format": "rows", **carried}).json()
    for r, spent, value in zip(
        rows_answer["results"], second["budget_spent"], second["budget_value"], strict=True
    ):
        assert r["budget"]["spent"] == pytest.approx(spent)
        assert r["budget"]["value"] == pytest.approx(value)


@pytest.mark.parametrize(
    ("changes", "field"),
    [
        ({"budget": -1}, "budget"),
        ({"budget": "lots"}, "budget"),
        ({"budget_spent": 0.1}, "budget_total"),
        ({"budget_total": 1.0}, "budget_spent"),
        ({"budget_spent": 0.1, "budget_total": 1.0}, "budget_value"),
        ({"budget_spent": -0.1, "budget_total": 1.0, "budget_value": -1.0}, "budget_spent"),
        ({"budget_spent": 0.1, "budget_total": "x", "budget_value": -1.0}, "budget_total"),
        ({"budget_spent": 0.1, "budget_total": 1.0, "budget_value": "x"}, "budget_value"),
        ({"method": "aail", "budget": 0.1}, "budget"),
        ({"regret_bound": 0.1}, "regret_bound"),
        (
            {"method": "sl", "budget": None, "budget_spent": 0.0, "budget_total": 1.0},
            "budget_spent",
        ),
    ],
)
def test_bad_budget_fields_get_a_422_naming_them(client: TestClient, changes, field) -> None:
    body = {**SETTINGS, "partners": PARTNERS, "observation": [0.1, 0.5, 0, 0, 0.7, 0.6, 0, 0]}
    response = client.post("/v1/act", json={**body, **changes})
    assert response.status_code == 422, response.text
    assert field in response.text
