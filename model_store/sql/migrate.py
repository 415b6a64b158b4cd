"""Schema management: upgrade an empty or older database, refuse a newer one.

Alembic runs in code (a `Config` built here, no alembic.ini), on a connection of the store's own
engine, inside one transaction: on PostgreSQL DDL is transactional and an advisory lock makes
concurrent first uses wait for each other; on SQLite the transaction is `BEGIN IMMEDIATE`, which
does the same. The revision is re-read under the lock, so the second process finds the work done.
"""

from __future__ import annotations

from pathlib import Path

from alembic import command
from alembic.config import Config
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory
from alembic.util.exc import CommandError
from sqlalchemy import Connection, Engine, text

from model_store.errors import ModelStoreError, SchemaTooNew
from model_store.sql.engine import BEGIN_MODE_OPTION

MIGRATIONS_DIR = Path(__file__).resolve().parent.parent / "migrations"
_PG_MIGRATION_LOCK = 0x636F6578  # arbitrary advisory-lock key ("coex")


def alembic_config() -> Config:
    cfg = Config()
    cfg.set_main_option("script_location", str(MIGRATIONS_DIR))
    return cfg


def head_revision() -> str:
    head = ScriptDirectory.from_config(alembic_config()).get_current_head()
    assert head is not None, "the model store ships at least one migration"
    return head


def current_revision(conn: Connection) -> str | None:
    return MigrationContext.configure(conn).get_current_revision()


def ensure_schema(engine: Engine, *, auto_migrate: bool = True) -> str:
    """Bring the database to this code's head revision (or check it is there); return it."""
    head = head_revision()
    with engine.connect() as conn:
        conn = conn.execution_options(**{BEGIN_MODE_OPTION: "IMMEDIATE"})
        with conn.begin():
            if conn.dialect.name == "postgresql":
                conn.execute(
                    text("SELECT pg_advisory_xact_lock(:key)"), {"key": _PG_MIGRATION_LOCK}
                )
            current = current_revision(conn)
            if current == head:
                return head
            _refuse_unknown(current, head)
            if not auto_migrate:
                raise ModelStoreError(
                    f"database schema {current or 'empty'} is older than this coexist "
                    f"(head {head}): run `coexist models migrate`"
                )
            cfg = alembic_config()
            cfg.attributes["connection"] = conn
            command.upgrade(cfg, "head")
    return head


def _refuse_unknown(current: str | None, head: str) -> None:
    if current is None:
        return
    script = ScriptDirectory.from_config(alembic_config())
    try:
        script.get_revision(current)
    except CommandError:
        raise SchemaTooNew(
            f"database schema {current} is newer than this coexist (head {head}): upgrade coexist"
        ) from None
