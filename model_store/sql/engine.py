"""Engine creation for the two backends.

| backend    | URL                                 | what is set up                                |
|------------|-------------------------------------|-----------------------------------------------|
| SQLite     | `sqlite:///path/to/models.db`       | WAL journal, busy_timeout, foreign keys, real |
|            |                                     | transactions (BEGIN issued by us), no pooling |
| PostgreSQL | `postgresql+psycopg://user@host/db` | psycopg 3, pre-ping, connect timeout          |
|            | (`postgresql://`, `postgres://` are |                                               |
|            | rewritten to psycopg)               |                                               |

SQLite notes (why): Python's sqlite3 module opens transactions lazily and never around DDL, which
breaks atomic migrations and lets two writers both read a version counter before either writes.
So the driver's own transaction handling is switched off and we emit `BEGIN` ourselves: write
sessions use `BEGIN IMMEDIATE` (writers queue on busy_timeout instead of failing), readers a plain
deferred `BEGIN` (in WAL mode they never wait for a writer). Pooling is off (`NullPool`) so every
session opens the file afresh: a database file whose directory disappeared is an error at once
instead of a ghost connection to an unlinked file, and forked processes share no connections.
After the file exists it is opened with `mode=rw`, so SQLite never silently creates a new, empty
database in its place.

Mistakes are named, not swallowed: with `create=False` a SQLite file that does not exist is an
`InvalidArgument` naming the path (a mistyped path would otherwise become an empty store that
answers "0 models"), and a PostgreSQL URL without its driver names the extra to install.
"""

from __future__ import annotations

import re
import sqlite3
import time
from pathlib import Path
from typing import Any
from urllib.parse import quote

from sqlalchemy import Engine, create_engine, event
from sqlalchemy.engine import URL, make_url
from sqlalchemy.pool import NullPool

from model_store.errors import InvalidArgument, StoreUnavailable

SQLITE_BUSY_TIMEOUT_MS = 15_000
PG_CONNECT_TIMEOUT_S = 5
WAL_RETRY_S = 0.01  # between two tries of a new file's WAL switch (`_set_wal`)
BEGIN_MODE_OPTION = "coexist_sqlite_begin"  # execution option: "IMMEDIATE" for write sessions


# `scheme://user:PASSWORD@`: what `redact_url` masks in a URL that does not even parse
_USERINFO_PASSWORD = re.compile(r"(://[^:/?#@\s]*:)[^@\s]*@")


def redact_url(url: str | URL) -> str:
    """`url` safe to log, print or answer: its password (if any) replaced by `***`. Every place
    that shows a store URL goes through this (or `render_as_string(hide_password=True)`);
    the password only ever reaches the database driver."""
    if isinstance(url, URL):
        return str(url.render_as_string(hide_password=True))
    try:
        return str(make_url(url).render_as_string(hide_password=True))
    except Exception:  # unparsable: mask by shape (sqlalchemy's own message would echo it)
        return _USERINFO_PASSWORD.sub(r"\1***@", url)


def normalise_url(url: str | URL) -> URL:
    """Parse a store URL (a URL object is taken as it is, password included); plain
    `postgresql://` (and `postgres://`) become psycopg 3 URLs."""
    if isinstance(url, URL):
        parsed = url  # not `make_url(str(url))`: `str` masks the password as `***`
    else:
        try:
            parsed = make_url(url)
        except Exception:  # sqlalchemy raises ArgumentError and others, their text echoes it
            raise InvalidArgument(
                f"store_url: cannot parse {redact_url(url)!r} (expected sqlite:///path or "
                "postgresql://user:password@host:port/database)",
                field="store_url",
            ) from None
    if parsed.drivername in ("postgresql", "postgres"):
        parsed = parsed.set(drivername="postgresql+psycopg")
    if parsed.get_backend_name() not in ("sqlite", "postgresql"):
        raise InvalidArgument(
            f"store_url: unsupported backend {parsed.get_backend_name()!r} "
            "(expected sqlite:///path or postgresql://...)",
            field="store_url",
        )
    return parsed


def without_password(url: URL) -> URL:
    """`url` with no password: what may be rendered into a string (an environment variable, a
    conninfo), the password handed over apart. (`url.set(password=None)` would keep it: `set`
    skips arguments that are None.)"""
    return URL.create(
        url.drivername, url.username, None, url.host, url.port, url.database, url.query
    )


def is_sqlite(url: URL) -> bool:
    return url.get_backend_name() == "sqlite"


POSTGRES_EXTRA_HINT = "pip install 'coexist[postgres]'"
NEW_STORE_HINT = "`coexist serve --create-store` or `coexist train` make a new one"


def create_store_engine(url: str | URL, *, create: bool = True) -> Engine:
    """An engine for `url`, configured as described in the module docstring; `create=False`:
    a SQLite file that does not exist is an error instead of a new, empty store."""
    parsed = normalise_url(url)
    if is_sqlite(parsed):
        return _sqlite_engine(parsed, create=create)
    try:
        return create_engine(
            parsed,
            pool_pre_ping=True,
            connect_args={"connect_timeout": PG_CONNECT_TIMEOUT_S},
        )
    except ImportError as exc:  # the dialect imports its driver here
        raise InvalidArgument(
            f"store_url: the PostgreSQL driver ({exc.name or 'psycopg'}) is not installed: "
            f"{POSTGRES_EXTRA_HINT}",
            field="store_url",
        ) from None


def sqlite_file(url: str | URL) -> Path | None:
    """The absolute path of a SQLite store URL's file, None for other backends (and for an
    in-memory URL, which `create_store_engine` refuses)."""
    parsed = normalise_url(url)
    if not is_sqlite(parsed) or not parsed.database or parsed.database == ":memory:":
        return None
    return Path(parsed.database).expanduser().absolute()


def check_store_exists(url: str | URL) -> None:
    """Raise `InvalidArgument` (field `store_url`) when `url` is a SQLite file that does not
    exist: what opening it with `create=False` would say, before anything else starts."""
    file = sqlite_file(url)
    if file is not None and not file.is_file():
        raise InvalidArgument(
            f"store_url: no SQLite database at {str(file)!r} (the file does not exist: check "
            f"the path; {NEW_STORE_HINT})",
            field="store_url",
        )


def _sqlite_engine(url: URL, *, create: bool) -> Engine:
    path = url.database
    if not path or path == ":memory:":
        raise InvalidArgument(
            "store_url: an in-memory SQLite database cannot be shared between sessions; "
            "use a file (sqlite:///path/to/models.db)",
            field="store_url",
        )
    file = Path(path).expanduser().absolute()
    if not create:
        check_store_exists(url)
    _create_sqlite_file(file)
    uri = f"file:{quote(str(file))}?mode=rw"

    def connect() -> sqlite3.Connection:
        return sqlite3.connect(
            uri, uri=True, timeout=SQLITE_BUSY_TIMEOUT_MS / 1000, check_same_thread=False
        )

    engine = create_engine("sqlite://", creator=connect, poolclass=NullPool)

    @event.listens_for(engine, "connect")
    def _on_connect(dbapi_conn: Any, _record: Any) -> None:
        dbapi_conn.isolation_level = None  # we issue BEGIN ourselves (see module docstring)
        cursor = dbapi_conn.cursor()
        cursor.execute(f"PRAGMA busy_timeout = {SQLITE_BUSY_TIMEOUT_MS}")
        cursor.execute("PRAGMA foreign_keys = ON")
        cursor.execute("PRAGMA synchronous = NORMAL")
        cursor.close()

    @event.listens_for(engine, "begin")
    def _on_begin(conn: Any) -> None:
        mode = conn.get_execution_options().get(BEGIN_MODE_OPTION, "")
        conn.exec_driver_sql(f"BEGIN {mode}".strip())

    return engine


def _create_sqlite_file(path: Path) -> None:
    """Create the directory and the database file (in WAL mode) if they do not exist yet."""
    deadline = time.monotonic() + SQLITE_BUSY_TIMEOUT_MS / 1000
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        while not _set_wal(path, retry=time.monotonic() < deadline):
            time.sleep(WAL_RETRY_S)
    except (OSError, sqlite3.Error) as exc:
        raise StoreUnavailable(f"cannot open SQLite database {str(path)!r}: {exc}") from None


def _set_wal(path: Path, *, retry: bool) -> bool:
    """Switch the file to WAL (a property of the file: set once, every later connection
    inherits it); False where another process holds the lock and `retry` allows another try.
    Two processes opening a new file at once both switch it, and SQLite may refuse one of them
    "database is locked" at once, without waiting out the busy timeout (it does not wait where
    waiting could deadlock), so the switch is tried again until the busy timeout has passed."""
    conn = sqlite3.connect(path, timeout=SQLITE_BUSY_TIMEOUT_MS / 1000)
    try:
        conn.execute("PRAGMA journal_mode = WAL")
        return True
    except sqlite3.OperationalError as exc:
        if retry and "locked" in str(exc):
            return False
        raise
    finally:
        conn.close()
