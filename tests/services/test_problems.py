"""Every error answer outside `/v2` is RFC 9457 problem details (`application/problem+json`),
whichever layer makes it: request validation, the engine, the registry, the router's 404 and
405, the body limit, the token gate, a body that is not UTF-8, an error nothing foresaw. Each
names its type (a page the server serves, open whatever the tokens), the field at fault and
the code clients keyed on before; none holds the token sent or an exception's own words. The
OpenAPI description documents the same."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi import APIRouter
from fastapi.testclient import TestClient
from pydantic import SecretStr

from model_store.sql import SqlModelStore
from services.app import create_app
from services.problems import MEDIA_TYPE, PROBLEM_TYPES
from services.settings import Settings

ADMIN = "admin-token-for-the-problem-tests-01"
READ_TOKEN = "read-token-for-the-problem-tests-01"
READ = {"Authorization": f"Bearer {READ_TOKEN}"}
OBS = [0.1, 0.4, 0.0, 0.0, 0.7, 0.6, 0.0, 0.0]
ACT = {"env": "particle", "ego_goal": "a2", "observation": OBS}
LIMIT = 4096
SECRET_WORDS = "the database password is hunter2"

unforeseen = APIRouter()


@unforeseen.get("/v1/unforeseen")
def fails() -> None:
    raise RuntimeError(SECRET_WORDS)


@pytest.fixture(scope="module")
def client(_tiny_zoo_template: Path) -> Iterator[TestClient]:
    settings = Settings(
        admin_token=SecretStr(ADMIN),
        read_token=SecretStr(READ_TOKEN),
        require_read_token=True,
        max_body_bytes=LIMIT,
        grpc_enabled=False,
    )
    with SqlModelStore(f"sqlite:///{_tiny_zoo_template}") as store:
        app = create_app(settings, store=store, routers=[unforeseen])
        with TestClient(app, raise_server_exceptions=False) as client:
            yield client


def problem_of(response: Any, status: int, code: str, field: str | None = None) -> dict[str, Any]:
    """The body, checked against RFC 9457 and the server's conventions."""
    assert response.status_code == status, response.text
    assert response.headers["content-type"] == MEDIA_TYPE
    body: dict[str, Any] = response.json()
    assert body["status"] == status and body["code"] == code and body["field"] == field, body
    if code in PROBLEM_TYPES:
        assert body["type"] == f"/problems/{code}"
        assert body["title"] == PROBLEM_TYPES[code][0]
    else:
        assert body["type"] == "about:blank" and code == "http_error"
    assert isinstance(body["detail"], str) and body["detail"]
    assert body["instance"] == response.request.url.raw_path.decode().partition("?")[0]
    assert "error" not in body  # the shape before problem details is gone from the server
    return body


def test_validation_errors_name_every_field(client: TestClient) -> None:
    answer = client.post("/v1/act", json={**ACT, "observation": "x", "seed": "y"}, headers=READ)
    first = answer.json()["errors"][0]
    body = problem_of(answer, 422, "invalid_request", first["field"])
    assert body["detail"] == f"{first['field']}: {first['detail']}"
    assert {e["field"] for e in body["errors"]} == {"observation", "seed"}
    json_type = {**READ, "Content-Type": "application/json"}
    malformed = client.post("/v1/act", content=b'{"env": ', headers=json_type)
    assert "malformed JSON" in problem_of(malformed, 422, "invalid_request", "body")["detail"]
    job = client.post(
        "/v1/jobs", json={"kind": "nope"}, headers={"Authorization": f"Bearer {ADMIN}"}
    )
    problem_of(job, 422, "invalid_request", "kind")


def test_engine_registry_and_session_errors(client: TestClient) -> None:
    unknown_goal = client.post("/v1/act", json={**ACT, "ego_goal": "zz"}, headers=READ)
    problem_of(unknown_goal, 422, "invalid_request", "ego_goal")
    pinned = {**ACT, "versions": {"particle/task/a2": 7}}
    missing = client.post("/v1/act", json=pinned, headers=READ)
    problem_of(missing, 404, "model_not_found", "versions[particle/task/a2]")
    registry = client.get("/v1/registry/models/particle/task/zz", headers=READ)
    problem_of(registry, 404, "not_found", "name")
    session = client.get("/v1/sessions/no-such-session", headers=READ)
    problem_of(session, 404, "session_not_found", "session_id")


def test_the_router_the_body_limit_and_the_decoder(client: TestClient) -> None:
    problem_of(client.get("/v1/nothing-here", headers=READ), 404, "not_found")
    wrong_method = client.delete("/v1/envs", headers=READ)
    problem_of(wrong_method, 405, "method_not_allowed")
    assert wrong_method.headers["allow"] == "GET"
    big = client.post("/v1/act", content=b"[" + b" " * LIMIT + b"]", headers=READ)
    assert str(LIMIT) in problem_of(big, 413, "body_too_large", "body")["detail"]
    latin1 = client.post(
        "/v1/act", content=b'{"env": "\xe9"}', headers={**READ, "Content-Type": "application/json"}
    )
    assert problem_of(latin1, 400, "http_error")["title"] == "Bad Request"  # about:blank


def test_the_token_gate_says_what_is_missing_and_echoes_no_token(client: TestClient) -> None:
    anonymous = client.post("/v1/act", json=ACT)
    problem_of(anonymous, 401, "unauthorized")
    assert anonymous.headers["www-authenticate"] == "Bearer"
    wrong_token = "wrong-token-that-must-not-come-back-0"
    wrong = client.post("/v1/act", json=ACT, headers={"Authorization": f"Bearer {wrong_token}"})
    problem_of(wrong, 403, "forbidden")
    assert wrong_token not in wrong.text


def test_an_unforeseen_error_is_a_500_problem_without_its_words(client: TestClient) -> None:
    answer = client.get("/v1/unforeseen", headers=READ)
    body = problem_of(answer, 500, "internal")
    assert "RuntimeError" in body["detail"] and "hunter2" not in answer.text


def test_every_problem_type_is_a_page_open_to_anyone(client: TestClient) -> None:
    index = client.get("/problems")
    assert index.status_code == 200 and index.headers["content-type"].startswith("text/html")
    for code, (title, _) in PROBLEM_TYPES.items():
        assert f'href="/problems/{code}"' in index.text
        page = client.get(f"/problems/{code}")  # no token: documentation
        assert page.status_code == 200 and title in page.text, code
        assert "`" not in page.text  # backquoted names are code
    problem_of(client.get("/problems/no_such_type", headers=READ), 404, "not_found")
    problem_of(client.get("/problems/no_such_type"), 401, "unauthorized")  # not a page


def test_openapi_documents_problem_details_for_every_error(client: TestClient) -> None:
    openapi = client.get("/openapi.json", headers=READ).json()
    assert openapi["components"]["schemas"]["Problem"]["required"] == [
        "type",
        "title",
        "status",
        "detail",
        "code",
    ]
    errors = 0
    for path, operations in openapi["paths"].items():
        for operation in operations.values():
            for status, response in operation["responses"].items():
                if status[0] not in "45":
                    continue
                media_types = set(response.get("content", {}))
                if path == "/v2" or path.startswith("/v2/"):
                    # the protocol's own error body, 400 where FastAPI would document 422
                    assert status != "422", path
                    schema = response["content"]["application/json"]["schema"]
                    assert schema == {"$ref": "#/components/schemas/InferenceError"}, path
                else:
                    errors += 1
                    assert media_types == {MEDIA_TYPE}, (path, status, media_types)
    assert errors > 40  # the act, session, registry and job routes' errors


def test_every_code_the_server_raises_has_a_problem_type() -> None:
    """The error classes' codes (`code = "..."`, `code, field = "...", ...`) and the codes the HTTP layers answer with
    (`ApiError(415, "...")`, `_refuse(503, "...")`, ...), read from the sources: each has a
    title and a page. gRPC's own (`services/grpc_api`) never reach HTTP."""
    root = Path(__file__).resolve().parents[2]
    raised: set[str] = set()
    for folder in ("services", "model_store"):
        for path in (root / folder).rglob("*.py"):
            if "grpc_api" in path.parts:
                continue
            text = path.read_text()
            raised.update(re.findall(r'\bcode\b[\w, ]*= "([a-z_]+)"', text))
            raised.update(re.findall(r'(?:\(|return)\s*[45]\d\d,\s*"([a-z_]+)"', text))
    assert {"body_too_large", "unauthorized", "session_not_found", "not_found"} <= raised
    assert raised - {"http_error"} <= set(PROBLEM_TYPES), raised - set(PROBLEM_TYPES)
