"""Fixtures of the model store tests: one store URL per backend.

Test modules import them (`from store_fixtures import store, store_url, pg_url`) rather than
getting them from a conftest.py, whose basename would collide with other test folders' under mypy.

`store_url` is parametrised over SQLite (a file in tmp_path) and PostgreSQL (the server at
`COEXIST_TEST_PG_URL`, default `postgresql://postgres@127.0.0.1:5432/test`). Each PostgreSQL test
gets a fresh schema with a random name, selected through the connection's `search_path`, and
dropped afterwards, so pytest-xdist workers and reruns never see each other's tables.
The PostgreSQL variants skip when no server answers, unless `COEXIST_REQUIRE_POSTGRES` is set,
in which case they fail.
"""

from __future__ import annotations

import os
import uuid
from collections.abc import Iterator
from functools import lru_cache

import psycopg
import pytest
from sqlalchemy.engine import make_url

from model_store.sql import SqlModelStore

PG_URL = os.environ.get("COEXIST_TEST_PG_URL", "postgresql://postgres@127.0.0.1:5432/test")


@lru_cache(maxsize=1)
def _pg_problem() -> str | None:
    """None when the server answers, else why not."""
    try:
        with psycopg.connect(PG_URL, connect_timeout=3) as conn:
            conn.execute("SELECT 1")
    except psycopg.Error as exc:
        return str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    return None


def require_postgres() -> None:
    problem = _pg_problem()
    if problem is None:
        return
    message = f"PostgreSQL not reachable at {PG_URL}: {problem}"
    if os.environ.get("COEXIST_REQUIRE_POSTGRES"):
        pytest.fail(f"{message} (COEXIST_REQUIRE_POSTGRES is set)")
    pytest.skip(f"{message}; set COEXIST_REQUIRE_POSTGRES=1 to make this a failure")


@pytest.fixture
def pg_url() -> Iterator[str]:
    """A PostgreSQL store URL whose tables live in a fresh schema of their own."""
    require_postgres()
    schema = f"coexist_test_{uuid.uuid4().hex[:12]}"
    with psycopg.connect(PG_URL, autocommit=True) as conn:
        conn.execute(f'CREATE SCHEMA "{schema}"')
    url = make_url(PG_URL).update_query_dict({"options": f"-csearch_path={schema}"})
    try:
        yield url.render_as_string(hide_password=False)
    finally:
        with psycopg.connect(PG_URL, autocommit=True) as conn:
            conn.execute(f'DROP SCHEMA IF EXISTS "{schema}" CASCADE')


@pytest.fixture(params=["sqlite", pytest.param("postgres", marks=pytest.mark.postgres)])
def store_url(request: pytest.FixtureRequest, tmp_path) -> str:
    if request.param == "sqlite":
        return f"sqlite:///{tmp_path / 'store' / 'models.db'}"
    return request.getfixturevalue("pg_url")


@pytest.fixture
def store(store_url: str) -> Iterator[SqlModelStore]:
    with SqlModelStore(store_url) as opened:
        yield opened
