"""Prometheus metrics of the HTTP server (`GET /metrics`).

| metric | type | labels | what |
|---|---|---|---|
| `coexist_http_requests_total` | counter | route, method, status | requests answered |
| `coexist_http_request_seconds` | histogram | route | latency, from the first byte in to the response start |
| `coexist_engine_*_total` | counter | | engine counters (rows, errors, cache hits/misses, loads, reloads ...) |
| `coexist_engine_models_loaded` | gauge | | networks in the weights cache |
| `coexist_model_version_served` | gauge | model (name@alias) | the version each alias resolves to now |
| `coexist_sessions_live` | gauge | | goal-inference sessions held (expired ones purged first) |
| `coexist_sessions_max` | gauge | | the limit (`COEXIST_MAX_SESSIONS`) |

The engine's counters are read when Prometheus scrapes (a collector), so the request path pays
nothing for them. Each process keeps its own registry: with several uvicorn workers a scrape
answers for the worker that took it (label your scrape targets per worker, or run one worker per
container as docker/ does).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from typing import Any

from prometheus_client import CollectorRegistry, Counter, Histogram
from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily, Metric
from prometheus_client.registry import Collector

from services.engine import InferenceEngine
from services.logging import route_template
from services.sessions import SessionStore

# Latency buckets from 50 µs to 1 s: single acts take well under a millisecond.
LATENCY_BUCKETS = (5e-5, 1e-4, 2e-4, 5e-4, 1e-3, 2e-3, 5e-3, 1e-2, 2.5e-2, 0.1, 0.25, 1.0)


class EngineCollector(Collector):
    """Exports the engine's counters and served versions at scrape time."""

    def __init__(self, engine_of: Callable[[], InferenceEngine | None]) -> None:
        self.engine_of = engine_of

    def collect(self) -> Iterator[Metric]:
        engine = self.engine_of()
        if engine is None:
            return
        stats = vars(engine.stats.snapshot())
        for name, value in stats.items():
            counter = CounterMetricFamily(f"coexist_engine_{name}", f"engine counter {name}")
            counter.add_metric([], value)
            yield counter
        status = engine.status()
        loaded = GaugeMetricFamily("coexist_engine_models_loaded", "networks in the weights cache")
        loaded.add_metric([], status.models_loaded)
        yield loaded
        served = GaugeMetricFamily(
            "coexist_model_version_served", "version served per name@alias", labels=["model"]
        )
        for ref, version in sorted(status.versions_served.items()):
            served.add_metric([ref], version)
        yield served


class SessionCollector(Collector):
    """Exports how many sessions this process holds, at scrape time."""

    def __init__(self, store_of: Callable[[], SessionStore | None]) -> None:
        self.store_of = store_of

    def collect(self) -> Iterator[Metric]:
        store = self.store_of()
        if store is None:
            return
        store.purge_expired()  # an expired session is gone: do not count it
        live = GaugeMetricFamily("coexist_sessions_live", "goal-inference sessions held")
        live.add_metric([], len(store))
        yield live
        limit = GaugeMetricFamily("coexist_sessions_max", "the most sessions this process holds")
        limit.add_metric([], store.max_sessions)
        yield limit


class HttpMetrics:
    """Request counters and latency histograms, recorded by a small ASGI middleware."""

    def __init__(self, registry: CollectorRegistry) -> None:
        self.requests = Counter(
            "coexist_http_requests",
            "HTTP requests answered",
            ["route", "method", "status"],
            registry=registry,
        )
        self.latency = Histogram(
            "coexist_http_request_seconds",
            "HTTP request latency",
            ["route"],
            buckets=LATENCY_BUCKETS,
            registry=registry,
        )

    def middleware(self, app: Any) -> Any:
        """Wrap an ASGI app; the route label is the matched route's path template."""

        async def wrapped(scope: dict[str, Any], receive: Any, send: Any) -> None:
            if scope["type"] != "http":
                await app(scope, receive, send)
                return
            start = time.perf_counter()
            status = 500

            async def send_and_record(message: dict[str, Any]) -> None:
                nonlocal status
                if message["type"] == "http.response.start":
                    status = message["status"]
                    label = route_template(scope) or "unmatched"
                    self.latency.labels(label).observe(time.perf_counter() - start)
                    self.requests.labels(label, scope["method"], str(status)).inc()
                await send(message)

            await app(scope, receive, send_and_record)

        return wrapped
