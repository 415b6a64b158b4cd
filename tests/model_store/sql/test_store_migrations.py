"""The Alembic migrations create exactly the schema the ORM maps (no drift between them)."""

# ruff: noqa: F811  (the fixtures imported from store_fixtures are re-bound as test arguments)

from __future__ import annotations

from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from sqlalchemy import create_engine
from store_fixtures import pg_url, store_url  # noqa: F401

from model_store.sql import SqlModelStore
from model_store.sql.engine import normalise_url
from model_store.sql.migrate import head_revision
from model_store.sql.orm import Base


def test_migrated_schema_matches_the_orm(store_url: str) -> None:
    with SqlModelStore(store_url) as store:
        assert store.schema_revision == head_revision()
    engine = create_engine(normalise_url(store_url))
    with engine.connect() as conn:
        diff = compare_metadata(MigrationContext.configure(conn), Base.metadata)
    engine.dispose()
    assert diff == []
