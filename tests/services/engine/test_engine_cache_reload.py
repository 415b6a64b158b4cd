"""Resolution, caching and hot reload: aliases and pinned versions, the LRU bound, moving the
production alias under a concurrent reader, store outages during refresh, status and stats."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from model_store.errors import ChecksumMismatch, StoreUnavailable
from services.engine import (
    ActRequest,
    InferenceEngine,
    InvalidRequest,
    ModelNotFound,
    ModelUnavailable,
    PartnerSpec,
)

TASK_A2 = "particle/task/a2"
OBS = np.random.default_rng(0).random((1, 8))
PARTNER = (PartnerSpec(1, goal="b3"),)


def _act(engine: InferenceEngine, goal: str = "a2", **kw):
    [result] = engine.act(ActRequest("particle", goal, OBS, PARTNER, **kw))
    return result


def _versions(result) -> dict[str, int]:
    return {m.name: m.version for m in result.models}


def test_alias_and_pinned_versions(tiny_zoo) -> None:
    engine = InferenceEngine(tiny_zoo.store)
    production = _act(engine)
    assert _versions(production) == {TASK_A2: 1, "particle/impact/b3": 1}
    latest = _act(engine, alias="latest")
    assert _versions(latest)[TASK_A2] == 2
    pinned = _act(engine, versions={TASK_A2: 2})
    assert _versions(pinned)[TASK_A2] == 2
    assert pinned.probs == latest.probs != production.probs
    v2 = tiny_zoo.store.get_version(TASK_A2, 2)
    assert pinned.models[0].sha256 == v2.sha256
    with pytest.raises(ModelNotFound) as err:
        _act(engine, versions={TASK_A2: 7})
    assert err.value.field == f"versions[{TASK_A2}]" and err.value.ref == f"{TASK_A2}/7"
    with pytest.raises(ModelNotFound) as err:
        _act(engine, alias="staging")
    assert err.value.field == "ego_goal" and "staging" in str(err.value)
    for unused in ("particle/task/zz", "particle/impact/c1"):  # unknown, or not this request's
        with pytest.raises(InvalidRequest) as refused:
            _act(engine, versions={TASK_A2: 2, unused: 1})
        assert refused.value.field == f"versions[{unused}]"


def test_missing_networks_name_the_field(tiny_zoo) -> None:
    engine = InferenceEngine(tiny_zoo.store)
    with pytest.raises(ModelNotFound) as err:
        _act(engine, goal="a0")
    assert (err.value.field, err.value.name) == ("ego_goal", "particle/task/a0")
    with pytest.raises(ModelNotFound) as err:
        engine.act(
            ActRequest("particle", "a2", OBS, (PartnerSpec(1, goal_probs={"b3": 0.5, "a1": 0.5}),))
        )
    assert (err.value.field, err.value.name) == ("partners[0].goal_probs", "particle/impact/a1")
    with pytest.raises(ModelNotFound) as err:  # a goal no model name can hold
        _act(engine, goal="3")
    assert err.value.field == "ego_goal"
    with pytest.raises(ModelNotFound) as err:
        engine.act(ActRequest("particle", "a2", OBS, (PartnerSpec(1, goal="c1"),), method="jl"))
    assert err.value.field == "method" and "joint" in err.value.message
    assert engine.stats.errors == 4


def test_lru_bounds_loaded_networks_and_stacks(tiny_zoo) -> None:
    engine = InferenceEngine(tiny_zoo.store, cache_size=2, stack_cache_size=1)
    for goal in ("a2", "b3", "c1"):
        _act(engine, goal=goal, method="sl")
    assert engine.status().models_loaded == 2
    assert engine.stats.loads == 3
    _act(engine, goal="c1", method="sl")  # the stacked group is still cached: nothing loaded
    assert (engine.stats.loads, engine.stats.stack_hits) == (3, 1)
    _act(engine, goal="a2", method="sl")  # evicted from both caches: loaded again
    assert engine.stats.loads == 4
    assert engine.status().models_loaded == 2
    _act(engine, goal="c1", method="aail")  # a group of two: task c1 (cached) + impact b3
    assert engine.stats.loads == 5 and engine.stats.cache_hits >= 1


def test_hot_reload_swaps_to_the_new_version(tiny_zoo) -> None:
    store = tiny_zoo.store
    engine = InferenceEngine(store)
    before = _act(engine)
    assert engine.refresh() is False  # nothing changed
    store.set_alias(TASK_A2, "production", 2)
    assert _versions(_act(engine))[TASK_A2] == 1  # cached until the refresh
    assert engine.refresh() is True
    after = _act(engine)
    assert _versions(after)[TASK_A2] == 2 and after.probs != before.probs
    assert engine.status().versions_served[f"{TASK_A2}@production"] == 2
    assert engine.stats.reloads == 1
    assert engine.refresh() is False
    store.delete_alias(TASK_A2, "production")
    assert engine.refresh() is True
    with pytest.raises(ModelNotFound):
        _act(engine)


def test_fixed_sets_serve_repeated_requests_and_follow_a_reload(tiny_zoo) -> None:
    """A request shape asked again resolves its networks as one fixed set (the per-name
    counters); a group evicted from the stack LRU is stacked again; a reload voids the set."""
    store = tiny_zoo.store
    engine = InferenceEngine(store, stack_cache_size=1)
    probs = {"a2": 0.2, "b3": 0.3, "c1": 0.5}
    request = ActRequest("particle", "a2", OBS, (PartnerSpec(1, goal_probs=probs),), seed=3)
    [first] = engine.act(request)
    hits, stack_hits = engine.stats.resolve_hits, engine.stats.stack_hits
    assert engine.act(request) == [first]
    assert (engine.stats.resolve_hits, engine.stats.stack_hits) == (hits + 4, stack_hits + 1)
    _act(engine, goal="c1", method="sl")  # another group evicts this one (one stack slot)
    misses, loads = engine.stats.stack_misses, engine.stats.loads
    assert engine.act(request) == [first]
    assert (engine.stats.stack_misses, engine.stats.loads) == (misses + 1, loads)
    store.set_alias(TASK_A2, "production", 2)
    assert _versions(engine.act(request)[0])[TASK_A2] == 1  # cached until the refresh
    assert engine.refresh() is True
    [after] = engine.act(request)
    assert _versions(after)[TASK_A2] == 2 and after.probs != first.probs


def test_hot_reload_under_a_concurrent_reader(tiny_zoo) -> None:
    store = tiny_zoo.store
    engine = InferenceEngine(store)
    seen: set[int] = set()
    errors: list[BaseException] = []
    stop = threading.Event()

    def reader() -> None:
        while not stop.is_set():
            try:
                seen.add(_versions(_act(engine))[TASK_A2])
            except BaseException as exc:
                errors.append(exc)
                return

    thread = threading.Thread(target=reader)
    thread.start()
    try:
        for version in (2, 1, 2):
            time.sleep(0.02)
            store.set_alias(TASK_A2, "production", version)
            assert engine.refresh() is True
    finally:
        time.sleep(0.02)
        stop.set()
        thread.join()
    assert errors == []
    assert seen == {1, 2}
    assert _versions(_act(engine))[TASK_A2] == 2


def test_refresh_thread_picks_up_a_moved_alias(tiny_zoo) -> None:
    engine = InferenceEngine(tiny_zoo.store, refresh_interval_s=0.02)
    _act(engine)
    engine.start_refresh_thread()
    engine.start_refresh_thread()  # idempotent
    try:
        assert engine.status().refresh_thread_alive
        tiny_zoo.store.set_alias(TASK_A2, "production", 2)
        deadline = time.monotonic() + 5
        while _versions(_act(engine))[TASK_A2] != 2:
            assert time.monotonic() < deadline, "the refresh thread did not reload"
            time.sleep(0.01)
    finally:
        engine.stop()
    assert not engine.status().refresh_thread_alive


def test_store_outage_during_refresh_is_retried(tiny_zoo, monkeypatch) -> None:
    store = tiny_zoo.store
    engine = InferenceEngine(store)
    _act(engine)
    store.set_alias(TASK_A2, "production", 2)
    real_token = store.change_token

    def down() -> str:
        raise StoreUnavailable("database is gone")

    monkeypatch.setattr(store, "change_token", down)
    assert engine.refresh() is False
    assert engine.stats.refresh_errors == 1
    status = engine.status()
    assert not status.store_reachable and "gone" in (status.store_error or "")
    assert _versions(_act(engine))[TASK_A2] == 1  # still serving from the cache
    monkeypatch.setattr(store, "change_token", real_token)
    assert engine.refresh() is True
    assert _versions(_act(engine))[TASK_A2] == 2
    assert engine.status().store_reachable


def test_a_corrupt_new_version_keeps_the_old_one(tiny_zoo, monkeypatch) -> None:
    store = tiny_zoo.store
    engine = InferenceEngine(store)
    _act(engine)
    real_load = store.load_weights

    def load(name: str, version: int) -> bytes:
        if (name, version) == (TASK_A2, 2):
            raise ChecksumMismatch("tampered")
        return real_load(name, version)

    monkeypatch.setattr(store, "load_weights", load)
    store.set_alias(TASK_A2, "production", 2)
    assert engine.refresh() is False
    assert _versions(_act(engine))[TASK_A2] == 1
    monkeypatch.setattr(store, "load_weights", real_load)
    assert engine.refresh() is True  # the token was not advanced: the move is retried
    assert _versions(_act(engine))[TASK_A2] == 2


def test_load_failure_is_model_unavailable(tiny_zoo, monkeypatch) -> None:
    engine = InferenceEngine(tiny_zoo.store)

    def broken(name: str, version: int) -> bytes:
        raise StoreUnavailable("database is gone")

    monkeypatch.setattr(tiny_zoo.store, "load_weights", broken)
    with pytest.raises(ModelUnavailable):
        _act(engine)
    assert engine.stats.load_failures == 1


def test_status_stats_and_envs(tiny_zoo) -> None:
    engine = InferenceEngine(tiny_zoo.store)
    empty = engine.status()
    assert empty.store_reachable and empty.models_loaded == 0 and empty.versions_served == {}
    _act(engine)
    _act(engine)
    status = engine.status()
    assert status.models_loaded == 2
    assert status.versions_served == {
        "particle/impact/b3@production": 1,
        f"{TASK_A2}@production": 1,
    }
    stats = engine.stats.snapshot()
    assert (stats.requests, stats.rows, stats.loads, stats.cache_misses) == (2, 2, 2, 2)
    assert (stats.resolve_misses, stats.resolve_hits, stats.stack_hits) == (2, 2, 1)
    [info] = [e for e in engine.envs() if e.name == "particle"]
    assert info.name == "particle" and len(info.goals) == 35 and info.max_agents == 5
    assert info.action_meanings == ("rest", "up", "down", "left", "right")
    assert info.obs_dims == {1: 4, 2: 8, 3: 12, 4: 16, 5: 20}
    assert info.observation_layouts[2] == [
        "self.x",
        "self.y",
        "self.vx",
        "self.vy",
        "other1.x",
        "other1.y",
        "other1.vx",
        "other1.vy",
    ]
    assert info.state_layout == ("x", "y", "vx", "vy")
    assert info.methods == ("aail_bounded", "aail_budget", "aail", "nail", "sl", "jl")


@pytest.mark.parametrize(
    "kwargs",
    [{"cache_size": 0}, {"stack_cache_size": 0}, {"refresh_interval_s": 0}, {"max_batch": 0}],
)
def test_constructor_rejects_bad_settings(tiny_zoo, kwargs) -> None:
    with pytest.raises(ValueError, match=next(iter(kwargs))):
        InferenceEngine(tiny_zoo.store, **kwargs)
