"""`coexist_sessions_live` / `coexist_sessions_max`: the sessions a process holds, expired ones
not counted, read at scrape time (`services.metrics.SessionCollector`)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from prometheus_client import CollectorRegistry, generate_latest
from session_zoo import session_zoo_template

from model_store.sql import SqlModelStore
from services.engine import InferenceEngine
from services.metrics import SessionCollector
from services.sessions import SessionPartner, SessionSettings, SessionStore

SETTINGS = SessionSettings(env="particle", ego_goal="a2", partners=(SessionPartner(1, infer=True),))


@pytest.fixture(scope="module")
def engine(tmp_path_factory: pytest.TempPathFactory) -> Iterator[InferenceEngine]:
    with SqlModelStore(f"sqlite:///{session_zoo_template(tmp_path_factory)}") as store:
        yield InferenceEngine(store)


def _gauges(registry: CollectorRegistry) -> dict[str, float]:
    lines = generate_latest(registry).decode().splitlines()
    return {
        line.split()[0]: float(line.split()[1])
        for line in lines
        if line.startswith("coexist_sessions_")
    }


def test_live_sessions_are_counted_and_expired_ones_are_not(engine: InferenceEngine) -> None:
    now = [100.0]
    store = SessionStore(engine, max_sessions=7, ttl_s=10.0, clock=lambda: now[0])
    registry = CollectorRegistry()
    registry.register(SessionCollector(lambda: store))
    assert _gauges(registry) == {"coexist_sessions_live": 0.0, "coexist_sessions_max": 7.0}
    store.create(SETTINGS)
    now[0] += 6.0
    second = store.create(SETTINGS)
    assert _gauges(registry)["coexist_sessions_live"] == 2.0
    now[0] += 6.0  # the first one has been idle 12 s > 10 s
    assert _gauges(registry)["coexist_sessions_live"] == 1.0
    store.delete(second.session_id)
    assert _gauges(registry)["coexist_sessions_live"] == 0.0


def test_no_store_no_gauges() -> None:
    registry = CollectorRegistry()
    registry.register(SessionCollector(lambda: None))
    assert _gauges(registry) == {}
