"""`SqlModelStore`: the model store on SQLite or PostgreSQL (see `model_store.store` for the
semantics, `model_store.sql.engine` for the per-backend set-up).

Every public method is one managed session: commit on success, rollback on any error, ORM rows
converted to entities before the session closes. Database errors become domain errors here:
`IntegrityError` -> `AlreadyExists`, any other DBAPI error (unreachable server, a vanished file,
a dropped schema) -> `StoreUnavailable`. Writers take the change-counter lock first
(`queries.lock_change_counter`), so version numbers and event ids are allocated one writer at a
time; readers never wait for it.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from sqlalchemy import URL, delete, exists, or_, select
from sqlalchemy.exc import DBAPIError, IntegrityError
from sqlalchemy.orm import Session, selectinload, sessionmaker

from model_store.checks import check_kind, check_new_model
from model_store.entities import Event, Page, RegisteredModel
from model_store.errors import AlreadyExists, Conflict, InvalidArgument, StoreUnavailable, brief
from model_store.naming import (
    path_prefixes,
    validate_tags,
    validate_text,
)
from model_store.sql import queries as q
from model_store.sql.convert import (
    decode_page_token,
    encode_page_token,
    event_entity,
    model_entity,
    now,
)
from model_store.sql.engine import (
    BEGIN_MODE_OPTION,
    create_store_engine,
    normalise_url,
    without_password,
)
from model_store.sql.migrate import ensure_schema
from model_store.sql.orm import EventRow, GoalRow, ModelRow, SchemaMetaRow, TagRow, VersionRow
from model_store.sql.versions import VersionOps
from model_store.store import ModelStore

DEFAULT_MAX_ARTIFACT_BYTES = 64 * 1024 * 1024
MAX_PAGE_SIZE = 1000
MAX_EVENT_ID = 2**63 - 1  # events.id is a BigInteger


class SqlModelStore(VersionOps, ModelStore):
    """Model store backed by a SQL database reached at `url` (SQLite file or PostgreSQL)."""

    def __init__(
        self,
        url: str | URL,
        *,
        max_artifact_bytes: int = DEFAULT_MAX_ARTIFACT_BYTES,
        auto_migrate: bool = True,
        create: bool = True,
    ) -> None:
        """`create=False`: a SQLite file that does not exist is an `InvalidArgument` naming the
        path, not a new empty store (`open_store`, the commands' entry, asks for that)."""
        if max_artifact_bytes < 1:
            raise InvalidArgument(
                "max_artifact_bytes: must be positive", field="max_artifact_bytes"
            )
        self.url = normalise_url(url)
        self.max_artifact_bytes = max_artifact_bytes
        self._engine = create_store_engine(self.url, create=create)
        try:
            self.schema_revision = ensure_schema(self._engine, auto_migrate=auto_migrate)
        except DBAPIError as exc:
            self._engine.dispose()
            raise StoreUnavailable(f"{self._where()}: {_first_line(exc)}") from exc
        except BaseException:
            self._engine.dispose()
            raise
        self._readers = sessionmaker(self._engine, expire_on_commit=False)
        writer_engine = self._engine.execution_options(**{BEGIN_MODE_OPTION: "IMMEDIATE"})
        self._writers = sessionmaker(writer_engine, expire_on_commit=False)

    def __repr__(self) -> str:
        return f"SqlModelStore({self.url.render_as_string(hide_password=True)!r})"

    def close(self) -> None:
        self._engine.dispose()

    def reopen_url(self) -> str:
        """`ModelStore.reopen_url`: this URL without its password (`reopen_password` hands that
        over apart), a SQLite path made absolute (the other process may run in another
        directory)."""
        url = self.url
        if url.get_backend_name() == "sqlite" and url.database:
            url = url.set(database=str(Path(url.database).absolute()))
        rendered: str = without_password(url).render_as_string()
        return rendered

    def reopen_password(self) -> str | None:
        """`ModelStore.reopen_password`: the password of this URL, if it has one."""
        return self.url.password

    def _where(self) -> str:
        return f"model store database {self.url.render_as_string(hide_password=True)} unavailable"

    @contextmanager
    def _session(self, *, write: bool = False) -> Iterator[Session]:
        """One transaction; database errors become domain errors (see module docstring)."""
        maker = self._writers if write else self._readers
        try:
            with maker() as session, session.begin():
                if write:
                    q.lock_change_counter(session)
                yield session
        except IntegrityError as exc:
            raise AlreadyExists(f"conflicting concurrent write: {_first_line(exc)}") from exc
        except DBAPIError as exc:
            raise StoreUnavailable(f"{self._where()}: {_first_line(exc)}") from exc

    # --- registered models -----------------------------------------------------------------
    def create_model(
        self,
        name: str,
        *,
        env: str,
        kind: str,
        goals: Sequence[str],
        obs_dim: int,
        n_actions: int,
        description: str = "",
        tags: Mapping[str, str] | None = None,
        exist_ok: bool = False,
    ) -> RegisteredModel:
        goal_list, tag_map = check_new_model(
            name,
            env=env,
            kind=kind,
            goals=goals,
            obs_dim=obs_dim,
            n_actions=n_actions,
            description=description,
            tags=tags,
        )
        with self._session(write=True) as session:
            existing = session.execute(select(ModelRow.id).where(ModelRow.name == name)).first()
            if existing is None:
                _refuse_nested_name(session, name)
            else:
                model = model_entity(q.find_model(session, name))
                same = (model.env, model.kind, list(model.goals), model.obs_dim, model.n_actions)
                if exist_ok and same == (env, kind, goal_list, obs_dim, n_actions):
                    return model
                raise AlreadyExists(f"model {name!r} already exists", field="name")
            stamp = now()
            row = ModelRow(
                name=name,
                env=env,
                kind=kind,
                obs_dim=obs_dim,
                n_actions=n_actions,
                description=description,
                last_version=0,
                created_at=stamp,
                updated_at=stamp,
            )
            row.goals = [GoalRow(position=i, goal=g) for i, g in enumerate(goal_list)]
            row.tags = [TagRow(key=k, value=v) for k, v in sorted(tag_map.items())]
            row.aliases = []
            session.add(row)
            session.flush()
            q.emit(session, "model_created", name)
            return model_entity(row)

    def get_model(self, name: str) -> RegisteredModel:
        with self._session() as session:
            return model_entity(q.find_model(session, name))

    def list_models(
        self,
        *,
        env: str | None = None,
        kind: str | None = None,
        goal: str | None = None,
        tag: str | None = None,
        page_size: int = 50,
        page_token: str | None = None,
    ) -> Page[RegisteredModel]:
        if not isinstance(page_size, int) or not 1 <= page_size <= MAX_PAGE_SIZE:
            raise InvalidArgument(
                f"page_size: expected 1..{MAX_PAGE_SIZE}, got {brief(page_size)}", field="page_size"
            )
        for key, value in (("env", env), ("goal", goal), ("tag", tag)):
            if value is not None:
                validate_text(value, key)
        stmt = select(ModelRow).order_by(ModelRow.name).limit(page_size + 1)
        if env is not None:
            stmt = stmt.where(ModelRow.env == env)
        if kind is not None:
            stmt = stmt.where(ModelRow.kind == check_kind(kind))
        if goal is not None:
            stmt = stmt.where(exists().where(GoalRow.model_id == ModelRow.id, GoalRow.goal == goal))
        if tag is not None:
            key, has_value, value = tag.partition("=")
            cond = [TagRow.model_id == ModelRow.id, TagRow.key == key]
            if has_value:
                cond.append(TagRow.value == value)
            stmt = stmt.where(exists().where(*cond))
        if page_token:
            stmt = stmt.where(ModelRow.name > decode_page_token(page_token))
        stmt = stmt.options(
            selectinload(ModelRow.goals),
            selectinload(ModelRow.tags),
            selectinload(ModelRow.aliases),
        )
        with self._session() as session:
            rows = list(session.execute(stmt).scalars())
            items = tuple(model_entity(r) for r in rows[:page_size])
        token = encode_page_token(items[-1].name) if len(rows) > page_size else None
        return Page(items=items, next_page_token=token)

    def update_model(
        self,
        name: str,
        *,
        description: str | None = None,
        tags: Mapping[str, str] | None = None,
    ) -> RegisteredModel:
        if description is not None:
            validate_text(description, "description")
        tag_map = validate_tags(tags) if tags is not None else None
        with self._session(write=True) as session:
            row = q.find_model(session, name)
            if description is not None:
                row.description = description
            if tag_map is not None:
                row.tags = [TagRow(key=k, value=v) for k, v in sorted(tag_map.items())]
            row.updated_at = now()
            q.emit(session, "model_updated", name)
            session.flush()
            return model_entity(row)

    def delete_model(self, name: str) -> None:
        with self._session(write=True) as session:
            row = q.find_model(session, name)
            for alias in list(row.aliases):
                row.aliases.remove(alias)
            session.flush()
            # A bulk delete: the versions are never loaded (their weights may be large).
            session.execute(delete(VersionRow).where(VersionRow.model_id == row.id))
            session.delete(row)
            q.emit(session, "model_deleted", name)

    # --- change feed -----------------------------------------------------------------------
    def change_token(self) -> str:
        with self._session() as session:
            meta = session.execute(select(SchemaMetaRow).where(SchemaMetaRow.id == 1)).scalar_one()
            return f"{meta.change_seq}-{meta.store_id[:12]}"

    def events(self, since_id: int = 0, limit: int = 100) -> list[Event]:
        if not isinstance(since_id, int) or not 0 <= since_id <= MAX_EVENT_ID:
            raise InvalidArgument(
                f"since_id: expected an integer in 0..{MAX_EVENT_ID}, got {brief(since_id)}",
                field="since_id",
            )
        if not isinstance(limit, int) or not 1 <= limit <= MAX_PAGE_SIZE:
            raise InvalidArgument(
                f"limit: expected 1..{MAX_PAGE_SIZE}, got {brief(limit)}", field="limit"
            )
        stmt = select(EventRow).where(EventRow.id > since_id).order_by(EventRow.id).limit(limit)
        with self._session() as session:
            return [event_entity(r) for r in session.execute(stmt).scalars()]


def _refuse_nested_name(session: Session, name: str) -> None:
    """No model name may be a path prefix of another: it keeps `name/3` refs unambiguous."""
    nested = session.execute(
        select(ModelRow.name)
        .where(
            or_(
                ModelRow.name.in_(path_prefixes(name)),
                ModelRow.name.startswith(name + "/", autoescape=True),
            )
        )
        .limit(1)
    ).scalar_one_or_none()
    if nested is not None:
        raise Conflict(
            f"name: {name!r} and the existing model {nested!r} would make refs ambiguous "
            "(one name is a path prefix of the other)",
            field="name",
        )


def _first_line(exc: BaseException) -> str:
    orig: Any = getattr(exc, "orig", None) or exc
    return (str(orig).strip().splitlines() or [type(orig).__name__])[0]
