"""Latency and throughput of `InferenceEngine.act` (no transport): batch 1 and batch 256.

Run: `.venv/bin/python benchmarks/engine.py [--repeats 5] [--calls 2000] [--hidden 128,128]`
(or `--store-url URL` to use a registered zoo that has the networks of the cases below).

| case            | request                                                                  |
|-----------------|--------------------------------------------------------------------------|
| sl, batch 1     | ego `a2` in a 5-agent world, 4 partners announced (ignored by SL), seeded |
| aail, batch 1   | the same with AAIL: task net + 4 impact nets (`b3`, `c1`, `d4`, `e0`)     |
| * batch 256     | 256 observations in one call; figure = actions (rows) per second          |
| blend alone     | `policy.blend.blend("aail", ...)` on the batch-1 shapes, for comparison   |

BLAS threads: run with `OPENBLAS_NUM_THREADS=1` to measure what one server worker per core sees;
with the default (one thread per core) batch-256 figures collapse whenever the cores are busy.

Networks get the trainer's default architecture (MLP 8-128-128-5) with random weights in a
temporary SQLite store; the caches are warmed before timing. Latency: per-call wall time,
p50/p90 of `calls` calls; each case runs `repeats` times and the table shows the median over the
repeats (and the min..max of the p50s).
"""

from __future__ import annotations

import argparse
import functools
import os
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

from model_store.entities import Lineage
from model_store.naming import impact_model_name, task_model_name
from model_store.sql import SqlModelStore
from model_store.store import ModelStore
from model_store.testing import qnet_spec, qnet_weights
from policy.blend import blend
from services.engine import ActRequest, InferenceEngine, PartnerSpec

EGO, PARTNER_GOALS = "a2", ("b3", "c1", "d4", "e0")


def build_zoo(store: ModelStore, hidden: tuple[int, ...]) -> None:
    spec = qnet_spec(obs_dim=8, n_actions=5, hidden=hidden)
    models = [(task_model_name("particle", EGO), "task", EGO)] + [
        (impact_model_name("particle", g), "impact", g) for g in PARTNER_GOALS
    ]
    for seed, (name, kind, goal) in enumerate(models):
        store.create_model(name, env="particle", kind=kind, goals=[goal], obs_dim=8, n_actions=5)
        store.register_version(
            name,
            spec=spec,
            weights=qnet_weights(spec, seed=seed),
            lineage=Lineage(config={"alpha": 0.02}),
            aliases=("latest", "production"),
        )


def latencies(call: Callable[[], object], calls: int) -> list[float]:
    """Wall time of each call, in seconds."""
    times = []
    for _ in range(calls):
        start = time.perf_counter()
        call()
        times.append(time.perf_counter() - start)
    return times


def request(method: str, batch: int) -> ActRequest:
    obs = np.random.default_rng(batch).random((batch, 20)).astype(np.float32)
    partners = tuple(PartnerSpec(i + 1, goal=g) for i, g in enumerate(PARTNER_GOALS))
    return ActRequest("particle", EGO, obs, partners, method=method, seed=1)  # type: ignore[arg-type]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--calls", type=int, default=2000, help="calls per batch-1 repeat")
    parser.add_argument("--hidden", default="128,128", help="hidden sizes of the random zoo")
    parser.add_argument("--store-url", default=None, help="use this store instead")
    args = parser.parse_args()
    hidden = tuple(int(h) for h in args.hidden.split(","))

    with tempfile.TemporaryDirectory() as tmp:
        url = args.store_url or f"sqlite:///{Path(tmp) / 'models.db'}"
        with SqlModelStore(url) as store:
            if not args.store_url:
                build_zoo(store, hidden)
            engine = InferenceEngine(store)
            threads = os.environ.get("OPENBLAS_NUM_THREADS", "default")
            table = Table(
                title=f"InferenceEngine.act, 1 ego + 4 partners, MLP 8-{args.hidden}-5, "
                f"OPENBLAS_NUM_THREADS={threads}"
            )
            for column in ("case", "p50 µs", "p90 µs", "actions/s", "p50 spread µs"):
                table.add_column(column, justify="left" if column == "case" else "right")
            for method in ("sl", "aail"):
                one = request(method, 1)
                engine.act(one)  # warm the caches
                runs = [
                    latencies(functools.partial(engine.act, one), args.calls)
                    for _ in range(args.repeats)
                ]
                add_latency_row(table, f"{method}, batch 1", runs, rows=1)
            qt = np.random.default_rng(0).normal(size=(1, 5))
            qi = np.random.default_rng(1).normal(size=(1, 4, 5))
            runs = [
                latencies(lambda: blend("aail", qt, qi, 0.02), args.calls)
                for _ in range(args.repeats)
            ]
            add_latency_row(table, "policy.blend aail alone, batch 1", runs, rows=1)
            for method in ("sl", "aail"):
                big = request(method, 256)
                engine.act(big)
                calls = max(20, args.calls // 40)
                runs = [
                    latencies(functools.partial(engine.act, big), calls)
                    for _ in range(args.repeats)
                ]
                add_latency_row(table, f"{method}, batch 256", runs, rows=256)
    Console().print(table)


def add_latency_row(table: Table, label: str, runs: list[list[float]], rows: int) -> None:
    p50s = [float(np.percentile(r, 50)) for r in runs]
    p90s = [float(np.percentile(r, 90)) for r in runs]
    rates = [rows * len(r) / sum(r) for r in runs]
    table.add_row(
        label,
        f"{statistics.median(p50s) * 1e6:,.0f}",
        f"{statistics.median(p90s) * 1e6:,.0f}",
        f"{statistics.median(rates):,.0f}",
        f"{min(p50s) * 1e6:,.0f}..{max(p50s) * 1e6:,.0f}",
    )


if __name__ == "__main__":
    main()
