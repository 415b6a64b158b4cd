"""Alembic environment of the model store.

Run by `model_store.sql.migrate.upgrade` with an open connection in
`config.attributes["connection"]` (the store's own engine, so SQLite pragmas and PostgreSQL
search paths apply). From the command line (`alembic -c model_store/migrations/alembic.ini
upgrade head`) it builds an engine from `COEXIST_STORE_URL` or the `sqlalchemy.url` option.
"""

from __future__ import annotations

import os

from alembic import context

from model_store.sql.engine import create_store_engine
from model_store.sql.orm import Base

config = context.config


def _run(connection: object) -> None:
    context.configure(connection=connection, target_metadata=Base.metadata)  # type: ignore[arg-type]
    with context.begin_transaction():
        context.run_migrations()


connection = config.attributes.get("connection")
if connection is not None:
    _run(connection)
else:
    url = os.environ.get("COEXIST_STORE_URL") or config.get_main_option("sqlalchemy.url")
    if not url:
        raise SystemExit("set COEXIST_STORE_URL or sqlalchemy.url in alembic.ini")
    engine = create_store_engine(url)
    with engine.connect() as conn:
        _run(conn)
        conn.commit()
    engine.dispose()
