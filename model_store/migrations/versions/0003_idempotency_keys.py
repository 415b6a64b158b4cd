"""Idempotent uploads: a version may carry the key of the request that registered it.

Revision ID: 0003_idempotency_keys
Revises: 0002_training_jobs
Create Date: 2025-01-03
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0003_idempotency_keys"
down_revision = "0002_training_jobs"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.add_column("model_versions", sa.Column("idempotency_key", sa.String(128), nullable=True))
    # an index, not a table constraint: SQLite adds one without rebuilding the table; NULLs
    # (versions registered without a key) never collide, on either backend
    op.create_index(
        "uq_model_versions_idempotency_key",
        "model_versions",
        ["model_id", "idempotency_key"],
        unique=True,
    )


def downgrade() -> None:
    op.drop_index("uq_model_versions_idempotency_key", table_name="model_versions")
    op.drop_column("model_versions", "idempotency_key")
