"""The shared session store (services.sessions.shared) over Redis and PostgreSQL: two store
objects stand for two server processes on one store. A session stepped alternately through both
answers exactly as the in-memory store does; racing steps commit once; a foreign id, a tampered
or stale record and a store that does not answer are named errors that cost no other session."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from dataclasses import replace
from typing import Any

import numpy as np
import pytest
from serve_process import free_port
from session_backends import BACKENDS, drop_namespace, new_secret, shared_store_url
from session_zoo import random_observation, session_zoo_template

from model_store.sql import SqlModelStore
from services.engine import InferenceEngine
from services.sessions import (
    Observed,
    SessionLimitReached,
    SessionNotFound,
    SessionPartner,
    SessionSettings,
    SessionStateInvalid,
    SessionStore,
    SessionStoreUnavailable,
    SharedSessionStore,
    StepConflict,
)
from services.sessions.backends import SessionBackend, open_backend
from services.sessions.codec import FORMAT, SessionCodec

PARTNERS = (1, 2, 3, 4)  # a scene of five agents, every partner inferred
STEPS = 8


@pytest.fixture(scope="module")
def engine(tmp_path_factory: pytest.TempPathFactory) -> Iterator[InferenceEngine]:
    with SqlModelStore(f"sqlite:///{session_zoo_template(tmp_path_factory)}") as store:
        yield InferenceEngine(store)


@pytest.fixture(params=BACKENDS)
def url(request: pytest.FixtureRequest) -> Iterator[str]:
    with shared_store_url(request.param) as url:
        yield url


@pytest.fixture
def codec(url: str) -> Iterator[SessionCodec]:
    codec = SessionCodec(new_secret())
    yield codec
    drop_namespace(url, codec.namespace())


def shared(
    engine: InferenceEngine, url: str, codec: SessionCodec, **kwargs: Any
) -> SharedSessionStore:
    """A store object as one server process holds it: a connection of its own."""
    return SharedSessionStore(engine, open_backend(url, codec.namespace()), codec, **kwargs)


def settings(**changes: Any) -> SessionSettings:
    partners = tuple(SessionPartner(i, infer=True) for i in PARTNERS)
    return replace(SessionSettings("particle", "a2", partners, seed=11), **changes)


def inputs(seed: int) -> list[tuple[list[float], list[Observed]]]:
    rng = np.random.default_rng(seed)
    steps = []
    for t in range(STEPS):
        observed = [] if t == 0 else [Observed(i, int(rng.integers(5))) for i in PARTNERS]
        steps.append((random_observation(rng, len(PARTNERS) + 1).tolist(), observed))
    return steps


def answers(stores: list[Any], session: SessionSettings, seed: int) -> list[tuple[Any, ...]]:
    """Every step's probabilities, budget and beliefs, the stores taking turns (each after
    scoring the next step ahead, as the REST route does)."""
    session_id = stores[0].create(session).session_id
    out = []
    for t, (obs, observed) in enumerate(inputs(seed)):
        store = stores[t % len(stores)]
        answer = store.step(session_id, obs, observed, expected_step=t)
        store.prepare_next(session_id)
        result = answer.result
        out.append(
            (list(result.probs), result.action, result.budget_spent, answer.beliefs, answer.step)
        )
    return out


@pytest.mark.parametrize(
    "session",
    [settings(), settings(method="aail_budget", budget=0.4, seed=3)],
    ids=["aail_bounded", "aail_budget"],
)
def test_alternating_processes_answer_as_one(
    engine: InferenceEngine, url: str, codec: SessionCodec, session: SessionSettings
) -> None:
    expected = answers([SessionStore(engine)], session, seed=5)
    a, b = shared(engine, url, codec), shared(engine, url, codec)
    assert answers([a, b], session, seed=5) == expected
    # a third process that never saw the session restores it from the store alone
    c = shared(engine, url, codec)
    assert answers([a, c, b], session, seed=5) == expected


def test_the_state_survives_a_process_that_is_gone(
    engine: InferenceEngine, url: str, codec: SessionCodec
) -> None:
    steps = inputs(9)
    single = SessionStore(engine)
    ref_id = single.create(settings()).session_id
    expected = [single.step(ref_id, o, obs, t).result.probs for t, (o, obs) in enumerate(steps)]
    first = shared(engine, url, codec)
    session_id = first.create(settings()).session_id
    got = [first.step(session_id, o, obs, t).result.probs for t, (o, obs) in enumerate(steps[:4])]
    first.backend.close()
    del first  # its copies are gone with it
    second = shared(engine, url, codec)
    got += [
        second.step(session_id, o, obs, t + 4).result.probs for t, (o, obs) in enumerate(steps[4:])
    ]
    assert [list(p) for p in got] == [list(p) for p in expected]
    info = second.get(session_id)
    assert info.step == STEPS and all(b.updates == STEPS - 1 for b in info.beliefs)


class RaceBackend:
    """The real backend, except that each `replace` waits until both racers computed their
    step: two steps of one session arriving at once, on two processes."""

    def __init__(self, backend: SessionBackend, barrier: threading.Barrier) -> None:
        self.backend, self.barrier = backend, barrier
        self.url = backend.url

    def __getattr__(self, name: str) -> Any:
        return getattr(self.backend, name)

    def replace(self, *args: Any) -> Any:
        self.barrier.wait(timeout=30)
        return self.backend.replace(*args)


def test_racing_steps_commit_once(engine: InferenceEngine, url: str, codec: SessionCodec) -> None:
    barrier = threading.Barrier(2)
    backends = [RaceBackend(open_backend(url, codec.namespace()), barrier) for _ in range(2)]
    racers = [SharedSessionStore(engine, backend, codec) for backend in backends]
    session_id = racers[0].create(settings()).session_id
    (obs, _), (obs_1, observed_1) = inputs(3)[:2]
    outcomes: list[Any] = [None, None]

    def step(k: int) -> None:
        try:
            outcomes[k] = racers[k].step(session_id, obs)  # no expected_step: both try step 0
        except StepConflict as err:
            outcomes[k] = err

    threads = [threading.Thread(target=step, args=(k,)) for k in range(2)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    conflicts = [o for o in outcomes if isinstance(o, StepConflict)]
    assert len(conflicts) == 1, outcomes
    assert "at the same time" in str(conflicts[0])
    reader = shared(engine, url, codec)
    assert reader.get(session_id).step == 1  # applied once
    # the loser's process goes on from the winner's step
    lost = outcomes.index(conflicts[0])
    backends[lost].barrier = threading.Barrier(1)  # alone now
    assert racers[lost].step(session_id, obs_1, observed_1, expected_step=1).step == 1


def test_a_foreign_or_unknown_id_is_named(
    engine: InferenceEngine, url: str, codec: SessionCodec
) -> None:
    store = shared(engine, url, codec)
    live = store.create(settings()).session_id
    other = SessionCodec(new_secret())
    foreign = shared(engine, url, other).create(settings()).session_id
    try:
        for session_id in (foreign, "no-such-session", live.split(".")[0] + ".AAAAAAAAAAA"):
            with pytest.raises(SessionNotFound, match="this deployment did not issue it"):
                store.step(session_id, inputs(1)[0][0])
        unknown = codec.new_id()  # this deployment's kind of id, never created
        with pytest.raises(SessionNotFound, match="expired after 300 s idle, or was deleted"):
            store.get(unknown)
        assert store.step(live, inputs(1)[0][0]).step == 0  # the live one is untouched
    finally:
        drop_namespace(url, other.namespace())


def write_record(url: str, codec: SessionCodec, session_id: str, record: bytes) -> None:
    """Change a record in the store behind the servers' backs."""
    if url.startswith("redis"):
        import redis

        with redis.Redis.from_url(url) as client:
            key = f"coexist:{codec.namespace()}:s:{session_id}"
            client.hset(key, "r", record)
            client.hincrby(key, "v", 1)
    else:
        import psycopg

        with psycopg.connect(url, autocommit=True) as conn:
            conn.execute(
                "UPDATE coexist_sessions SET record = %s, version = version + 1 WHERE id = %s",
                (record, session_id),
            )


def read_record(store: SharedSessionStore, session_id: str) -> bytes:
    loaded = store.backend.load(session_id, 0, time.time())
    assert loaded is not None and loaded.record is not None
    return loaded.record


@pytest.mark.parametrize(
    ("change", "named"),
    [
        (lambda r: r[:-5] + bytes([r[-5] ^ 1]) + r[-4:], "integrity check"),
        (lambda r: b"CS0" + r[len(FORMAT) :], f"format 'CS0', this server reads {FORMAT.decode()}"),
        (lambda r: r[:20], "integrity check"),
    ],
    ids=["tampered", "other-format", "truncated"],
)
def test_a_bad_record_stops_its_session_alone(
    engine: InferenceEngine, url: str, codec: SessionCodec, change: Any, named: str
) -> None:
    a, b = shared(engine, url, codec), shared(engine, url, codec)
    bad, good = (a.create(settings()).session_id for _ in range(2))
    (obs, _), (obs_1, observed_1) = inputs(2)[:2]
    for session_id in (bad, good):
        a.step(session_id, obs)
    write_record(url, codec, bad, change(read_record(a, bad)))
    for store in (a, b):  # a must not trust its own copy: the stored version moved
        with pytest.raises(SessionStateInvalid, match=named) as err:
            store.step(bad, obs_1, observed_1)
        assert err.value.code == "session_state_invalid"
    assert b.step(good, obs_1, observed_1, expected_step=1).step == 1


def test_a_record_of_another_session_fails_its_tag(
    engine: InferenceEngine, url: str, codec: SessionCodec
) -> None:
    store = shared(engine, url, codec)
    one, two = (store.create(settings()).session_id for _ in range(2))
    write_record(url, codec, two, read_record(store, one))  # a copied record, validly signed
    with pytest.raises(SessionStateInvalid, match="integrity check"):
        shared(engine, url, codec).get(two)


def test_a_store_that_does_not_answer_is_named_and_loses_nothing(
    engine: InferenceEngine, url: str, codec: SessionCodec
) -> None:
    store = shared(engine, url, codec)
    session_id = store.create(settings()).session_id
    (obs, _), (obs_1, observed_1) = inputs(4)[:2]
    store.step(session_id, obs)
    scheme = url.split("://")[0]
    dead_url = f"{scheme}://user:pa55word-not-shown@127.0.0.1:{free_port()}/0"
    dead = shared(engine, dead_url, codec)
    started = time.monotonic()
    for call in (
        lambda: dead.create(settings()),
        lambda: dead.step(session_id, obs_1, observed_1),
        lambda: dead.get(session_id),
        lambda: dead.delete(session_id),
        lambda: len(dead),
    ):
        with pytest.raises(SessionStoreUnavailable) as err:
            call()
        assert "127.0.0.1" in str(err.value) and "did not answer" in str(err.value)
        assert "pa55word" not in str(err.value)
    assert time.monotonic() - started < 10  # refused at once, not waited on
    # the session went on untouched, on the store that answers
    assert store.step(session_id, obs_1, observed_1, expected_step=1).beliefs[0].updates == 1


def test_bounds_and_expiry(engine: InferenceEngine, url: str, codec: SessionCodec) -> None:
    ttl = 2.0  # real seconds: Redis expires the keys itself
    store = shared(engine, url, codec, max_sessions=3, max_per_client=2, ttl_s=ttl)
    first = store.create(settings(), client="10.0.0.1").session_id
    store.create(settings(), client="10.0.0.1")
    with pytest.raises(SessionLimitReached, match="this client holds its maximum of 2") as err:
        shared(engine, url, codec, max_sessions=3, max_per_client=2).create(
            settings(), client="10.0.0.1"
        )
    assert 0 < err.value.retry_after_s <= ttl
    store.create(settings(), client="10.0.0.2")
    with pytest.raises(SessionLimitReached, match="the server holds its maximum of 3"):
        store.create(settings(), client="10.0.0.3")
    assert len(store) == 3
    time.sleep(ttl + 0.3)
    with pytest.raises(SessionNotFound, match=r"expired after 2 s idle"):
        store.step(first, inputs(1)[0][0])
    assert len(store) == 0
    store.create(settings(), client="10.0.0.1")  # the slots freed up


def test_delete(engine: InferenceEngine, url: str, codec: SessionCodec) -> None:
    a, b = shared(engine, url, codec), shared(engine, url, codec)
    session_id = a.create(settings()).session_id
    a.step(session_id, inputs(1)[0][0])
    b.delete(session_id)
    with pytest.raises(SessionNotFound, match="or was deleted"):
        a.step(session_id, inputs(1)[1][0], expected_step=1)
    with pytest.raises(SessionNotFound):
        b.delete(session_id)


def test_a_failed_step_writes_nothing(
    engine: InferenceEngine, url: str, codec: SessionCodec
) -> None:
    a, b = shared(engine, url, codec), shared(engine, url, codec)
    session_id = a.create(settings()).session_id
    obs, _ = inputs(1)[0]
    with pytest.raises(StepConflict):
        a.step(session_id, obs, expected_step=3)
    with pytest.raises(Exception, match="observation"):
        a.step(session_id, [1.0, 2.0])
    assert b.get(session_id).step == 0
    assert a.step(session_id, obs, expected_step=0).step == 0
