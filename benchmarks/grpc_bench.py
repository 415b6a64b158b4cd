"""gRPC load test: latency and throughput of Act / ActBatch against the server's own no-op floor.

Run: `.venv/bin/python benchmarks/grpc_bench.py [--duration 3] [--store URL]`

| case      | call                                      | per call                          |
|-----------|-------------------------------------------|-----------------------------------|
| no-op     | `grpc.health.v1.Health/Check`             | nothing (the transport's floor)   |
| act       | `PolicyService/Act`, AAIL                 | 1 ego + 4 partners (5 networks)   |
| batch 256 | `PolicyService/ActBatch`, AAIL, 256 rows  | the same, vectorised over 256     |

each at concurrency 1 and 32. The server (the real `build_grpc_server`, sync, 8 worker threads)
runs in a child process pinned to CPU 0; the load generator runs in this process on CPU 1: one
thread per concurrent client, each with its own persistent channel, closed loop (a new call as
soon as the last answered). Every case warms up, then runs for `--duration` seconds; loopback
only. Without `--store`, a temporary SQLite store gets the FIVE_AGENTS scenario's networks (task
a2, impact a0 b2 c4 e1) at the production size (hidden 256-128-128, random weights).

Targets (issue 5): act p50 <= 2x no-op p50; act rps at c=32 >= 40 % of no-op's; batch actions/s
>= 30x single-call rps. A Python client saturates before a C client would, so the c=32 figures
are a lower bound on what the server sustains.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import grpc
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from envs.particle.scenarios import FIVE_AGENTS  # noqa: E402
from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb  # noqa: E402
from services.grpc_api.gen.coexist.v1 import policy_pb2_grpc as pb_grpc  # noqa: E402

EGO, PARTNERS = FIVE_AGENTS
BATCH = 256
WARMUP_CALLS = 50


def build_store(url: str) -> None:
    """Register the FIVE_AGENTS networks (production-sized, random weights) at `url`."""
    import torch

    from model_store import Lineage, impact_model_name, open_store, task_model_name
    from policy.qnet import QNetSpec, QNetwork, weights_to_safetensors

    spec = QNetSpec(obs_dim=8, n_actions=5)
    names = [(task_model_name("particle", EGO), "task", EGO)]
    names += [(impact_model_name("particle", g), "impact", g) for g in PARTNERS]
    with open_store(url) as store:
        for seed, (name, kind, goal) in enumerate(names):
            torch.manual_seed(seed)
            store.create_model(name, env="particle", kind=kind, goals=[goal], obs_dim=8,
                               n_actions=5, exist_ok=True)  # fmt: skip
            store.register_version(
                name, spec=spec.to_json(), weights=weights_to_safetensors(QNetwork(spec)),
                lineage=Lineage(config={"alpha": 0.05}, seed=seed), aliases=("production",),
            )  # fmt: skip


def serve(url: str, workers: int) -> None:
    """Child process: serve the store until killed; print the bound port first."""
    from model_store import open_store
    from services.engine import InferenceEngine
    from services.grpc_api.server import build_grpc_server

    engine = InferenceEngine(open_store(url))
    server = build_grpc_server(engine, port=0, max_workers=workers)
    server.start()
    print(server.port, flush=True)
    server.wait_for_termination()


def act_request(rows: int) -> Any:
    rng = np.random.default_rng(0)
    obs_BD = rng.random((rows, 4 * (1 + len(PARTNERS))))
    obs_BD[:, 2::4] = obs_BD[:, 3::4] = 0.0  # velocities at rest
    partners = [pb.PartnerSpec(index=i + 1, goal=g) for i, g in enumerate(PARTNERS)]
    if rows == 1:
        return pb.ActRequest(env="particle", ego_goal=EGO, observation=obs_BD[0], partners=partners)
    vectors = [pb.Vector(values=row) for row in obs_BD]
    return pb.ActBatchRequest(env="particle", ego_goal=EGO, observations=vectors, partners=partners)


def noop_call(channel: grpc.Channel) -> Callable[[], Any]:
    from grpc_health.v1 import health_pb2, health_pb2_grpc

    stub, request = health_pb2_grpc.HealthStub(channel), health_pb2.HealthCheckRequest()
    return lambda: stub.Check(request)


def act_call(channel: grpc.Channel) -> Callable[[], Any]:
    stub, request = pb_grpc.PolicyServiceStub(channel), act_request(1)
    return lambda: stub.Act(request)


def batch_call(channel: grpc.Channel) -> Callable[[], Any]:
    stub, request = pb_grpc.PolicyServiceStub(channel), act_request(BATCH)
    return lambda: stub.ActBatch(request)


@dataclass(frozen=True)
class LoadResult:
    case: str
    concurrency: int
    calls: int
    seconds: float
    p50_ms: float
    p99_ms: float
    rows_per_call: int

    @property
    def rps(self) -> float:
        return self.calls / self.seconds

    @property
    def actions_per_s(self) -> float:
        return self.rps * self.rows_per_call


def run_load(
    case: str, make_call: Callable[[grpc.Channel], Callable[[], Any]], target: str,
    concurrency: int, duration: float, rows_per_call: int = 1,
) -> LoadResult:  # fmt: skip
    """Closed-loop load from `concurrency` threads, each with its own channel."""
    start_gate = threading.Barrier(concurrency + 1)
    deadline = [0.0]
    latencies: list[list[float]] = [[] for _ in range(concurrency)]

    def client(k: int) -> None:
        with grpc.insecure_channel(target) as channel:
            call = make_call(channel)
            for _ in range(WARMUP_CALLS):
                call()
            start_gate.wait()
            mine = latencies[k]
            while (t0 := time.perf_counter()) < deadline[0]:
                call()
                mine.append(time.perf_counter() - t0)

    threads = [threading.Thread(target=client, args=(k,)) for k in range(concurrency)]
    for thread in threads:
        thread.start()
    deadline[0] = time.perf_counter() + 3600  # the clients warm up first
    start_gate.wait()
    started = time.perf_counter()
    deadline[0] = started + duration
    for thread in threads:
        thread.join()
    elapsed = time.perf_counter() - started
    all_ms = np.concatenate([np.asarray(lat) for lat in latencies]) * 1e3
    return LoadResult(case, concurrency, len(all_ms), elapsed, float(np.percentile(all_ms, 50)),
                      float(np.percentile(all_ms, 99)), rows_per_call)  # fmt: skip


def start_server(url: str, workers: int) -> tuple[subprocess.Popen[str], str]:
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    pin = ["taskset", "-c", "0"] if os.path.exists("/usr/bin/taskset") else []
    command = [*pin, sys.executable, __file__, "--serve", "--store", url, "--workers", str(workers)]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, text=True, env=env, cwd=ROOT)
    assert process.stdout is not None
    port = process.stdout.readline().strip()
    if not port.isdigit():
        process.kill()
        raise RuntimeError("the benchmark server did not start")
    return process, f"127.0.0.1:{port}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=3.0, help="seconds per case")
    parser.add_argument("--store", help="store URL holding the FIVE_AGENTS networks")
    parser.add_argument("--workers", type=int, default=8, help="server thread pool size")
    parser.add_argument("--serve", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.serve:
        serve(args.store, args.workers)
        return

    from rich.console import Console
    from rich.table import Table

    with tempfile.TemporaryDirectory() as tmp:
        url = args.store or f"sqlite:///{tmp}/models.db"
        if not args.store:
            build_store(url)
        server, target = start_server(url, args.workers)
        if hasattr(os, "sched_setaffinity") and (os.cpu_count() or 1) > 1:
            os.sched_setaffinity(0, {1})  # the load generator on the other core
        try:
            cases = [("no-op", noop_call, 1), ("act", act_call, 1),
                     (f"batch {BATCH}", batch_call, BATCH)]  # fmt: skip
            results = [
                run_load(name, make, target, c, args.duration, rows)
                for name, make, rows in cases
                for c in (1, 32)
            ]
        finally:
            server.terminate()
            server.wait(timeout=10)

    table = Table(title=f"gRPC, sync server ({args.workers} threads), {args.duration:g} s per case")
    for column in ("case", "concurrency", "p50 ms", "p99 ms", "calls/s", "actions/s"):
        table.add_column(column, justify="left" if column == "case" else "right")
    for r in results:
        table.add_row(r.case, str(r.concurrency), f"{r.p50_ms:.3f}", f"{r.p99_ms:.3f}",
                      f"{r.rps:,.0f}", f"{r.actions_per_s:,.0f}")  # fmt: skip
    by = {(r.case, r.concurrency): r for r in results}
    noop1, act1, noop32, act32 = by["no-op", 1], by["act", 1], by["no-op", 32], by["act", 32]
    batch32 = by[f"batch {BATCH}", 32]
    console = Console()
    console.print(table)
    console.print(
        f"act p50 / no-op p50 (c=1): {act1.p50_ms / noop1.p50_ms:.2f}x (target <= 2)\n"
        f"act rps / no-op rps (c=32): {act32.rps / noop32.rps:.0%} (target >= 40 %)\n"
        f"batch actions/s / act rps (c=32): {batch32.actions_per_s / act32.rps:.0f}x (target >= 30)"
    )


if __name__ == "__main__":
    main()
