"""Register a batch of networks at most once per job, however often the job runs.

A distributed job can run twice: Ray retries a task whose worker died (maybe after it had
registered half its networks), and a worker cut off from the cluster may still finish after its
retry did. Version numbers are never reused, so a second registration would be a duplicate
version forever. Two pieces make publishing idempotent:

| piece            | what                                                                    |
|------------------|-------------------------------------------------------------------------|
| job key          | `"{run id}/{batch key}"`, e.g. `"5f0c…/task:a2,b3"`: the same for every  |
|                  | attempt of one batch of one run, different for every new run            |
| marker           | the key is written into each version's lineage config (`config["job"]`) |
| publish lock     | held while a batch checks for markers and registers: PostgreSQL         |
|                  | `pg_advisory_lock(hash(key))` on a connection of its own, SQLite an     |
|                  | exclusive `flock` on `<database>.publish.lock` next to the file; a     |
|                  | backend without SQL gives its own (`ModelStore.lock`)                   |

Under the lock, a member whose model already has a version marked with the job key is not
registered again: that version is returned instead (a model twice in one batch, a gate retry's
two candidates, is matched occurrence by occurrence). Two attempts finishing together take the
lock in turn, and the second finds the first one's versions. A holder that dies releases the
lock with its connection (PostgreSQL) or its open file (SQLite). The aliases of a version are set
in the same transaction that registers it, so a reused version already carries them; the gate tag
is written again (the same value).
"""

from __future__ import annotations

import fcntl
import hashlib
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

from sqlalchemy.engine import URL

from model_store.entities import Lineage, ModelVersion
from model_store.sql.engine import is_sqlite, normalise_url, without_password
from model_store.store import ModelStore
from trainer.learners import TrainedBatch
from trainer.publish import publish_batch

if TYPE_CHECKING:
    import psycopg

JOB_CONFIG_KEY = "job"  # lineage config key of the job marker
PG_LOCK_TIMEOUT_S = 600  # a publish holds the lock for seconds; waiting longer means trouble

# called with each version this attempt registered itself (fault injection in the tests)
RegisteredHook = Callable[[ModelVersion], None]


def lock_id(job_key: str) -> int:
    """A signed 64-bit PostgreSQL advisory lock id derived from the job key."""
    return int.from_bytes(hashlib.sha256(job_key.encode()).digest()[:8], "big", signed=True)


def lock_connection(url: URL) -> psycopg.Connection[Any]:
    """An autocommit connection to the PostgreSQL database at `url`, for the publish lock. The
    password goes to psycopg as a keyword of its own, never into the conninfo string: a string
    that holds it is one traceback or log line away from a leak. Where `url` has none, libpq
    reads `PGPASSWORD` (how a job's subprocess gets it: `trainer.jobs.runner`)."""
    import psycopg

    conninfo = without_password(url.set(drivername="postgresql")).render_as_string()
    return psycopg.connect(conninfo, password=url.password, autocommit=True, connect_timeout=5)


@contextmanager
def publish_lock(store_url: str | URL, job_key: str) -> Iterator[None]:
    """Hold the job's publish lock (see the module docstring) for the `with` block."""
    url = normalise_url(store_url)
    if is_sqlite(url):
        database = Path(url.database or "").expanduser().absolute()
        lock_path = database.with_name(database.name + ".publish.lock")
        with open(lock_path, "a+b") as lock_file:
            fcntl.flock(lock_file, fcntl.LOCK_EX)  # released by close, also when the process dies
            yield
        return
    with lock_connection(url) as conn:
        conn.execute(f"SET lock_timeout = '{PG_LOCK_TIMEOUT_S}s'")
        conn.execute("SELECT pg_advisory_lock(%s)", (lock_id(job_key),))
        yield  # closing the session releases the lock


class _RegisterOnce:
    """The store as `publish_batch` sees it, except that `register_version` returns the version
    already marked with the job key, if there is one: the k-th call for a model (a goal twice
    in one batch: a gate retry's two candidates, `trainer.zoo.retry_batches`) gets the k-th
    marked version. Everything else passes through."""

    def __init__(self, store: ModelStore, job_key: str, on_register: RegisteredHook | None):
        self._store = store
        self._job_key = job_key
        self._on_register = on_register
        self._calls: dict[str, int] = {}  # model name -> register_version calls so far

    def __getattr__(self, attribute: str) -> Any:
        return getattr(self._store, attribute)

    def register_version(
        self, name: str, *, spec: dict, weights: bytes, lineage: Lineage, aliases: Sequence[str]
    ) -> ModelVersion:
        nth = self._calls.get(name, 0)
        self._calls[name] = nth + 1
        marked = [
            v
            for v in self._store.list_versions(name)
            if v.lineage.config.get(JOB_CONFIG_KEY) == self._job_key
        ]
        if nth < len(marked):
            return sorted(marked, key=lambda v: v.version)[nth]
        version = self._store.register_version(
            name, spec=spec, weights=weights, lineage=lineage, aliases=aliases
        )
        if self._on_register is not None:
            self._on_register(version)
        return version


def publish_once(
    store: ModelStore,
    store_url: str | URL,
    batch: TrainedBatch,
    *,
    job_key: str,
    env: str,
    parents: Mapping[tuple[str, ...], Sequence[str]] | None = None,
    serve_alias: str = "production",
    on_register: RegisteredHook | None = None,
) -> list[ModelVersion]:
    """`publish_batch` with the job marker, under the publish lock, skipping marked members.

    The lock is the store's own (`ModelStore.lock`) where its backend offers one, else it lives
    in the database `store` writes to: its SQL `url` (a plugin backend over a SQL database has
    one too), else `store_url`, which must then name that database."""
    once = cast(ModelStore, _RegisterOnce(store, job_key, on_register))
    sql_url: URL | None = getattr(store, "url", None)  # the object: its password stays inside
    with store.lock(job_key) or publish_lock(
        sql_url if sql_url is not None else store_url, job_key
    ):
        return publish_batch(
            once,
            batch,
            env=env,
            parents=parents,
            serve_alias=serve_alias,
            extra_config={JOB_CONFIG_KEY: job_key},
        )
