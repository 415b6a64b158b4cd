"""Latency and throughput of `InferenceEngine.act` (no transport): batch 1 and batch 256.

Run: `OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/engine.py [--repeats 5] [--calls 2000]`
(`--hidden 128,128`; `--store-url URL` to use a registered zoo that has the networks below;
`--compare OLD_CHECKOUT` to measure another checkout of the repository in the same run).

| case              | request                                                                 |
|-------------------|-------------------------------------------------------------------------|
| sl, batch 1       | ego `a2` in a 5-agent world, 4 partners announced (ignored by SL), seeded|
| aail, batch 1     | the same with AAIL: task net + 4 impact nets (`b3`, `c1`, `d4`, `e0`)    |
| aail unseeded     | the same without a seed (no generator to build per request)             |
| aail_bounded      | the same with the default method, AAIL-B (`policy.regret_bound`)         |
| blend alone       | `policy.blend.blend("aail", ...)` on the batch-1 shapes (the checked    |
|                   | entry point: the compiled kernel where it is built, else numpy)         |
| blend vectorised  | `policy.blend.blend_vectorised`, the numpy reference, same shapes       |
| * batch 256       | 256 observations in one call; figure = actions (rows) per second        |

BLAS threads: run with `OPENBLAS_NUM_THREADS=1` to measure what one server worker per core sees;
with the default (one thread per core) batch-256 figures collapse whenever the cores are busy.

Networks get the trainer's default architecture (MLP 8-128-128-5) with random weights in a
temporary SQLite store; the caches are warmed before timing. Latency: per-call wall time,
p50/p90 of `calls` calls; each case runs `repeats` times and the table shows the median over the
repeats (and the min..max of the p50s).

`--compare` runs this script under the other checkout (`PYTHONPATH`), alternating with this one
repeat by repeat, so that both see the same machine load; the table then shows both p50s and
their ratio. Cases the other checkout lacks are left blank.
"""

from __future__ import annotations

import argparse
import functools
import importlib
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from machine import describe
from rich.console import Console
from rich.table import Table

from model_store.entities import Lineage
from model_store.naming import impact_model_name, task_model_name
from model_store.sql import SqlModelStore
from model_store.store import ModelStore
from model_store.testing import qnet_spec, qnet_weights
from services.engine import ActRequest, InferenceEngine, PartnerSpec

# the module (`policy` re-exports the function `blend` under the same name)
policy_blend = importlib.import_module("policy.blend")
EGO, PARTNER_GOALS = "a2", ("b3", "c1", "d4", "e0")
Runs = dict[str, list[list[float]]]  # case -> one list of per-call seconds per repeat
ROWS = {"sl, batch 256": 256, "aail, batch 256": 256, "aail_bounded, batch 256": 256}


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


def request(method: str, batch: int, seed: int | None = 1) -> ActRequest:
    obs = np.random.default_rng(batch).random((batch, 20)).astype(np.float32)
    partners = tuple(PartnerSpec(i + 1, goal=g) for i, g in enumerate(PARTNER_GOALS))
    return ActRequest("particle", EGO, obs, partners, method=method, seed=seed)  # type: ignore[arg-type]


def blend_cases() -> dict[str, Callable[[], object]]:
    """The blend on the batch-1 shapes, through every entry point this checkout has."""
    q_task = np.random.default_rng(0).normal(size=(1, 5))
    q_impact = np.random.default_rng(1).normal(size=(1, 4, 5))
    cases: dict[str, Callable[[], object]] = {
        "blend alone": lambda: policy_blend.blend("aail", q_task, q_impact, 0.02)
    }
    if hasattr(policy_blend, "blend_vectorised"):
        vectorised = policy_blend.blend_vectorised
        cases["blend vectorised"] = lambda: vectorised("aail", q_task, q_impact, 0.02)
    return cases


def measure(store_url: str | None, hidden: tuple[int, ...], repeats: int, calls: int) -> Runs:
    """Every case of the module docstring, `repeats` times."""
    runs: Runs = {}
    with tempfile.TemporaryDirectory() as tmp:
        url = store_url or f"sqlite:///{Path(tmp) / 'models.db'}"
        with SqlModelStore(url) as store:
            if not store_url:
                build_zoo(store, hidden)
            engine = InferenceEngine(store)
            single: dict[str, Callable[[], object]] = {
                "sl, batch 1": functools.partial(engine.act, request("sl", 1)),
                "aail, batch 1": functools.partial(engine.act, request("aail", 1)),
                "aail unseeded, batch 1": functools.partial(engine.act, request("aail", 1, None)),
                "aail_bounded, batch 1": functools.partial(engine.act, request("aail_bounded", 1)),
                **blend_cases(),
            }
            big: dict[str, Callable[[], object]] = {
                "sl, batch 256": functools.partial(engine.act, request("sl", 256)),
                "aail, batch 256": functools.partial(engine.act, request("aail", 256)),
                "aail_bounded, batch 256": functools.partial(
                    engine.act, request("aail_bounded", 256)
                ),
            }
            for warm in [*single.values(), *big.values()]:
                warm()  # the caches
            for _ in range(repeats):
                for name, call in single.items():
                    runs.setdefault(name, []).append(latencies(call, calls))
                for name, call in big.items():
                    runs.setdefault(name, []).append(latencies(call, max(20, calls // 40)))
    return runs


def compare(old_tree: Path, args: argparse.Namespace) -> tuple[Runs, Runs]:
    """(old, new) runs, one repeat at a time each, alternating."""
    old: Runs = {}
    new: Runs = {}
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "runs.json"
        for _ in range(args.repeats):
            command = [sys.executable, __file__, "--repeats", "1", "--calls", str(args.calls)]
            command += ["--hidden", args.hidden, "--json", str(out)]
            command += ["--store-url", args.store_url] if args.store_url else []
            env = {**os.environ, "PYTHONPATH": str(old_tree.resolve())}
            subprocess.run(command, env=env, check=True)
            for name, repeat in json.loads(out.read_text()).items():
                old.setdefault(name, []).extend(repeat)
            hidden = tuple(int(h) for h in args.hidden.split(","))
            for name, repeat in measure(args.store_url, hidden, 1, args.calls).items():
                new.setdefault(name, []).extend(repeat)
    return old, new


def p50s(runs: list[list[float]]) -> list[float]:
    return [float(np.percentile(r, 50)) for r in runs]


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--calls", type=int, default=2000, help="calls per batch-1 repeat")
    parser.add_argument("--hidden", default="128,128", help="hidden sizes of the random zoo")
    parser.add_argument("--store-url", default=None, help="use this store instead")
    parser.add_argument("--compare", type=Path, default=None, help="another checkout to time")
    parser.add_argument("--json", type=Path, default=None, help="write the raw runs here")
    args = parser.parse_args()
    hidden = tuple(int(h) for h in args.hidden.split(","))
    threads = os.environ.get("OPENBLAS_NUM_THREADS", "default")
    title = (
        f"InferenceEngine.act, 1 ego + 4 partners, MLP 8-{args.hidden}-5, "
        f"OPENBLAS_NUM_THREADS={threads}; {describe()}"
    )
    if args.compare is not None:
        old, new = compare(args.compare, args)
        table = Table(title=f"{title}; before = {args.compare}, after = this checkout")
        for column in ("case", "before p50 µs", "after p50 µs", "speed-up", "after actions/s"):
            table.add_column(column, justify="left" if column == "case" else "right")
        for name, new_runs in new.items():
            after = statistics.median(p50s(new_runs))
            before = statistics.median(p50s(old[name])) if name in old else None
            table.add_row(
                name,
                f"{before * 1e6:,.0f}" if before else "",
                f"{after * 1e6:,.0f}",
                f"{before / after:.1f}x" if before else "",
                f"{rate(new_runs, ROWS.get(name, 1)):,.0f}",
            )
        Console().print(table)
        return
    runs = measure(args.store_url, hidden, args.repeats, args.calls)
    if args.json is not None:
        args.json.write_text(json.dumps(runs))
        return
    table = Table(title=title)
    for column in ("case", "p50 µs", "p90 µs", "actions/s", "p50 spread µs"):
        table.add_column(column, justify="left" if column == "case" else "right")
    for name, case_runs in runs.items():
        medians = p50s(case_runs)
        p90 = statistics.median(float(np.percentile(r, 90)) for r in case_runs)
        table.add_row(
            name,
            f"{statistics.median(medians) * 1e6:,.0f}",
            f"{p90 * 1e6:,.0f}",
            f"{rate(case_runs, ROWS.get(name, 1)):,.0f}",
            f"{min(medians) * 1e6:,.0f}..{max(medians) * 1e6:,.0f}",
        )
    Console().print(table)


def rate(runs: list[list[float]], rows: int) -> float:
    """Median over the repeats of rows answered per second of wall time."""
    return statistics.median(rows * len(r) / sum(r) for r in runs)


if __name__ == "__main__":
    main()
