"""Initial schema of the model store.

Revision ID: 0001_initial
Revises:
Create Date: 2025-01-01
"""

from __future__ import annotations

import uuid
from datetime import UTC, datetime

import sqlalchemy as sa
from alembic import op

revision = "0001_initial"
down_revision = None
branch_labels = None
depends_on = None

_TS = sa.DateTime(timezone=True)


def upgrade() -> None:
    op.create_table(
        "schema_meta",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("store_id", sa.String(32), nullable=False),
        sa.Column("change_seq", sa.BigInteger, nullable=False),
        sa.Column("created_at", _TS, nullable=False),
    )
    op.create_table(
        "registered_models",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("name", sa.String(200), nullable=False, unique=True),
        sa.Column("env", sa.String(64), nullable=False, index=True),
        sa.Column("kind", sa.String(16), nullable=False, index=True),
        sa.Column("obs_dim", sa.Integer, nullable=False),
        sa.Column("n_actions", sa.Integer, nullable=False),
        sa.Column("description", sa.Text, nullable=False),
        sa.Column("last_version", sa.Integer, nullable=False),
        sa.Column("created_at", _TS, nullable=False),
        sa.Column("updated_at", _TS, nullable=False),
    )
    op.create_table(
        "model_goals",
        sa.Column("model_id", sa.Integer, _model_fk(), primary_key=True),
        sa.Column("position", sa.Integer, primary_key=True),
        sa.Column("goal", sa.String(64), nullable=False, index=True),
    )
    op.create_table(
        "model_tags",
        sa.Column("model_id", sa.Integer, _model_fk(), primary_key=True),
        sa.Column("key", sa.String(64), primary_key=True),
        sa.Column("value", sa.Text, nullable=False),
    )
    op.create_table(
        "model_versions",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("model_id", sa.Integer, _model_fk(), nullable=False, index=True),
        sa.Column("version", sa.Integer, nullable=False),
        sa.Column("spec", sa.JSON, nullable=False),
        sa.Column("sha256", sa.String(64), nullable=False),
        sa.Column("size_bytes", sa.BigInteger, nullable=False),
        sa.Column("status", sa.String(16), nullable=False),
        sa.Column("lineage", sa.JSON, nullable=False),
        sa.Column("created_at", _TS, nullable=False),
        sa.Column("weights", sa.LargeBinary, nullable=False),
        sa.UniqueConstraint("model_id", "version", name="uq_model_versions_number"),
    )
    op.create_table(
        "model_aliases",
        sa.Column("model_id", sa.Integer, _model_fk(), primary_key=True),
        sa.Column("alias", sa.String(64), primary_key=True),
        sa.Column(
            "version_id", sa.Integer, sa.ForeignKey("model_versions.id"), nullable=False, index=True
        ),
    )
    op.create_table(
        "events",
        sa.Column("id", sa.BigInteger, primary_key=True, autoincrement=False),
        sa.Column("kind", sa.String(32), nullable=False),
        sa.Column("name", sa.String(200), nullable=False, index=True),
        sa.Column("version", sa.Integer, nullable=True),
        sa.Column("alias", sa.String(64), nullable=True),
        sa.Column("at", _TS, nullable=False),
    )
    # The one schema_meta row: the store's identity (part of change tokens) and its event counter.
    meta = sa.table(
        "schema_meta",
        sa.column("id", sa.Integer),
        sa.column("store_id", sa.String),
        sa.column("change_seq", sa.BigInteger),
        sa.column("created_at", _TS),
    )
    op.bulk_insert(
        meta, [{"id": 1, "store_id": uuid.uuid4().hex, "change_seq": 0, "created_at": _now()}]
    )


def _model_fk() -> sa.ForeignKey:
    return sa.ForeignKey("registered_models.id", ondelete="CASCADE")


def _now() -> datetime:
    return datetime.now(UTC)


def downgrade() -> None:
    for table in (
        "events",
        "model_aliases",
        "model_versions",
        "model_tags",
        "model_goals",
        "registered_models",
        "schema_meta",
    ):
        op.drop_table(table)
