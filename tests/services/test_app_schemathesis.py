"""The whole server's OpenAPI, fuzzed (schemathesis): every operation, up to `CASES` generated
cases each, in four configurations: SQLite and PostgreSQL, each with reads open and anonymous
requests, and with a read token required and the admin token on every request (so the writes
are fuzzed too). Not one answer may be a 5xx.

The apps are the real one (`create_app`, its middleware and error handlers) over a small
registered zoo (`replica_cluster.seed_zoo`), its engine warmed up as at start-up; the store,
engine and job table of each backend are installed in the app's state by a fixture (the way
the server's lifespan does it). The job runner runs `true` instead of `coexist train`, so an
accepted job trains nothing (each case's call runs the app's lifespan, which leaves what it
was given alone). `pytest -s` prints the cases each configuration ran."""

from __future__ import annotations

import contextlib
import sys
from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import schemathesis
from fastapi import FastAPI
from hypothesis import HealthCheck, settings
from pydantic import SecretStr
from replica_cluster import pg_schema_url, seed_zoo

from model_store.sql import SqlModelStore
from services.app import create_app
from services.engine import InferenceEngine
from services.settings import Settings
from services.warmup import warm_up
from trainer.jobs import JobRunner, JobSpec, JobTable

CASES = 20  # per operation and configuration
ADMIN_TOKEN = "fuzz-admin-token-0123456789"
AUTH = {"Authorization": f"Bearer {ADMIN_TOKEN}"}
BACKENDS = ["sqlite", pytest.param("postgres", marks=pytest.mark.postgres)]
RAN: Counter[str] = Counter()  # cases run, per configuration


def _app(require_read_token: bool) -> FastAPI:
    config = Settings(
        admin_token=SecretStr(ADMIN_TOKEN),
        require_read_token=require_read_token,
        grpc_enabled=False,
        max_sessions=64,
    )
    return create_app(config)


def _schema(app: FastAPI) -> Any:
    """The app's OpenAPI, read without a request: a request would run the app's lifespan, which
    with nothing installed yet would open a store of its own."""
    schema = schemathesis.openapi.from_dict(app.openapi())
    schema.app = app  # each case is an ASGI call to it
    return schema


OPEN_APP, TOKEN_APP = _app(False), _app(True)
open_schema, token_schema = _schema(OPEN_APP), _schema(TOKEN_APP)


def no_training(spec: JobSpec, run_dir: Path) -> list[str]:
    return ["true"]


@contextlib.contextmanager
def installed(app: FastAPI, backend: str, directory: Path) -> Iterator[JobRunner]:
    """The app serving a freshly seeded store of `backend`; yields its (harmless) job runner."""
    with contextlib.ExitStack() as stack:
        url = (
            stack.enter_context(pg_schema_url())
            if backend == "postgres"
            else f"sqlite:///{directory / 'models.db'}"
        )
        seed_zoo(url)
        store = stack.enter_context(SqlModelStore(url))
        engine = InferenceEngine(store)
        warm_up(engine)
        table = JobTable(url)
        runner = JobRunner(table, store_url=url, poll_s=0.05, command=no_training)
        stack.callback(table.close)
        stack.callback(runner.stop)
        app.state.settings = app.state.settings.model_copy(update={"data_dir": directory})
        app.state.store, app.state.engine, app.state.jobs = store, engine, (table, runner)
        app.state.sessions = None  # made on first use over this engine
        try:
            yield runner
        finally:
            app.state.store = app.state.engine = app.state.jobs = app.state.sessions = None


@pytest.fixture(scope="module", params=BACKENDS)
def open_backend(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory):
    name = f"{request.param}, reads open, anonymous requests"
    with installed(OPEN_APP, request.param, tmp_path_factory.mktemp("fuzz_open")) as runner:
        yield name, runner
    print(f"\nfuzzed {name}: {RAN[name]} cases", file=sys.stderr)


@pytest.fixture(scope="module", params=BACKENDS)
def token_backend(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory):
    name = f"{request.param}, read token required, admin token sent"
    with installed(TOKEN_APP, request.param, tmp_path_factory.mktemp("fuzz_token")) as runner:
        yield name, runner
    print(f"\nfuzzed {name}: {RAN[name]} cases", file=sys.stderr)


def _check(case: Any, app: FastAPI, backend: tuple[str, JobRunner], headers: dict[str, str]):
    name, runner = backend
    response = case.call(headers=headers)
    RAN[name] += 1
    assert app.state.jobs[1] is runner  # the harmless runner is the one that runs jobs
    assert response.status_code < 500, f"{case.method} {case.formatted_path}: {response.text}"


@open_schema.parametrize()
@settings(max_examples=CASES, deadline=None, suppress_health_check=list(HealthCheck))
def test_anonymous_requests_never_get_a_server_error(case: Any, open_backend: Any) -> None:
    _check(case, OPEN_APP, open_backend, {})


@token_schema.parametrize()
@settings(max_examples=CASES, deadline=None, suppress_health_check=list(HealthCheck))
def test_admin_requests_never_get_a_server_error(case: Any, token_backend: Any) -> None:
    _check(case, TOKEN_APP, token_backend, AUTH)
