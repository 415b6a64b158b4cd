"""Version and alias operations of `SqlModelStore` (a mixin: the class is split only to keep
each file readable; `sql_store.py` supplies `_session` and `max_artifact_bytes`)."""

from __future__ import annotations

import hmac
from collections.abc import Sequence
from contextlib import AbstractContextManager

from sqlalchemy import select
from sqlalchemy.orm import Session

from model_store.artifacts import check_artifact, sha256_hex
from model_store.checks import check_registration
from model_store.entities import Lineage, ModelVersion
from model_store.errors import (
    AlreadyExists,
    ChecksumMismatch,
    Conflict,
    InvalidArgument,
    InvalidArtifact,
    NotFound,
    brief,
)
from model_store.naming import (
    MAX_VERSION,
    parse_ref,
    ref_candidates,
    validate_alias,
)
from model_store.sql import queries as q
from model_store.sql.convert import now, version_entity
from model_store.sql.orm import AliasRow, ModelRow, VersionRow

REGISTER_ATTEMPTS = 3  # retries of a version allocation that lost a race (belt and braces)


def _check_version_number(version: int) -> int:
    if not isinstance(version, int) or isinstance(version, bool) or not 1 <= version <= MAX_VERSION:
        raise InvalidArgument(
            f"version: expected an integer in 1..{MAX_VERSION}, got {brief(version)}",
            field="version",
        )
    return version


def _registered_with(session: Session, model_id: int, key: str) -> VersionRow | None:
    query = select(VersionRow).where(
        VersionRow.model_id == model_id, VersionRow.idempotency_key == key
    )
    row: VersionRow | None = session.execute(query).scalar_one_or_none()
    return row


def _check_same(earlier: VersionRow, sha256: str, spec: dict, key: str) -> None:
    """A key names one upload: the same weights and spec, or a `Conflict`."""
    if earlier.sha256 != sha256 or earlier.spec != spec:
        raise Conflict(
            f"idempotency_key: {key!r} registered version {earlier.version} (sha256 "
            f"{earlier.sha256[:12]}…) from other weights or another spec: a key names one upload",
            field="idempotency_key",
        )


class VersionOps:
    max_artifact_bytes: int

    def _session(self, *, write: bool = False) -> AbstractContextManager[Session]:
        raise NotImplementedError

    def register_version(
        self,
        name: str,
        *,
        spec: dict,
        weights: bytes,
        lineage: Lineage,
        aliases: Sequence[str] = ("latest",),
        idempotency_key: str | None = None,
    ) -> ModelVersion:
        alias_list = check_registration(aliases, idempotency_key, lineage)
        with self._session() as session:
            model = q.find_model(session, name)
            sizes = (model.obs_dim, model.n_actions)
        # Parsing and hashing happen outside the write transaction: the lock is held briefly.
        artifact = check_artifact(
            spec, weights, obs_dim=sizes[0], n_actions=sizes[1], max_bytes=self.max_artifact_bytes
        )
        for attempt in range(REGISTER_ATTEMPTS):
            try:
                with self._session(write=True) as session:
                    model = q.find_model(session, name)
                    if (model.obs_dim, model.n_actions) != sizes:  # re-created meanwhile
                        raise InvalidArtifact(
                            f"model {name!r} changed during upload; retry", field="name"
                        )
                    if idempotency_key is not None:
                        earlier = _registered_with(session, model.id, idempotency_key)
                        if earlier is not None:  # a retry of an upload that was registered
                            _check_same(earlier, artifact.sha256, artifact.spec, idempotency_key)
                            return version_entity(name, earlier)
                    self._check_parents(session, lineage)
                    model.last_version += 1
                    row = VersionRow(
                        model_id=model.id,
                        version=model.last_version,
                        spec=artifact.spec,
                        sha256=artifact.sha256,
                        size_bytes=artifact.size_bytes,
                        status="ready",
                        lineage=lineage.to_json(),
                        created_at=now(),
                        weights=bytes(weights),
                        idempotency_key=idempotency_key,
                    )
                    session.add(row)
                    session.flush()
                    q.emit(session, "version_registered", name, version=row.version)
                    for alias in alias_list:
                        q.point_alias(session, model, alias, row)
                    model.updated_at = now()
                    return version_entity(name, row)
            except AlreadyExists:
                if attempt == REGISTER_ATTEMPTS - 1:
                    raise
        raise AssertionError("unreachable")  # pragma: no cover

    @staticmethod
    def _check_parents(session: Session, lineage: Lineage) -> None:
        for i, parent in enumerate(lineage.parents):
            ref = parse_ref(parent)
            found = session.execute(
                select(VersionRow.id)
                .join(ModelRow, VersionRow.model_id == ModelRow.id)
                .where(ModelRow.name == ref.name, VersionRow.version == ref.version)
            ).first()
            if found is None:
                field = f"lineage.parents[{i}]"
                raise InvalidArtifact(f"{field}: no such version {brief(parent)}", field=field)

    def get_version(self, name: str, version: int) -> ModelVersion:
        _check_version_number(version)
        with self._session() as session:
            return version_entity(
                name, q.find_version(session, q.find_model(session, name), version)
            )

    def list_versions(self, name: str, *, include_archived: bool = True) -> list[ModelVersion]:
        with self._session() as session:
            model = q.find_model(session, name)
            stmt = select(VersionRow).where(VersionRow.model_id == model.id)
            if not include_archived:
                stmt = stmt.where(VersionRow.status == "ready")
            rows = session.execute(stmt.order_by(VersionRow.version.desc())).scalars()
            return [version_entity(name, r) for r in rows]

    def resolve(self, ref: str) -> ModelVersion:
        candidates = ref_candidates(ref)
        with self._session() as session:
            for parsed in candidates[:-1]:  # `a/b/4`: version 4 of `a/b`, if that model exists
                if session.execute(select(ModelRow.id).where(ModelRow.name == parsed.name)).first():
                    break
            else:
                parsed = candidates[-1]
            if parsed.version is not None:
                model = q.find_model(session, parsed.name)
                return version_entity(parsed.name, q.find_version(session, model, parsed.version))
            # One statement: the alias and the version it names are read from one snapshot.
            row = session.execute(
                select(VersionRow)
                .join(AliasRow, AliasRow.version_id == VersionRow.id)
                .join(ModelRow, AliasRow.model_id == ModelRow.id)
                .where(ModelRow.name == parsed.name, AliasRow.alias == parsed.alias)
            ).scalar_one_or_none()
            if row is None:
                model = q.find_model(session, parsed.name)  # NotFound for an unknown model
                known = ", ".join(sorted(a.alias for a in model.aliases)) or "none"
                raise NotFound(
                    f"model {parsed.name!r} has no alias {parsed.alias!r} (aliases: {known})",
                    field="alias",
                )
            return version_entity(parsed.name, row)

    def load_weights(self, name: str, version: int) -> bytes:
        _check_version_number(version)
        with self._session() as session:
            if "\x00" in name:  # no model's (`queries.find_model` says so, as on every look-up)
                q.find_model(session, name)
            found = session.execute(
                select(VersionRow.weights, VersionRow.sha256)
                .join(ModelRow, VersionRow.model_id == ModelRow.id)
                .where(ModelRow.name == name, VersionRow.version == version)
            ).first()
            if found is None:
                q.find_model(session, name)
                raise NotFound(f"model {name!r} has no version {version}", field="version")
        data, expected = bytes(found[0]), found[1]
        actual = sha256_hex(data)
        if not hmac.compare_digest(actual, expected):
            raise ChecksumMismatch(
                f"{name}/{version}: stored weights hash to sha256 {actual}, registered as "
                f"{expected}; the database was changed outside coexist"
            )
        return data

    def archive_version(self, name: str, version: int) -> ModelVersion:
        _check_version_number(version)
        with self._session(write=True) as session:
            model = q.find_model(session, name)
            row = q.find_version(session, model, version)
            if row.status == "archived":
                return version_entity(name, row)
            pointing = sorted(a.alias for a in q.aliases_of(model, row))
            if pointing:
                raise Conflict(
                    f"{name}/{version} is the target of alias(es) {', '.join(pointing)}: "
                    "move or delete them before archiving",
                    field="version",
                )
            row.status = "archived"
            model.updated_at = now()
            q.emit(session, "version_archived", name, version=version)
            return version_entity(name, row)

    def delete_version(self, name: str, version: int) -> None:
        _check_version_number(version)
        with self._session(write=True) as session:
            model = q.find_model(session, name)
            row = q.find_version(session, model, version)
            pointing = sorted(a.alias for a in q.aliases_of(model, row))
            if pointing:  # deleting it would silently stop serving whatever uses the alias
                raise Conflict(
                    f"{name}/{version} is the target of alias(es) {', '.join(pointing)}: "
                    "move or delete them before deleting",
                    field="version",
                )
            session.delete(row)
            model.updated_at = now()
            q.emit(session, "version_deleted", name, version=version)

    def set_alias(self, name: str, alias: str, version: int) -> None:
        validate_alias(alias)
        _check_version_number(version)
        with self._session(write=True) as session:
            model = q.find_model(session, name)
            row = q.find_version(session, model, version)
            if row.status != "ready":
                raise Conflict(
                    f"{name}/{version} is archived: an alias must point at a ready version",
                    field="version",
                )
            if q.point_alias(session, model, alias, row):
                model.updated_at = now()

    def delete_alias(self, name: str, alias: str) -> None:
        validate_alias(alias)
        with self._session(write=True) as session:
            model = q.find_model(session, name)
            for row in model.aliases:
                if row.alias == alias:
                    q.drop_alias(session, model, row)
                    model.updated_at = now()
                    return
            raise NotFound(f"model {name!r} has no alias {alias!r}", field="alias")
