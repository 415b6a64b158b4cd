"""ORM row -> entity conversion and page tokens (the only place rows turn into entities)."""

from __future__ import annotations

import base64
import binascii
import json
from datetime import UTC, datetime

from model_store.entities import Event, Lineage, ModelVersion, RegisteredModel
from model_store.errors import InvalidArgument
from model_store.sql.orm import EventRow, ModelRow, VersionRow


def utc(ts: datetime) -> datetime:
    """SQLite drops the zone of `DateTime(timezone=True)`: everything stored is UTC."""
    return ts if ts.tzinfo is not None else ts.replace(tzinfo=UTC)


def now() -> datetime:
    return datetime.now(UTC)


def model_entity(row: ModelRow) -> RegisteredModel:
    return RegisteredModel(
        name=row.name,
        env=row.env,
        kind=row.kind,
        goals=tuple(g.goal for g in row.goals),
        obs_dim=row.obs_dim,
        n_actions=row.n_actions,
        description=row.description,
        tags={t.key: t.value for t in sorted(row.tags, key=lambda t: t.key)},
        aliases={a.alias: a.version.version for a in sorted(row.aliases, key=lambda a: a.alias)},
        created_at=utc(row.created_at),
        updated_at=utc(row.updated_at),
    )


def version_entity(name: str, row: VersionRow) -> ModelVersion:
    return ModelVersion(
        name=name,
        version=row.version,
        spec=dict(row.spec),
        sha256=row.sha256,
        size_bytes=row.size_bytes,
        created_at=utc(row.created_at),
        status=row.status,
        lineage=Lineage.from_json(row.lineage),
    )


def event_entity(row: EventRow) -> Event:
    return Event(
        id=row.id,
        kind=row.kind,
        name=row.name,
        version=row.version,
        alias=row.alias,
        at=utc(row.at),
    )


def encode_page_token(last_name: str) -> str:
    """Keyset pagination: the token is the last name of the page, opaque to callers."""
    raw = json.dumps({"after": last_name}).encode()
    return base64.urlsafe_b64encode(raw).decode().rstrip("=")


def decode_page_token(token: str) -> str:
    try:
        padded = token + "=" * (-len(token) % 4)
        data = json.loads(base64.urlsafe_b64decode(padded.encode()))
        after = data["after"]
        if not isinstance(after, str) or "\x00" in after:  # no name holds NUL
            raise TypeError
        return after
    except (binascii.Error, ValueError, KeyError, TypeError, UnicodeDecodeError):
        raise InvalidArgument(
            "page_token: not a token returned by a previous list call", field="page_token"
        ) from None
