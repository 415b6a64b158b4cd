"""ORM rows of the SQL store (SQLAlchemy 2.0 typed mappings). They never leave `model_store.sql`.

| table             | one row per         | notes                                           |
|-------------------|---------------------|-------------------------------------------------|
| schema_meta       | store (one, id = 1) | store_id (identity), change_seq (last event)    |
| registered_models | model name          | last_version: counter for gapless numbering     |
| model_goals       | (model, position)   | the goal(s), filterable                         |
| model_tags        | (model, key)        | free key/value tags, filterable                 |
| model_versions    | (model, version)    | spec + lineage JSON, sha256, weights (deferred),|
|                   |                     | the upload's idempotency key (unique per model) |
| model_aliases     | (model, alias)      | -> a version row of the same model              |
| events            | change              | id = change_seq at commit; no foreign keys      |
| training_jobs     | job of the job API  | owned by `trainer.jobs` (migration 0002)        |

The weights live in the database (`LargeBinary`: BLOB / BYTEA) so that every replica that reaches
the database can load them; the column is deferred so listing versions never reads them.
The schema is created by the Alembic migrations in `model_store/migrations/`, not by
`metadata.create_all`; keep both in step.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

from sqlalchemy import (
    JSON,
    BigInteger,
    DateTime,
    ForeignKey,
    Index,
    Integer,
    LargeBinary,
    String,
    Text,
    UniqueConstraint,
)
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column, relationship


class Base(DeclarativeBase):
    pass


class SchemaMetaRow(Base):
    __tablename__ = "schema_meta"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    store_id: Mapped[str] = mapped_column(String(32))
    change_seq: Mapped[int] = mapped_column(BigInteger)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True))


class ModelRow(Base):
    __tablename__ = "registered_models"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    name: Mapped[str] = mapped_column(String(200), unique=True)
    env: Mapped[str] = mapped_column(String(64), index=True)
    kind: Mapped[str] = mapped_column(String(16), index=True)
    obs_dim: Mapped[int] = mapped_column(Integer)
    n_actions: Mapped[int] = mapped_column(Integer)
    description: Mapped[str] = mapped_column(Text)
    last_version: Mapped[int] = mapped_column(Integer)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True))
    updated_at: Mapped[datetime] = mapped_column(DateTime(timezone=True))

    goals: Mapped[list[GoalRow]] = relationship(
        order_by="GoalRow.position", cascade="all, delete-orphan", passive_deletes=True
    )
    tags: Mapped[list[TagRow]] = relationship(cascade="all, delete-orphan", passive_deletes=True)
    aliases: Mapped[list[AliasRow]] = relationship(
        cascade="all, delete-orphan", passive_deletes=True
    )


class GoalRow(Base):
    __tablename__ = "model_goals"

    model_id: Mapped[int] = mapped_column(
        ForeignKey("registered_models.id", ondelete="CASCADE"), primary_key=True
    )
    position: Mapped[int] = mapped_column(Integer, primary_key=True)
    goal: Mapped[str] = mapped_column(String(64), index=True)


class TagRow(Base):
    __tablename__ = "model_tags"

    model_id: Mapped[int] = mapped_column(
        ForeignKey("registered_models.id", ondelete="CASCADE"), primary_key=True
    )
    key: Mapped[str] = mapped_column(String(64), primary_key=True)
    value: Mapped[str] = mapped_column(Text)


class VersionRow(Base):
    __tablename__ = "model_versions"
    __table_args__ = (
        UniqueConstraint("model_id", "version", name="uq_model_versions_number"),
        Index(
            "uq_model_versions_idempotency_key", "model_id", "idempotency_key", unique=True
        ),  # migration 0003
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    model_id: Mapped[int] = mapped_column(
        ForeignKey("registered_models.id", ondelete="CASCADE"), index=True
    )
    version: Mapped[int] = mapped_column(Integer)
    spec: Mapped[dict[str, Any]] = mapped_column(JSON)
    sha256: Mapped[str] = mapped_column(String(64))
    size_bytes: Mapped[int] = mapped_column(BigInteger)
    status: Mapped[str] = mapped_column(String(16))
    lineage: Mapped[dict[str, Any]] = mapped_column(JSON)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True))
    weights: Mapped[bytes] = mapped_column(LargeBinary, deferred=True)
    idempotency_key: Mapped[str | None] = mapped_column(String(128), nullable=True)


class AliasRow(Base):
    __tablename__ = "model_aliases"

    model_id: Mapped[int] = mapped_column(
        ForeignKey("registered_models.id", ondelete="CASCADE"), primary_key=True
    )
    alias: Mapped[str] = mapped_column(String(64), primary_key=True)
    version_id: Mapped[int] = mapped_column(ForeignKey("model_versions.id"), index=True)

    version: Mapped[VersionRow] = relationship(lazy="joined")


class EventRow(Base):
    __tablename__ = "events"

    id: Mapped[int] = mapped_column(BigInteger, primary_key=True, autoincrement=False)
    kind: Mapped[str] = mapped_column(String(32))
    name: Mapped[str] = mapped_column(String(200), index=True)
    version: Mapped[int | None] = mapped_column(Integer, nullable=True)
    alias: Mapped[str | None] = mapped_column(String(64), nullable=True)
    at: Mapped[datetime] = mapped_column(DateTime(timezone=True))


class TrainingJobRow(Base):
    """A training job of `trainer.jobs` (status: queued|running|succeeded|failed|gate_failed|
    interrupted|cancelling|cancelled)."""

    __tablename__ = "training_jobs"

    id: Mapped[str] = mapped_column(String(32), primary_key=True)
    kind: Mapped[str] = mapped_column(String(16))
    args: Mapped[dict[str, Any]] = mapped_column(JSON)
    status: Mapped[str] = mapped_column(String(16), index=True)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), index=True)
    started_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), nullable=True)
    finished_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), nullable=True)
    heartbeat_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), nullable=True)
    exit_code: Mapped[int | None] = mapped_column(Integer, nullable=True)
    attempts: Mapped[int] = mapped_column(Integer)
    run_dir: Mapped[str] = mapped_column(Text)
    log_tail: Mapped[str] = mapped_column(Text)
