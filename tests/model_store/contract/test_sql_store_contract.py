"""The exported store contract (`model_store.contract`) on coexist's SQL store, on SQLite and
on PostgreSQL (`store_fixtures.store`)."""

from __future__ import annotations

from store_fixtures import pg_url, store, store_url  # noqa: F401

from model_store.contract import StoreContract


class TestSqlStore(StoreContract):
    """`store` comes from store_fixtures: SQLite in tmp_path, PostgreSQL in a fresh schema."""
