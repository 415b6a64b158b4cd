"""`publish_once`: attempts of one job that finish together register each network once.

Runs without Ray: four threads, each with its own store connection (as four workers would have),
publish the same trained batch with the same job key at the same moment, on SQLite (flock) and on
PostgreSQL (advisory lock, a fresh schema per test).
"""

from __future__ import annotations

import os
import threading
import uuid
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import psycopg
import pytest
from sqlalchemy.engine import make_url

from model_store.sql import SqlModelStore
from trainer.backends.once import JOB_CONFIG_KEY, lock_id, publish_lock, publish_once
from trainer.config import TaskConfig
from trainer.learners import TrainedBatch, train_tasks

PG_URL = os.environ.get("COEXIST_TEST_PG_URL", "postgresql://postgres@127.0.0.1:5432/test")
ATTEMPTS = 4


@pytest.fixture(scope="module")
def batch() -> TrainedBatch:
    config = replace(TaskConfig(), total_steps=20, warmup_steps=5, envs_per_net=2, hidden=(8,))
    return train_tasks(["a2", "b3"], config, seed=3, evaluate=False)


@pytest.fixture(params=["sqlite", pytest.param("postgres", marks=pytest.mark.postgres)])
def store_url(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[str]:
    if request.param == "sqlite":
        yield f"sqlite:///{tmp_path / 'store' / 'models.db'}"
        return
    try:
        with psycopg.connect(PG_URL, autocommit=True, connect_timeout=3) as conn:
            schema = f"coexist_once_{uuid.uuid4().hex[:12]}"
            conn.execute(f'CREATE SCHEMA "{schema}"')
    except psycopg.Error as exc:
        if os.environ.get("COEXIST_REQUIRE_POSTGRES"):
            raise
        pytest.skip(f"PostgreSQL not reachable at {PG_URL}: {exc}")
    url = make_url(PG_URL).update_query_dict({"options": f"-csearch_path={schema}"})
    yield url.render_as_string(hide_password=False)
    with psycopg.connect(PG_URL, autocommit=True) as conn:
        conn.execute(f'DROP SCHEMA IF EXISTS "{schema}" CASCADE')


def _publish_together(store_url: str, batch: TrainedBatch, job_key: str) -> list[list[str]]:
    SqlModelStore(store_url).close()  # create the schema before the race
    start = threading.Barrier(ATTEMPTS)
    results: list[list[str]] = []
    errors: list[BaseException] = []

    def attempt() -> None:
        try:
            with SqlModelStore(store_url) as store:
                start.wait()
                versions = publish_once(store, store_url, batch, job_key=job_key, env="particle")
                results.append([v.ref for v in versions])
        except BaseException as exc:  # surfaced below
            errors.append(exc)

    threads = [threading.Thread(target=attempt) for _ in range(ATTEMPTS)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=60)
    assert not errors, errors
    return results


def test_attempts_finishing_together_register_each_network_once(
    store_url: str, batch: TrainedBatch
) -> None:
    results = _publish_together(store_url, batch, "run-a/task:a2,b3")
    assert results == [["particle/task/a2/1", "particle/task/b3/1"]] * ATTEMPTS
    with SqlModelStore(store_url) as store:
        for goal in ("a2", "b3"):
            versions = store.list_versions(f"particle/task/{goal}")
            assert [v.version for v in versions] == [1]
            assert versions[0].lineage.config[JOB_CONFIG_KEY] == "run-a/task:a2,b3"
            assert store.get_model(f"particle/task/{goal}").aliases["latest"] == 1
    # another run (another job key) is new work: new versions
    again = _publish_together(store_url, batch, "run-b/task:a2,b3")
    assert again == [["particle/task/a2/2", "particle/task/b3/2"]] * ATTEMPTS


def test_a_goal_twice_in_one_batch_is_two_networks_registered_once_each(
    store_url: str,
) -> None:
    # a gate retry's batch holds each failed goal twice (trainer.zoo.retry_batches)
    config = replace(TaskConfig(), total_steps=20, warmup_steps=5, envs_per_net=2, hidden=(8,))
    twice = train_tasks(["a2", "a2"], config, seed=4, evaluate=False)
    results = _publish_together(store_url, twice, "run-c/task-retry-1:0")
    assert results == [["particle/task/a2/1", "particle/task/a2/2"]] * ATTEMPTS
    with SqlModelStore(store_url) as store:
        versions = sorted(store.list_versions("particle/task/a2"), key=lambda v: v.version)
        assert [v.version for v in versions] == [1, 2]
        assert versions[0].sha256 != versions[1].sha256  # two candidates, not one copied


def test_the_publish_lock_excludes_a_second_holder(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'models.db'}"
    SqlModelStore(url).close()
    inside = threading.Event()
    order: list[str] = []

    def second() -> None:
        inside.wait()
        with publish_lock(url, "k"):
            order.append("second")

    thread = threading.Thread(target=second)
    thread.start()
    with publish_lock(url, "k"):
        inside.set()
        thread.join(timeout=0.3)  # it must still be waiting for the lock
        order.append("first")
    thread.join(timeout=10)
    assert order == ["first", "second"]


def test_lock_ids_are_signed_64_bit_and_differ_per_job() -> None:
    ids = {lock_id(f"run/task:{g}") for g in ("a2", "b3", "c", "d4")}
    assert len(ids) == 4
    assert all(-(2**63) <= i < 2**63 for i in ids)
