"""Alembic migrations of the model store (run programmatically by `model_store.sql.migrate`)."""
