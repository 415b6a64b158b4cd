"""The SQL implementation of the model store (SQLite or PostgreSQL)."""

from model_store.sql.sql_store import DEFAULT_MAX_ARTIFACT_BYTES, SqlModelStore

__all__ = ["DEFAULT_MAX_ARTIFACT_BYTES", "SqlModelStore"]
