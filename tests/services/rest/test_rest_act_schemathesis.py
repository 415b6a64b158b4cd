"""Property-based run of the inference routes against their own OpenAPI schema (schemathesis):
whatever a client sends, the answer is never a 5xx and always matches the documented schema.
"Schema-valid data rejected" is not checked: the schema holds JSON types, the engine the values."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import schemathesis
from fastapi import FastAPI
from hypothesis import HealthCheck, settings
from schemathesis.specs.openapi.checks import positive_data_acceptance

from model_store.sql import SqlModelStore
from services.engine import InferenceEngine
from services.registry.errors import install_error_handlers as install_registry_handlers
from services.rest import install_error_handlers, router

APP = FastAPI()
APP.include_router(router)
install_registry_handlers(APP)  # as the server does: the registry's handlers, then ours
install_error_handlers(APP)
schema = schemathesis.openapi.from_asgi("/openapi.json", APP)


@pytest.fixture
def engine_over_zoo(_tiny_zoo_template: Path) -> Iterator[None]:
    with SqlModelStore(f"sqlite:///{_tiny_zoo_template}") as store:  # read-only use
        APP.state.engine = InferenceEngine(store)
        yield
        APP.state.engine = None


@schema.parametrize()
@settings(max_examples=100, deadline=None, suppress_health_check=list(HealthCheck))
def test_inference_routes_never_fail_and_match_their_schema(case, engine_over_zoo) -> None:
    response = case.call()
    assert response.status_code < 500, response.text
    case.validate_response(response, excluded_checks=[positive_data_acceptance])


@pytest.mark.parametrize("fmt", ["rows", "columns"])
def test_both_batch_answers_match_the_documented_schema(engine_over_zoo, fmt: str) -> None:
    """Random bodies rarely get past the engine's checks: one valid batch in each format,
    checked against the operation's schema (its `format` field and its anyOf answer)."""
    operation = schema["/v1/act:batch"]["POST"]
    body: dict[str, Any] = {
        "env": "particle",
        "ego_goal": "a2",
        "partners": [{"index": 1, "goal": "b3"}],
        "observations": [[0.1, 0.4, 0, 0, 0.7, 0.6, 0, 0]] * 3,
        "seed": 1,
        "format": fmt,
    }
    case = operation.Case(body=body, media_type="application/json")
    response = case.call()
    assert response.status_code == 200, response.text
    assert ("format" in response.json()) == (fmt == "columns")
    case.validate_response(response, excluded_checks=[positive_data_acceptance])
