"""Prometheus metrics of the HTTP server (`GET /metrics`).

| metric | type | labels | what |
|---|---|---|---|
| `coexist_http_requests_total` | counter | route, method, status | requests answered |
| `coexist_http_request_seconds` | histogram | route | latency, from the first byte in to the response's last byte out (a stream's whole length), 50 µs to 60 s |
| `coexist_engine_*_total` | counter | | engine counters (rows, errors, cache hits/misses, loads, reloads ...) |
| `coexist_engine_models_loaded` | gauge | | networks in the weights cache |
| `coexist_store_reachable` | gauge | | 1 while the model store answers, else 0 (what `/readyz` checks) |
| `coexist_model_version_served` | gauge | model (name@alias) | the version each alias resolves to now |
| `coexist_sessions_live` | gauge | | goal-inference sessions held (expired ones purged first) |
| `coexist_sessions_max` | gauge | | the limit (`COEXIST_MAX_SESSIONS`) |

| `coexist_grpc_requests_total` | counter | method, code | gRPC calls answered (`/coexist.v1.PolicyService/Act`, `OK`) |
| `coexist_grpc_request_seconds` | histogram | method | latency, from the handler's start to its end (a stream's last answer) |
| `process_*` | gauge, counter | | this process: CPU seconds, resident and virtual memory, open and maximum file descriptors, start time (prometheus_client's process collector, Linux) |

The engine's counters are read when Prometheus scrapes (a collector), so the request path pays
nothing for them.

Several workers (`coexist serve --workers N`): the request counters and histograms (HTTP and
gRPC) use prometheus_client's multiprocess mode. `cli/serve.py` points `PROMETHEUS_MULTIPROC_DIR`
at a directory it empties at start (`prepare_multiprocess_dir`), each worker writes its values
to its own files there, and a scrape, whichever worker takes it, sums every worker's files
(`scrape_registry`). The engine and session figures stay per process (they describe the process
that answers: its cache, its sessions; with a shared session store, `coexist_sessions_live` counts
the deployment's).
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from prometheus_client import CollectorRegistry, Counter, Histogram, ProcessCollector
from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily, Metric
from prometheus_client.registry import Collector

from services.engine import InferenceEngine
from services.sessions import SessionStore, SessionStoreUnavailable, SharedSessionStore

MULTIPROC_ENV = "PROMETHEUS_MULTIPROC_DIR"
# Latency buckets from 50 µs to 60 s: single acts take well under a millisecond, while a streamed
# episode (timed to its last byte), an upload or a whole gRPC `Episode` stream takes seconds to
# tens of seconds; beyond the last bucket only `+Inf` would tell.
LATENCY_BUCKETS = (
    5e-5,
    1e-4,
    2e-4,
    5e-4,
    1e-3,
    2e-3,
    5e-3,
    1e-2,
    2.5e-2,
    0.1,
    0.25,
    1.0,
    2.5,
    5.0,
    10.0,
    30.0,
    60.0,
)


def multiprocess_dir() -> str | None:
    """The multiprocess directory when this process runs in prometheus_client's multiprocess
    mode (set before prometheus_client was imported, as the workers of `coexist serve` are)."""
    return os.environ.get(MULTIPROC_ENV) or None


def prepare_multiprocess_dir(default: Path) -> Path:
    """Set up multiprocess mode for the workers about to start: `PROMETHEUS_MULTIPROC_DIR` (the
    caller's, else `default`), created and emptied of an earlier run's files (counts of dead
    processes would otherwise be added to this run's), and exported for the workers."""
    directory = Path(os.environ.get(MULTIPROC_ENV) or default)
    directory.mkdir(parents=True, exist_ok=True)
    for stale in directory.glob("*.db"):
        stale.unlink()
    os.environ[MULTIPROC_ENV] = str(directory)
    return directory


def request_registry(app_registry: CollectorRegistry) -> CollectorRegistry | None:
    """Where the request metrics register: the app's registry, or none in multiprocess mode
    (their values go to this process's files, which `scrape_registry` reads back)."""
    return None if multiprocess_dir() else app_registry


def scrape_registry(app_registry: CollectorRegistry) -> CollectorRegistry:
    """What `/metrics` serves: the app's registry, or in multiprocess mode a registry summing
    every worker's files plus this process's own collectors (engine, sessions)."""
    if not multiprocess_dir():
        return app_registry
    from prometheus_client import multiprocess

    merged = CollectorRegistry()
    multiprocess.MultiProcessCollector(merged)
    merged.register(_Collectors(app_registry))
    return merged


class _Collectors(Collector):
    """Another registry's collectors, collected as one (the per-process ones, in multiprocess
    mode: the request metrics are not registered there, see `request_registry`)."""

    def __init__(self, registry: CollectorRegistry) -> None:
        self.registry = registry

    def collect(self) -> Iterator[Metric]:
        yield from self.registry.collect()


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
        reachable = GaugeMetricFamily(
            "coexist_store_reachable", "1 while the model store answers, else 0 (as /readyz)"
        )
        reachable.add_metric([], 1.0 if status.store_reachable else 0.0)
        yield reachable
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
    """Exports how many sessions the store holds, at scrape time: this process's (in memory),
    or the deployment's (a shared store; left out while it does not answer)."""

    def __init__(self, store_of: Callable[[], SessionStore | SharedSessionStore | None]) -> None:
        self.store_of = store_of

    def collect(self) -> Iterator[Metric]:
        store = self.store_of()
        if store is None:
            return
        try:
            store.purge_expired()  # an expired session is gone: do not count it
            count = len(store)
        except SessionStoreUnavailable:  # the sessions' routes answer 503 naming it
            return
        live = GaugeMetricFamily("coexist_sessions_live", "goal-inference sessions held")
        live.add_metric([], count)
        yield live
        limit = GaugeMetricFamily("coexist_sessions_max", "the most sessions the store holds")
        limit.add_metric([], store.max_sessions)
        yield limit


class HttpMetrics:
    """HTTP request counters and latency histograms, fed by `RequestIdMiddleware` (`record`).

    The labelled children are kept in a dict keyed by (route, method, status), so a request
    costs one dict lookup, one counter increment and one histogram observation: no label
    validation per request (prometheus_client's `labels()` does that on every call).
    """

    def __init__(self, registry: CollectorRegistry | None) -> None:
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
        self._children: dict[tuple[str, str, int], tuple[Any, Any]] = {}

    def record(self, route: str, method: str, status: int, seconds: float) -> None:
        """Count one answered request and observe its latency (seconds to the response start)."""
        key = (route, method, status)
        children = self._children.get(key)
        if children is None:
            children = (
                self.requests.labels(route, method, str(status)),
                self.latency.labels(route),
            )
            self._children[key] = children
        children[0].inc()
        children[1].observe(seconds)


class GrpcMetrics:
    """gRPC call counters and latency histograms, fed by the gRPC server's interceptor.

    `method` is the full method name (`/coexist.v1.PolicyService/Act`), `code` the status code's
    name (`OK`, `INVALID_ARGUMENT` ...); the latency runs from the handler's start to its return
    (for a stream, to its last answer). Children are cached as in `HttpMetrics`; the cache is
    filled under a lock, since grpcio's handlers run on a thread pool.
    """

    def __init__(self, registry: CollectorRegistry | None) -> None:
        self.requests = Counter(
            "coexist_grpc_requests", "gRPC calls answered", ["method", "code"], registry=registry
        )
        self.latency = Histogram(
            "coexist_grpc_request_seconds",
            "gRPC call latency",
            ["method"],
            buckets=LATENCY_BUCKETS,
            registry=registry,
        )
        self._children: dict[tuple[str, str], tuple[Any, Any]] = {}
        self._lock = threading.Lock()

    def record(self, method: str, code: str, seconds: float) -> None:
        """Count one finished call and observe its latency in seconds."""
        children = self._children.get((method, code))
        if children is None:
            with self._lock:
                children = (self.requests.labels(method, code), self.latency.labels(method))
                self._children[method, code] = children
        children[0].inc()
        children[1].observe(seconds)


def register_process_metrics(registry: CollectorRegistry) -> None:
    """CPU, memory and open file descriptors of this process (`process_*`, read from /proc at
    scrape time: nothing per request). In multiprocess mode each worker's are its own: the
    process that answers the scrape."""
    ProcessCollector(registry=registry)
