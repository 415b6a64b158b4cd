"""Where the store lives when nobody says (the embedded SQLite default), and which backend a
URL opens.

| setting             | effect                                                      |
|---------------------|-------------------------------------------------------------|
| `COEXIST_STORE_URL` | the store URL (SQLite file, PostgreSQL, a plugin's scheme), used as given |
| `COEXIST_DATA_DIR`  | otherwise `sqlite:///{COEXIST_DATA_DIR}/models.db`          |
| (neither)           | `sqlite:///./.coexist/models.db` (relative to the cwd)      |

The URL's scheme picks the backend: an entry point of the group `coexist.stores` named after it
(`postgresql+psycopg://` tries `postgresql+psycopg`, then `postgresql`), as MLflow picks its
registry stores. coexist's own SQL store is `sqlite`, `postgresql` and `postgres` (this
project's `pyproject.toml`); a package adds a backend with its own entry point naming a factory
`factory(url, *, max_artifact_bytes, auto_migrate, create) -> ModelStore`
(docs/extending.md). Every process opens its store here (the server, the CLI, a training job's
subprocess, a Ray worker), so a backend chosen by URL works in all of them.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable
from importlib.metadata import entry_points
from pathlib import Path

from sqlalchemy.engine import URL

from model_store.errors import InvalidArgument
from model_store.sql.sql_store import DEFAULT_MAX_ARTIFACT_BYTES, SqlModelStore
from model_store.store import ModelStore

log = logging.getLogger(__name__)

DEFAULT_DATA_DIR = ".coexist"
ENTRY_POINT_GROUP = "coexist.stores"

StoreFactory = Callable[..., ModelStore]
"""`factory(url, *, max_artifact_bytes, auto_migrate, create)` -> an open `ModelStore`."""


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


def store_schemes() -> dict[str, str]:
    """Every scheme a `coexist.stores` entry point names, with the factory it names."""
    return {p.name: p.value for p in entry_points(group=ENTRY_POINT_GROUP)}


def store_factory(url: str | URL) -> StoreFactory:
    """The factory of the backend `url`'s scheme picks (module docstring); `InvalidArgument`
    on field `store_url` for a URL without a scheme, a scheme nobody registered, or a plugin
    that fails to load. A URL object (a Ray worker's, password inside) is looked up by its
    driver name, never rendered."""
    if isinstance(url, URL):
        scheme = url.drivername
    else:
        scheme, separator, _ = url.partition("://")
        if not separator:
            scheme = url.partition(":")[0] if ":" in url else ""
    points = {p.name: p for p in entry_points(group=ENTRY_POINT_GROUP)}
    for name in (scheme, scheme.partition("+")[0]):
        if name and name in points:
            try:
                factory: StoreFactory = points[name].load()
            except Exception as exc:  # the plugin's own import failed: say which
                log.warning(
                    "store plugin %s (%s) failed to load: %s", name, points[name].value, exc
                )
                raise InvalidArgument(
                    f"store_url: the store backend of scheme {name!r} ({points[name].value}) "
                    f"failed to load ({type(exc).__name__}: {exc})",
                    field="store_url",
                ) from None
            return factory
    known = ", ".join(sorted(points)) or "none: reinstall coexist (`make setup`)"
    shown = f"scheme {scheme!r}" if scheme else "no scheme"
    raise InvalidArgument(
        f"store_url: {shown}; expected a URL whose scheme names a store backend "
        f"(installed: {known})",
        field="store_url",
    )


def check_store_url(url: str, *, create: bool) -> None:
    """What opening `url` would refuse, said before anything starts (`coexist serve`): a scheme
    no backend registered, a plugin that fails to load, a SQL driver that is not installed, a
    SQLite file that does not exist (unless `create`). `InvalidArgument` on field `store_url`."""
    from model_store.sql.engine import check_store_exists, create_store_engine, sqlite_file

    if store_factory(url) is not SqlModelStore:
        return  # a plugin's backend: opening it is its own check
    if sqlite_file(url) is None:
        create_store_engine(url).dispose()  # imports the driver; connects nowhere yet
    elif not create:
        check_store_exists(url)


def open_store(
    url: str | URL | None = None,
    *,
    max_artifact_bytes: int = DEFAULT_MAX_ARTIFACT_BYTES,
    auto_migrate: bool = True,
    create: bool = False,
) -> ModelStore:
    """Open the store at `url` or at `default_store_url()`, with the backend its scheme picks.
    A SQLite file that does not exist is an error naming the path (`InvalidArgument`, field
    `store_url`) unless `create`: commands that write models (`coexist train`, `coexist models
    import`) and `coexist serve` on its own default data directory ask for it, readers never
    do (a plugin's backend reads `create` the same way)."""
    url = url or default_store_url()
    return store_factory(url)(
        url,
        max_artifact_bytes=max_artifact_bytes,
        auto_migrate=auto_migrate,
        create=create,
    )
