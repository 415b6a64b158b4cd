"""Several processes at once: version numbers, alias moves seen by readers, races on one alias,
one name, and on the first migration.

Children are forked (spawning re-imports torch: seconds per process) and each opens its own store
from the URL, so none uses a connection of its parent; the parent starts no thread before forking.
"""

# ruff: noqa: F811  (the fixtures imported from store_fixtures are re-bound as test arguments)

from __future__ import annotations

import itertools
import multiprocessing as mp
import sqlite3
import threading
import time
from pathlib import Path
from typing import Any

import pytest
from store_fixtures import pg_url, store_url  # noqa: F401

from model_store.errors import AlreadyExists, StoreUnavailable
from model_store.sql import SqlModelStore
from model_store.sql import engine as sql_engine
from model_store.testing import qnet_spec, qnet_weights, test_lineage

NAME = "particle/task/a3"
SPEC = qnet_spec(obs_dim=8, n_actions=5, hidden=(16,))
PER_PROCESS = 6
CTX = mp.get_context("fork")


def _create(store: SqlModelStore) -> None:
    store.create_model(
        NAME, env="particle", kind="task", goals=["a3"], obs_dim=8, n_actions=5, exist_ok=True
    )


def _worker(url: str, job: str, barrier: Any, out: Any, stop: Any, arg: int) -> None:
    """Runs in a child process; puts ("ok", result) or ("error", repr) on `out`."""
    try:
        if job == "open":  # the race is on opening (migrating) the store itself
            barrier.wait(timeout=60)
            store = SqlModelStore(url)
        else:
            store = SqlModelStore(url)
            barrier.wait(timeout=60)
        with store:
            out.put(("ok", _job(store, job, arg, stop)))
    except BaseException as exc:  # report everything to the parent
        out.put(("error", repr(exc)))


def _job(store: SqlModelStore, job: str, arg: int, stop: Any) -> Any:
    if job == "open":
        _create(store)
        return store.schema_revision
    if job == "register":
        return [
            store.register_version(
                NAME,
                spec=SPEC,
                weights=qnet_weights(SPEC, seed=arg * 100 + i),
                lineage=test_lineage(),
            ).version
            for i in range(PER_PROCESS)
        ]
    if job == "alias":
        for _ in range(20):
            store.set_alias(NAME, "production", arg)
        return arg
    if job == "create":
        try:
            store.create_model(
                NAME, env="particle", kind="task", goals=["a3"], obs_dim=8, n_actions=5
            )
            return "created"
        except AlreadyExists:
            return "exists"
    if job == "read":
        return _read_until(store, stop)
    raise ValueError(f"job: unknown {job!r}")


def _read_until(store: SqlModelStore, stop: Any) -> dict:
    """Resolve `production` in a loop; every answer must be a whole, consistent version."""
    shas = {v.version: v.sha256 for v in store.list_versions(NAME)}
    seen: dict[int, int] = {}
    while not stop.is_set():
        mv = store.resolve(f"{NAME}@production")
        assert mv.sha256 == shas[mv.version], f"half state: {mv.version} with {mv.sha256}"
        seen[mv.version] = seen.get(mv.version, 0) + 1
        if sum(seen.values()) % 10 == 0:
            store.load_weights(NAME, mv.version)  # verifies its sha256
    return seen


def _run(url: str, jobs: list[tuple[str, int]], stop: Any = None, *, parent_work=None) -> list:
    import policy.qnet  # noqa: F401  (imported once here rather than in every child)

    barrier = CTX.Barrier(len(jobs) + 1)
    out = CTX.Queue()
    stop = stop or CTX.Event()
    procs = [
        CTX.Process(target=_worker, args=(url, job, barrier, out, stop, arg)) for job, arg in jobs
    ]
    for p in procs:
        p.start()
    barrier.wait(timeout=60)
    if parent_work is not None:
        parent_work()
        stop.set()
    results = [out.get(timeout=90) for _ in procs]
    for p in procs:
        p.join(timeout=30)
    errors = [r for status, r in results if status == "error"]
    assert not errors, errors
    return [r for _, r in results]


def test_two_processes_registering_get_distinct_gapless_versions(store_url: str) -> None:
    with SqlModelStore(store_url) as store:
        _create(store)
        results = _run(store_url, [("register", 1), ("register", 2)])
        numbers = sorted(results[0] + results[1])
        assert numbers == list(range(1, 2 * PER_PROCESS + 1))
        assert all(r == sorted(r) for r in results)
        assert [v.version for v in store.list_versions(NAME)] == numbers[::-1]
        assert store.get_model(NAME).aliases["latest"] == 2 * PER_PROCESS
        ids = [e.id for e in store.events(limit=1000)]
        assert ids == list(range(1, len(ids) + 1))


def test_readers_never_see_a_half_moved_alias(store_url: str) -> None:
    with SqlModelStore(store_url) as store:
        _create(store)
        for seed in (1, 2):
            store.register_version(
                NAME, spec=SPEC, weights=qnet_weights(SPEC, seed=seed), lineage=test_lineage()
            )
        store.set_alias(NAME, "production", 1)
        stop = CTX.Event()
        thread_result: dict = {}
        reader = threading.Thread(target=lambda: thread_result.update(_read_until(store, stop)))

        def flip() -> None:
            reader.start()  # after the fork: a child never inherits a running thread
            for i in range(40):
                store.set_alias(NAME, "production", 2 - i % 2)
                time.sleep(0.005)

        try:
            seen = _run(store_url, [("read", 0), ("read", 0)], stop, parent_work=flip)
        finally:
            stop.set()
            if reader.is_alive():
                reader.join(timeout=30)
        for counts in [*seen, thread_result]:
            assert set(counts) <= {1, 2} and sum(counts.values()) > 0
        assert set(thread_result) <= {1, 2} and sum(thread_result.values()) > 0


def test_racing_alias_moves_and_creates_end_in_one_valid_state(store_url: str) -> None:
    with SqlModelStore(store_url) as store:
        _create(store)
        for seed in (1, 2):
            store.register_version(
                NAME, spec=SPEC, weights=qnet_weights(SPEC, seed=seed), lineage=test_lineage()
            )
        assert sorted(_run(store_url, [("alias", 1), ("alias", 2)])) == [1, 2]
        final = store.get_model(NAME).aliases["production"]
        assert final in (1, 2)
        moves = [e for e in store.events(limit=1000) if e.alias == "production"]
        assert moves[-1].version == final
        assert all(a.version != b.version for a, b in itertools.pairwise(moves))
        store.delete_model(NAME)
        assert sorted(_run(store_url, [("create", 0), ("create", 0)])) == ["created", "exists"]


def test_first_use_by_two_processes_migrates_once(store_url: str) -> None:
    revisions = _run(store_url, [("open", 0), ("open", 0)])
    assert len(set(revisions)) == 1
    with SqlModelStore(store_url, auto_migrate=False) as store:
        assert store.get_model(NAME).name == NAME


def test_a_new_files_wal_switch_refused_at_once_is_tried_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """SQLite may refuse a new file's switch to WAL "database is locked" without waiting while
    another process switches it (the race of the test above): the store tries again within the
    busy timeout; a lock that outlasts it is StoreUnavailable."""
    real_connect, refusals = sqlite3.connect, [2]

    class Refusing:  # a connection whose first WAL switches are refused, as in the race
        def __init__(self, *args: Any, **kwargs: Any) -> None:
            self.conn = real_connect(*args, **kwargs)

        def execute(self, sql: str) -> Any:
            if "journal_mode" in sql and refusals[0] > 0:
                refusals[0] -= 1
                raise sqlite3.OperationalError("database is locked")
            return self.conn.execute(sql)

        def close(self) -> None:
            self.conn.close()

    monkeypatch.setattr(sql_engine.sqlite3, "connect", Refusing)
    sql_engine._create_sqlite_file(tmp_path / "models.db")
    assert refusals == [0]
    with real_connect(tmp_path / "models.db") as conn:
        assert conn.execute("PRAGMA journal_mode").fetchone() == ("wal",)
    refusals[0] = 10**6  # locked for good: refused once the busy timeout has passed
    monkeypatch.setattr(sql_engine, "SQLITE_BUSY_TIMEOUT_MS", 50)
    with pytest.raises(StoreUnavailable, match="database is locked"):
        sql_engine._create_sqlite_file(tmp_path / "other.db")
