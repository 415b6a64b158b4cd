"""`POST /v1/act:batch` with `"format": "columns"`: the rows answer's values, one array per field."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

MEANINGS = ("rest", "up", "down", "left", "right")
CASES: dict[str, dict[str, Any]] = {
    "aail, 2 partners": {
        "ego_goal": "e0",
        "width": 12,
        "method": "aail",
        "partners": [{"index": 2, "goal": "c"}, {"index": 1, "goal": "a2"}],
    },
    "aail, goal_probs": {
        "ego_goal": "a2",
        "width": 8,
        "method": "aail",
        "partners": [{"index": 1, "goal_probs": {"b3": 0.3, "c": 0.7}}],
    },
    "sl": {"ego_goal": "c1", "width": 8, "method": "sl", "partners": [{"index": 1, "goal": "b3"}]},
    "sl alone": {"ego_goal": "c1", "width": 4, "method": "sl", "partners": []},
}


def _body(case: dict[str, Any], rows: int) -> dict[str, Any]:
    obs = np.random.default_rng(rows).random((rows, case["width"])) * 0.9
    fields = {k: v for k, v in case.items() if k != "width"}
    return {"env": "particle", **fields, "observations": obs.tolist(), "seed": 5}


def assert_columns_are_rows(columns: dict[str, Any], results: list[dict[str, Any]]) -> None:
    """Every field of every row, exactly (both answers come from the same floats)."""
    assert columns["format"] == "columns"
    assert columns["probs"] == [r["probs"] for r in results]
    assert columns["actions"] == [r["action"] for r in results]
    assert columns["greedy_actions"] == [r["greedy_action"] for r in results]
    assert columns["action_meanings"] == [r["action_meaning"] for r in results]
    assert columns["action_meanings"] == [MEANINGS[a] for a in columns["actions"]]
    assert columns["task_entropies"] == [r["diagnostics"]["task_entropy"] for r in results]
    assert columns["task_weights"] == [r["diagnostics"]["task_weight"] for r in results]
    for b, result in enumerate(results):
        weights = result["diagnostics"]["partner_weights"]
        assert columns["partner_indices"] == [w["index"] for w in weights]
        assert columns["partner_weights"][b] == [w["weight"] for w in weights]
        assert columns["models"] == result["models"] and columns["method"] == result["method"]


@pytest.mark.parametrize("rows", [1, 7])
@pytest.mark.parametrize("case", CASES.values(), ids=list(CASES))
def test_columns_equal_rows_with_the_same_seed(act_client, case: dict[str, Any], rows: int) -> None:
    body = _body(case, rows)
    rows_answer = act_client.post("/v1/act:batch", json=body)
    columns_answer = act_client.post("/v1/act:batch", json={**body, "format": "columns"})
    assert rows_answer.status_code == columns_answer.status_code == 200, columns_answer.text
    assert columns_answer.headers["content-type"] == "application/json"
    results = rows_answer.json()["results"]
    assert "format" not in rows_answer.json()  # the default answer is unchanged
    columns = columns_answer.json()
    assert set(columns) == {
        "format",
        "method",
        "models",
        "probs",
        "actions",
        "greedy_actions",
        "action_meanings",
        "task_entropies",
        "task_weights",
        "partner_indices",
        "partner_weights",
    }
    assert_columns_are_rows(columns, results)
    explicit_rows = act_client.post("/v1/act:batch", json={**body, "format": "rows"}).json()
    assert explicit_rows["results"] == results


def test_columns_from_states(act_client) -> None:
    states = np.random.default_rng(2).random((3, 2, 4)).round(4).tolist()
    body = {
        "env": "particle",
        "ego_goal": "a2",
        "states": states,
        "ego_index": 1,
        "partners": [{"index": 1, "goal": "b3"}],
        "seed": 1,
        "format": "columns",
    }
    columns = act_client.post("/v1/act:batch", json=body).json()
    by_obs = {
        **body,
        "states": None,
        "ego_index": None,
        "observations": [s[1] + s[0] for s in states],
    }
    assert columns == act_client.post("/v1/act:batch", json=by_obs).json()
    rows = act_client.post("/v1/act:batch", json={**body, "format": "rows"}).json()["results"]
    assert_columns_are_rows(columns, rows)


@pytest.mark.parametrize("bad", ["COLUMNS", "tensor", 1, None])
def test_bad_format_is_a_422_naming_format(act_client, bad: Any) -> None:
    body = {**_body(CASES["sl"], 2), "format": bad}
    response = act_client.post("/v1/act:batch", json=body)
    assert response.status_code == 422, response.text
    error = response.json()
    assert error["field"] == "format" and error["detail"].startswith("format: ")


def test_columns_errors_name_the_body_fields(act_client) -> None:
    body = {**_body(CASES["sl"], 3), "format": "columns"}
    body["observations"][1][2] = 1e300  # beyond float32
    error = act_client.post("/v1/act:batch", json=body).json()
    assert error["field"] == "observations[1]"
    missing = {**_body(CASES["sl"], 2), "format": "columns", "ego_goal": "a0"}
    response = act_client.post("/v1/act:batch", json=missing)
    assert response.status_code == 404 and response.json()["field"] == "ego_goal"


def test_openapi_documents_both_answers_and_the_format(act_client) -> None:
    spec = act_client.get("/openapi.json").json()
    route = spec["paths"]["/v1/act:batch"]["post"]
    answer = route["responses"]["200"]["content"]["application/json"]["schema"]
    refs = {item["$ref"].rsplit("/", 1)[-1] for item in answer["anyOf"]}
    assert refs == {"ActBatchResponse", "ActColumnsResponse"}
    schemas = spec["components"]["schemas"]
    fmt = schemas["ActBatchBody"]["properties"]["format"]
    assert fmt["enum"] == ["rows", "columns"] and fmt["default"] == "rows" and fmt["description"]
    assert "partner_weights" in schemas["ActColumnsResponse"]["required"]
