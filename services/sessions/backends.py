"""Where a shared session store keeps its records: Redis or PostgreSQL, one URL away.

    backend = open_backend("redis://127.0.0.1:6379/0", namespace="3f9a…")
    backend.create(sid, client, record, now, ttl_s, max_sessions, max_per_client)  # Created
    loaded = backend.load(sid, known_version=4, now)    # None: absent; .record None: still 4
    backend.replace(sid, 4, record, client, now, ttl_s) # Replaced: ok / raced / gone
    backend.delete(sid, client); backend.count(now)

Every record has a version: 1 at creation, one more per committed step. `replace` writes only
over the version its step read (compare-and-set, one atomic operation on the server: a Lua
script in Redis, `UPDATE … WHERE version = $v` in PostgreSQL), so of two steps of one session
racing on two processes exactly one commits. `load` sends the record only when the caller's
copy is older than the stored one, so a process that served the previous step of a session
reads its version alone. Expiry: a record idle `ttl_s` is gone (Redis `PEXPIRE`; PostgreSQL
rows past `expires_at`, deleted at the next `create`). Bounds: `create` counts the live
sessions of the namespace and of the client in the same atomic step that inserts.

A store that does not answer raises `SessionStoreUnavailable` naming it (password hidden) and
the cause, within `timeout_s` (a `replace` whose reply was lost may have been applied). Times are the servers' wall clocks
(`time.time()`): replicas on one host, or synchronised hosts.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Literal, Protocol, TypeVar

from model_store.sql.engine import redact_url
from services.sessions.errors import SessionStoreUnavailable

T = TypeVar("T")


@dataclass(frozen=True)
class Loaded:
    version: int
    client: str
    expires_at: float  # wall-clock seconds
    record: bytes | None  # None: the caller's known version is the stored one


@dataclass(frozen=True)
class Created:
    outcome: Literal["created", "full", "client_full"]
    retry_after_s: float = 0.0  # when the first of the counted sessions could expire


@dataclass(frozen=True)
class Replaced:
    outcome: Literal["replaced", "raced", "gone"]
    version: int = 0  # the stored version now (replaced: the new one; raced: the winner's)


class SessionBackend(Protocol):
    url: str  # for messages: the password hidden

    def create(
        self,
        session_id: str,
        client: str,
        record: bytes,
        now: float,
        ttl_s: float,
        max_sessions: int,
        max_per_client: int,
    ) -> Created: ...

    def load(self, session_id: str, known_version: int, now: float) -> Loaded | None: ...

    def replace(
        self, session_id: str, version: int, record: bytes, client: str, now: float, ttl_s: float
    ) -> Replaced: ...

    def delete(self, session_id: str, client: str) -> bool: ...

    def count(self, now: float) -> int: ...

    def close(self) -> None: ...


def open_backend(url: str, namespace: str, timeout_s: float = 2.0) -> SessionBackend:
    """The backend for `url`: `redis://` / `rediss://` / `unix://`, or `postgresql://` (also
    `postgresql+psycopg://`, the model store's spelling). `ValueError` for another scheme or a
    missing client library (named with its extra)."""
    scheme = url.split("://", 1)[0].lower()
    if scheme in ("redis", "rediss", "unix"):
        return RedisBackend(url, namespace, timeout_s)
    if scheme in ("postgresql", "postgres", "postgresql+psycopg"):
        return PostgresBackend(url, namespace, timeout_s)
    raise ValueError(
        f"COEXIST_SESSION_STORE_URL: expected redis://, rediss:// or postgresql://, got "
        f"{redact_url(url)!r}"
    )


# --- Redis -------------------------------------------------------------------------------------
# KEYS: the session's hash, the namespace's zset of live ids (score: expiry in ms), the client's
# zset. A hash holds v (version), r (record), c (client), e (expiry, ms).
_CREATE = """
redis.call('ZREMRANGEBYSCORE', KEYS[2], '-inf', ARGV[1])
redis.call('ZREMRANGEBYSCORE', KEYS[3], '-inf', ARGV[1])
if redis.call('ZCARD', KEYS[2]) >= tonumber(ARGV[4]) then
  return {1, redis.call('ZRANGE', KEYS[2], 0, 0, 'WITHSCORES')[2]}
end
if redis.call('ZCARD', KEYS[3]) >= tonumber(ARGV[5]) then
  return {2, redis.call('ZRANGE', KEYS[3], 0, 0, 'WITHSCORES')[2]}
end
redis.call('HSET', KEYS[1], 'v', 1, 'r', ARGV[6], 'c', ARGV[7], 'e', ARGV[2])
redis.call('PEXPIRE', KEYS[1], ARGV[3])
redis.call('ZADD', KEYS[2], ARGV[2], ARGV[8])
redis.call('ZADD', KEYS[3], ARGV[2], ARGV[8])
redis.call('PEXPIRE', KEYS[3], ARGV[3])
return {0, '0'}
"""
_LOAD = """
local h = redis.call('HMGET', KEYS[1], 'v', 'c', 'e')
if not h[1] then return false end
if h[1] == ARGV[1] then return h end
h[4] = redis.call('HGET', KEYS[1], 'r')
return h
"""
_REPLACE = """
local v = redis.call('HGET', KEYS[1], 'v')
if not v then return {2, 0} end
if v ~= ARGV[1] then return {1, tonumber(v)} end
local next = tonumber(v) + 1
redis.call('HSET', KEYS[1], 'v', next, 'r', ARGV[2], 'e', ARGV[3])
redis.call('PEXPIRE', KEYS[1], ARGV[4])
redis.call('ZADD', KEYS[2], ARGV[3], ARGV[5])
redis.call('ZADD', KEYS[3], ARGV[3], ARGV[5])
redis.call('PEXPIRE', KEYS[3], ARGV[4])
return {0, next}
"""
_DELETE = """
local n = redis.call('DEL', KEYS[1])
redis.call('ZREM', KEYS[2], ARGV[1])
redis.call('ZREM', KEYS[3], ARGV[1])
return n
"""
_COUNT = """
redis.call('ZREMRANGEBYSCORE', KEYS[1], '-inf', ARGV[1])
return redis.call('ZCARD', KEYS[1])
"""


class RedisBackend:
    """Records in Redis hashes under `coexist:{namespace}:` (module docstring)."""

    def __init__(self, url: str, namespace: str, timeout_s: float) -> None:
        try:
            import redis
            from redis.backoff import NoBackoff
            from redis.retry import Retry
        except ImportError:  # pragma: no cover - the extra is part of dev
            raise ValueError(
                "COEXIST_SESSION_STORE_URL: a redis:// store needs the redis client "
                "(pip install 'coexist[redis]')"
            ) from None
        self.url = redact_url(url)
        self._errors = (redis.ConnectionError, redis.TimeoutError)
        self._redis = redis.Redis.from_url(
            url,
            socket_timeout=timeout_s,
            socket_connect_timeout=timeout_s,
            retry=Retry(NoBackoff(), 0),  # a store that is down: one clear 503, not a wait
        )
        self._prefix = f"coexist:{namespace}:"
        self._all = self._prefix + "live"
        scripts = {"create": _CREATE, "load": _LOAD, "replace": _REPLACE}
        scripts.update(delete=_DELETE, count=_COUNT)
        self._scripts = {name: self._redis.register_script(s) for name, s in scripts.items()}

    def _keys(self, session_id: str, client: str) -> list[str]:
        return [self._prefix + "s:" + session_id, self._all, self._prefix + "c:" + client]

    def _run(self, name: str, keys: list[str], args: list[Any]) -> Any:
        try:
            return self._scripts[name](keys=keys, args=args)
        except self._errors as err:
            raise SessionStoreUnavailable(
                None, f"the session store {self.url} did not answer: {err}"
            ) from None

    def create(
        self,
        session_id: str,
        client: str,
        record: bytes,
        now: float,
        ttl_s: float,
        max_sessions: int,
        max_per_client: int,
    ) -> Created:
        now_ms, ttl_ms = int(now * 1000), max(1, int(ttl_s * 1000))
        args = [now_ms, now_ms + ttl_ms, ttl_ms, max_sessions, max_per_client, record, client]
        outcome, first = self._run("create", self._keys(session_id, client), [*args, session_id])
        if outcome == 0:
            return Created("created")
        retry = max(0.0, float(first) / 1000 - now)
        return Created("full" if outcome == 1 else "client_full", retry)

    def load(self, session_id: str, known_version: int, now: float) -> Loaded | None:
        got = self._run("load", [self._prefix + "s:" + session_id], [known_version])
        if not got:
            return None
        record = got[3] if len(got) > 3 else None
        return Loaded(int(got[0]), got[1].decode(), int(got[2]) / 1000, record)

    def replace(
        self, session_id: str, version: int, record: bytes, client: str, now: float, ttl_s: float
    ) -> Replaced:
        ttl_ms = max(1, int(ttl_s * 1000))
        args = [version, record, int(now * 1000) + ttl_ms, ttl_ms, session_id]
        outcome, stored = self._run("replace", self._keys(session_id, client), args)
        return Replaced(("replaced", "raced", "gone")[outcome], int(stored))

    def delete(self, session_id: str, client: str) -> bool:
        return bool(self._run("delete", self._keys(session_id, client), [session_id]))

    def count(self, now: float) -> int:
        return int(self._run("count", [self._all], [int(now * 1000)]))

    def close(self) -> None:
        self._redis.close()


# --- PostgreSQL --------------------------------------------------------------------------------
_TABLE = "coexist_sessions"
_SCHEMA = f"""
CREATE TABLE IF NOT EXISTS {_TABLE} (
    namespace text NOT NULL,
    id text NOT NULL,
    client text NOT NULL,
    version bigint NOT NULL,
    expires_at double precision NOT NULL,
    record bytea NOT NULL,
    PRIMARY KEY (namespace, id)
);
CREATE INDEX IF NOT EXISTS {_TABLE}_expiry ON {_TABLE} (namespace, expires_at);
"""


class PostgresBackend:
    """Records in the table `coexist_sessions` (created if absent), one row per session; one
    connection per thread, autocommit, statements prepared by psycopg after a few uses."""

    def __init__(self, url: str, namespace: str, timeout_s: float) -> None:
        try:
            import psycopg
        except ImportError:  # pragma: no cover - the extra is part of dev
            raise ValueError(
                "COEXIST_SESSION_STORE_URL: a postgresql:// store needs psycopg "
                "(pip install 'coexist[postgres]')"
            ) from None
        self._psycopg = psycopg
        self.url = redact_url(url)
        self._dsn = url.replace("postgresql+psycopg://", "postgresql://", 1)
        self._timeout_s = timeout_s
        self._namespace = namespace
        self._local = threading.local()
        self._made_table = False

    @contextmanager
    def _cursor(self) -> Iterator[Any]:
        """A cursor of this thread's connection; a failed connection is dropped (the next call
        connects again) and named as `SessionStoreUnavailable`."""
        psycopg = self._psycopg
        try:
            conn = getattr(self._local, "conn", None)
            if conn is None or conn.closed:
                conn = psycopg.connect(
                    self._dsn, autocommit=True, connect_timeout=max(1, round(self._timeout_s))
                )
                # (SETs, not the `options` parameter, which would replace the URL's own).
                # synchronous_commit off: a step's commit does not wait for the WAL flush, as
                # Redis does not fsync each write; a killed replica still loses nothing (the
                # row is committed before the answer), a crash of PostgreSQL itself may lose
                # the last few hundred ms of steps, never corrupt a record.
                conn.execute(f"SET statement_timeout = {int(self._timeout_s * 1000)}")
                conn.execute("SET synchronous_commit = off")
                self._local.conn = conn
                if not self._made_table:
                    # two servers starting at once may race on the catalogue: the loser's
                    # table exists by then
                    with contextlib.suppress(psycopg.errors.UniqueViolation):
                        conn.execute(_SCHEMA)
                    self._made_table = True
            with conn.cursor() as cur:
                yield cur
        except (psycopg.OperationalError, psycopg.InterfaceError) as err:
            self._drop()
            first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
            raise SessionStoreUnavailable(
                None, f"the session store {self.url} did not answer: {first}"
            ) from None

    def _drop(self) -> None:
        conn = getattr(self._local, "conn", None)
        self._local.conn = None
        if conn is not None:
            with contextlib.suppress(self._psycopg.Error):  # already broken
                conn.close()

    def _one(self, sql: str, params: tuple[Any, ...], read: Callable[[Any], T]) -> T:
        with self._cursor() as cur:
            cur.execute(sql, params)
            return read(cur.fetchone())

    def create(
        self,
        session_id: str,
        client: str,
        record: bytes,
        now: float,
        ttl_s: float,
        max_sessions: int,
        max_per_client: int,
    ) -> Created:
        ns = self._namespace
        with self._cursor() as cur, cur.connection.transaction():
            # creates of one namespace one at a time: the counts hold until the insert
            cur.execute("SELECT pg_advisory_xact_lock(hashtext(%s))", (ns,))
            cur.execute(
                f"DELETE FROM {_TABLE} WHERE namespace = %s AND expires_at <= %s", (ns, now)
            )
            cur.execute(
                f"SELECT count(*), min(expires_at), count(*) FILTER (WHERE client = %s), "
                f"min(expires_at) FILTER (WHERE client = %s) FROM {_TABLE} WHERE namespace = %s",
                (client, client, ns),
            )
            total, first, mine, my_first = cur.fetchone()
            if total >= max_sessions:
                return Created("full", max(0.0, first - now))
            if mine >= max_per_client:
                return Created("client_full", max(0.0, my_first - now))
            cur.execute(
                f"INSERT INTO {_TABLE} (namespace, id, client, version, expires_at, record) "
                "VALUES (%s, %s, %s, 1, %s, %s)",
                (ns, session_id, client, now + ttl_s, record),
            )
        return Created("created")

    def load(self, session_id: str, known_version: int, now: float) -> Loaded | None:
        row = self._one(
            f"SELECT version, client, expires_at, CASE WHEN version = %s THEN NULL ELSE record "
            f"END FROM {_TABLE} WHERE namespace = %s AND id = %s AND expires_at > %s",
            (known_version, self._namespace, session_id, now),
            lambda row: row,
        )
        if row is None:
            return None
        version, client, expires_at, record = row
        return Loaded(version, client, expires_at, None if record is None else bytes(record))

    def replace(
        self, session_id: str, version: int, record: bytes, client: str, now: float, ttl_s: float
    ) -> Replaced:
        ns = self._namespace
        with self._cursor() as cur:
            cur.execute(
                f"UPDATE {_TABLE} SET version = version + 1, record = %s, expires_at = %s "
                "WHERE namespace = %s AND id = %s AND version = %s AND expires_at > %s "
                "RETURNING version",
                (record, now + ttl_s, ns, session_id, version, now),
            )
            row = cur.fetchone()
            if row is not None:
                return Replaced("replaced", row[0])
            cur.execute(
                f"SELECT version FROM {_TABLE} WHERE namespace = %s AND id = %s "
                "AND expires_at > %s",
                (ns, session_id, now),
            )
            row = cur.fetchone()
        return Replaced("gone") if row is None else Replaced("raced", row[0])

    def delete(self, session_id: str, client: str) -> bool:
        with self._cursor() as cur:
            cur.execute(
                f"DELETE FROM {_TABLE} WHERE namespace = %s AND id = %s",
                (self._namespace, session_id),
            )
            return bool(cur.rowcount)

    def count(self, now: float) -> int:
        return self._one(
            f"SELECT count(*) FROM {_TABLE} WHERE namespace = %s AND expires_at > %s",
            (self._namespace, now),
            lambda row: int(row[0]),
        )

    def close(self) -> None:
        self._drop()
