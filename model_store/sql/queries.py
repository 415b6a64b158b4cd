"""Row look-ups and row writes shared by the store's methods; every function takes the session
of the current transaction. Missing rows raise `NotFound` naming the field."""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session, selectinload

from model_store.errors import NotFound
from model_store.sql.convert import now
from model_store.sql.orm import AliasRow, EventRow, ModelRow, SchemaMetaRow, VersionRow

_META_KEY = "coexist_meta"


def lock_change_counter(session: Session) -> SchemaMetaRow:
    """Lock the one `schema_meta` row for the rest of the transaction (first thing every write
    does). It serialises writers, so event ids are handed out and committed in the same order:
    a reader that has seen event n has seen every event before it, and `change_token` never
    misses a change."""
    meta = session.execute(
        select(SchemaMetaRow).where(SchemaMetaRow.id == 1).with_for_update()
    ).scalar_one()
    session.info[_META_KEY] = meta
    return meta


def emit(
    session: Session, kind: str, name: str, *, version: int | None = None, alias: str | None = None
) -> None:
    """Append an event; its id is the next value of the (locked) change counter."""
    meta: SchemaMetaRow = session.info[_META_KEY]
    meta.change_seq += 1
    session.add(
        EventRow(id=meta.change_seq, kind=kind, name=name, version=version, alias=alias, at=now())
    )


def find_model(session: Session, name: str) -> ModelRow:
    if "\x00" in name:  # no model has one (names are validated), and PostgreSQL cannot compare it
        raise NotFound(f"model {name!r} not found", field="name")
    row = session.execute(
        select(ModelRow)
        .where(ModelRow.name == name)
        .options(
            selectinload(ModelRow.goals),
            selectinload(ModelRow.tags),
            selectinload(ModelRow.aliases),
        )
    ).scalar_one_or_none()
    if row is None:
        raise NotFound(f"model {name!r} not found", field="name")
    return row


def find_version(session: Session, model: ModelRow, version: int) -> VersionRow:
    row = session.execute(
        select(VersionRow).where(VersionRow.model_id == model.id, VersionRow.version == version)
    ).scalar_one_or_none()
    if row is None:
        raise NotFound(f"model {model.name!r} has no version {version}", field="version")
    return row


def aliases_of(model: ModelRow, version: VersionRow) -> list[AliasRow]:
    return [a for a in model.aliases if a.version_id == version.id]


def point_alias(session: Session, model: ModelRow, alias: str, version: VersionRow) -> bool:
    """Create or move `alias` to `version`; False when it already pointed there (no change)."""
    for row in model.aliases:
        if row.alias == alias:
            if row.version_id == version.id:
                return False
            row.version = version
            break
    else:
        model.aliases.append(AliasRow(alias=alias, version=version))
    emit(session, "alias_set", model.name, version=version.version, alias=alias)
    return True


def drop_alias(session: Session, model: ModelRow, alias: AliasRow) -> None:
    version = alias.version.version
    model.aliases.remove(alias)  # delete-orphan: the row goes at flush
    emit(session, "alias_deleted", model.name, version=version, alias=alias.alias)
