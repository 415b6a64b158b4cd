"""Property-based run of the session routes against their own OpenAPI schema (schemathesis), as
`test_rest_act_schemathesis` does for /v1/act: whatever a client sends, the answer is never a 5xx
and always matches the documented schema. Half of the generated calls on /v1/sessions/{id} use a
live session's id (the others a random one: 404), so steps, reads and deletes are exercised."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import pytest
import schemathesis
from fastapi import FastAPI
from hypothesis import HealthCheck, settings
from schemathesis.specs.openapi.checks import allow_header_conformance, positive_data_acceptance
from session_zoo import session_zoo_template

from model_store.sql import SqlModelStore
from services.engine import InferenceEngine
from services.registry.errors import install_error_handlers as install_registry_handlers
from services.rest import install_error_handlers, sessions_router
from services.sessions import SessionNotFound, SessionPartner, SessionSettings, SessionStore

APP = FastAPI()
APP.include_router(sessions_router)
install_registry_handlers(APP)  # as the server does: the registry's handlers, then ours
install_error_handlers(APP)
schema = schemathesis.openapi.from_asgi("/openapi.json", APP)


@pytest.fixture
def sessions(tmp_path_factory: pytest.TempPathFactory) -> Iterator[SessionStore]:
    url = f"sqlite:///{session_zoo_template(tmp_path_factory)}"
    with SqlModelStore(url) as store:  # read-only use
        APP.state.engine = InferenceEngine(store)
        APP.state.sessions = SessionStore(APP.state.engine, max_sessions=8)
        yield APP.state.sessions
        APP.state.engine = APP.state.sessions = None


@schema.parametrize()
@settings(max_examples=60, deadline=None, suppress_health_check=list(HealthCheck))
def test_session_routes_never_fail_and_match_their_schema(case, sessions) -> None:
    live = None
    if "session_id" in (case.path_parameters or {}) and len(case.path_parameters["session_id"]) % 2:
        partners = (SessionPartner(1, infer=True),)
        live = sessions.create(SessionSettings("particle", "a2", partners, seed=1))
        sessions.step(live.session_id, [0.1] * 8)  # so that `observed` may be valid
        case.path_parameters["session_id"] = live.session_id
    response = case.call()
    assert response.status_code < 500, response.text
    # allow_header_conformance: Starlette answers a 405 with the Allow header of the first route
    # matching the path (GET /v1/sessions/{id} lists GET, not also DELETE): a framework limit
    case.validate_response(
        response, excluded_checks=[positive_data_acceptance, allow_header_conformance]
    )
    for session_id in [live.session_id] if live else []:
        with contextlib.suppress(SessionNotFound):  # the case may have deleted it
            sessions.delete(session_id)
    if response.status_code == 201:  # a session the case created
        sessions.delete(response.json()["session_id"])
