"""Where the store lives when nobody says: the embedded SQLite default.

| setting             | effect                                                      |
|---------------------|-------------------------------------------------------------|
| `COEXIST_STORE_URL` | the store URL (SQLite file or PostgreSQL), used as given    |
| `COEXIST_DATA_DIR`  | otherwise `sqlite:///{COEXIST_DATA_DIR}/models.db`          |
| (neither)           | `sqlite:///./.coexist/models.db` (relative to the cwd)      |
"""

from __future__ import annotations

import os
from pathlib import Path

from model_store.sql.sql_store import DEFAULT_MAX_ARTIFACT_BYTES, SqlModelStore

DEFAULT_DATA_DIR = ".coexist"


def default_data_dir() -> Path:
    return Path(os.environ.get("COEXIST_DATA_DIR") or DEFAULT_DATA_DIR)


def default_store_url() -> str:
    """`COEXIST_STORE_URL`, else a SQLite file in the data directory (created if missing)."""
    url = os.environ.get("COEXIST_STORE_URL")
    if url:
        return url
    data_dir = default_data_dir()
    data_dir.mkdir(parents=True, exist_ok=True)
    return f"sqlite:///{data_dir / 'models.db'}"


def open_store(
    url: str | None = None,
    *,
    max_artifact_bytes: int = DEFAULT_MAX_ARTIFACT_BYTES,
    auto_migrate: bool = True,
    create: bool = False,
) -> SqlModelStore:
    """Open the store at `url` or at `default_store_url()`. A SQLite file that does not exist
    is an error naming the path (`InvalidArgument`, field `store_url`) unless `create`: commands
    that write models (`coexist train`, `coexist models import`) and `coexist serve` on its own
    default data directory ask for it, readers never do."""
    return SqlModelStore(
        url or default_store_url(),
        max_artifact_bytes=max_artifact_bytes,
        auto_migrate=auto_migrate,
        create=create,
    )
