"""Capacity: how many robots one server holds, each a REST session stepping at a fixed rate
(`HZ`) with inferred partners (`PARTNER_GOALS`), within a step-latency bound (`P99_MS`) and
without errors; and act throughput under concurrent load, one worker against two.

Run: `OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/capacity.py [--workers 1]
[--session-store redis://127.0.0.1:6379/0] [--sessions 10,20,40,60,80] [--duration 10]
[--processes 2] [--throughput]` (needs `taskset`; `--throughput` needs `wrk`).

| part        | what                                                                         |
|-------------|------------------------------------------------------------------------------|
| server      | `coexist serve --no-bootstrap --workers W` on a temporary SQLite store of     |
|             | every particle network at the trainer's size (`session_scene.build_store`),   |
|             | REST only; one worker pinned to CPU 0, two workers on both CPUs; sessions in  |
|             | memory, or in the shared store of `--session-store` (required for W > 1)     |
| robots      | N sessions (5 agents, partners 1-4 inferred), each on its own keep-alive      |
|             | connection, stepping a seeded episode (`session_scene.episode`, the partners' |
|             | true actions in `observed`) on a fixed 10 Hz schedule from a random phase     |
| load        | `--processes` processes (pinned to CPU 1 with one worker), each an asyncio    |
|             | loop over raw sockets with pre-encoded requests (an `httpx` client saturates  |
|             | far below the server); latency runs from a step's SCHEDULED send time to its  |
|             | answer, so a late send counts (no coordinated omission)                       |
| warm-up     | a few sessions for 3 s on a new server, untimed (each worker loads and stacks |
|             | its networks on first use)                                                    |
| held        | the largest N whose steps, after the warm-up, have p99 <= P99_MS, no error    |
|             | (any status but 200, a dropped connection) and >= 95 % of the 10 Hz steps done |
| CPU         | the server's CPU seconds (all its processes, from /proc) and Redis's own      |
|             | (`INFO cpu`) over each level, per step: the figure to plan cores with, less   |
|             | moved by other work on the machine than the latencies                         |
| throughput  | `wrk -t2 -c32` closed loop on `POST /v1/act` (4 announced partners, the same  |
|             | episode's observations), rounds of `--duration` s: median requests/s          |
"""

from __future__ import annotations

import argparse
import asyncio
import json
import multiprocessing
import os
import random
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from session_scene import (  # noqa: E402
    EGO_GOAL,
    PARTNER_GOALS,
    act_bodies,
    build_store,
    episode,
    step_bodies,
)
from wrk_server import free_port, http_ok, lua_script, parse_wrk, stop, wait_ready  # noqa: E402

HZ = 10.0
P99_MS = 20.0
WARMUP_S = 1.0
N_AGENTS = 1 + len(PARTNER_GOALS)
CREATE = {
    "env": "particle",
    "ego_goal": EGO_GOAL,
    "partners": [{"index": j + 1, "infer": True} for j in range(len(PARTNER_GOALS))],
    "seed": 7,
}


# --- the server --------------------------------------------------------------------------------
def start(store_url: str, port: int, workers: int, session_store: str | None) -> Any:
    env = {
        **os.environ,
        "COEXIST_DEV_MODE": "1",
        "COEXIST_LOG_LEVEL": "warning",
        "COEXIST_MAX_SESSIONS": "100000",
        "COEXIST_MAX_SESSIONS_PER_CLIENT": "100000",
    }
    if session_store:
        env["COEXIST_SESSION_STORE_URL"] = session_store
        env["COEXIST_SESSION_SECRET"] = os.urandom(24).hex()
    pin = ["taskset", "-c", "0"] if workers == 1 else []
    command = [
        *pin,
        str(ROOT / ".venv/bin/coexist"),
        "serve",
        "--no-bootstrap",
        "--workers",
        str(workers),
        "--host",
        "127.0.0.1",
        "--http-port",
        str(port),
        "--grpc-port",
        "0",
        "--store-url",
        store_url,
    ]
    server = subprocess.Popen(command, env=env, stdout=subprocess.DEVNULL)
    if wait_ready(server, lambda: http_ok(f"http://127.0.0.1:{port}/readyz"), "the server", 180):
        return server
    server.kill()
    raise SystemExit("the server did not become ready within 180 s")


def cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of process `pid` and every process under it (the workers)."""
    tick = os.sysconf("SC_CLK_TCK")
    total, todo = 0.0, [pid]
    while todo:
        p = todo.pop()
        try:
            fields = Path(f"/proc/{p}/stat").read_text().rsplit(")", 1)[1].split()
            total += (int(fields[11]) + int(fields[12])) / tick  # utime, stime
            for task in Path(f"/proc/{p}/task").iterdir():
                todo += [int(c) for c in (task / "children").read_text().split()]
        except (FileNotFoundError, ProcessLookupError):
            continue
    return total


def redis_cpu_seconds(url: str | None) -> float:
    """The Redis server's own CPU seconds so far (0 without a Redis session store)."""
    if not url or not url.startswith("redis"):
        return 0.0
    import redis

    with redis.Redis.from_url(url) as client:
        info = client.info("cpu")
    return float(info["used_cpu_user"]) + float(info["used_cpu_sys"])


# --- the robots --------------------------------------------------------------------------------
def _request(port: int, path: str, body: bytes) -> bytes:
    head = (
        f"POST {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n"
        f"Content-Type: application/json\r\nContent-Length: {len(body)}\r\n\r\n"
    )
    return head.encode() + body


async def _answer(reader: asyncio.StreamReader) -> tuple[int, bytes]:
    head = await reader.readuntil(b"\r\n\r\n")
    status = int(head[9:12])
    length = 0
    for line in head.split(b"\r\n")[1:]:
        name, _, value = line.partition(b":")
        if name.strip().lower() == b"content-length":
            length = int(value)
    return status, await reader.readexactly(length)


async def _robot(
    port: int, bodies: list[bytes], start_at: float, until: float, out: dict[str, Any]
) -> None:
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    try:
        writer.write(_request(port, "/v1/sessions", json.dumps(CREATE).encode()))
        status, created = await _answer(reader)
        if status != 201:
            out["errors"] += 1
            return
        path = f"/v1/sessions/{json.loads(created)['session_id']}/steps"
        # step 0 brings no evidence (nothing was observed before it); the cycle's first body
        # (the episode's last actions, wrapped) only from its second round on
        requests = [_request(port, path, b) for b in bodies]
        first = _request(
            port, path, json.dumps({"observation": json.loads(bodies[0])["observation"]}).encode()
        )
        k = 0
        loop = asyncio.get_running_loop()
        while True:
            due = start_at + k / HZ
            if due >= until:
                return
            delay = due - loop.time()
            if delay > 0:
                await asyncio.sleep(delay)
            writer.write(requests[k % len(requests)] if k else first)
            status, _ = await _answer(reader)
            if due >= start_at + WARMUP_S:
                out["latencies"].append(loop.time() - due)
                out["due"] += 1
                if status != 200:
                    out["errors"] += 1
            k += 1
    except (OSError, asyncio.IncompleteReadError):
        out["errors"] += 1
    finally:
        writer.close()


def _robots(port: int, n: int, duration: float, bodies: list[bytes], seed: int) -> dict[str, Any]:
    """One load process: `n` robots for `duration` s (after creating their sessions)."""
    import uvloop

    async def run() -> dict[str, Any]:
        out: dict[str, Any] = {"latencies": [], "errors": 0, "due": 0}
        loop = asyncio.get_running_loop()
        rng = random.Random(seed)
        begin = loop.time() + 1.0  # every session created by then
        until = begin + WARMUP_S + duration
        await asyncio.gather(
            *(_robot(port, bodies, begin + rng.random() / HZ, until, out) for _ in range(n))
        )
        return out

    return uvloop.run(run())


def hold(
    port: int,
    n: int,
    duration: float,
    processes: int,
    workers: int,
    server_pid: int,
    session_store: str | None,
) -> dict[str, float]:
    obs_TD, act_TP = episode(N_AGENTS, 400, seed=3)
    bodies = step_bodies(obs_TD, act_TP, observed=True)
    shares = [n // processes + (k < n % processes) for k in range(processes)]
    if workers == 1:  # the server has CPU 0: the load takes CPU 1
        os.sched_setaffinity(0, {1})
    cpu_before, redis_before = cpu_seconds(server_pid), redis_cpu_seconds(session_store)
    with multiprocessing.get_context("fork").Pool(processes) as pool:
        parts = pool.starmap(
            _robots, [(port, s, duration, bodies, k) for k, s in enumerate(shares) if s]
        )
    server_cpu = cpu_seconds(server_pid) - cpu_before
    redis_cpu = redis_cpu_seconds(session_store) - redis_before
    os.sched_setaffinity(0, set(range(os.cpu_count() or 1)))
    latencies = np.concatenate([p["latencies"] for p in parts]) * 1e3
    expected = n * HZ * duration
    return {
        "sessions": n,
        "steps": len(latencies),
        "done": len(latencies) / expected,
        "p50_ms": float(np.percentile(latencies, 50)) if len(latencies) else float("nan"),
        "p99_ms": float(np.percentile(latencies, 99)) if len(latencies) else float("nan"),
        "errors": sum(p["errors"] for p in parts),
        # the server's CPU per step, warm-up and session creation included (a small share)
        "cpu_ms": server_cpu * 1e3 / max(1, len(latencies)),
        "redis_cpu_ms": redis_cpu * 1e3 / max(1, len(latencies)),
    }


def throughput(port: int, duration: float, rounds: int, tmp: Path) -> float:
    """Median requests/s of `wrk -t2 -c32` on /v1/act over `rounds` rounds."""
    obs_TD, _ = episode(N_AGENTS, 200, seed=3)
    script = tmp / "act.lua"
    script.write_text(lua_script("/v1/act", act_bodies(obs_TD, PARTNER_GOALS)))
    command = ["wrk", "-t2", "-c32", "--timeout", "10s", "-s", str(script), "--latency"]
    subprocess.run([*command, "-d2s", f"http://127.0.0.1:{port}"], check=True, capture_output=True)
    rates = []
    for _ in range(rounds):
        done = subprocess.run(
            [*command, f"-d{round(duration)}s", f"http://127.0.0.1:{port}"],
            check=True,
            capture_output=True,
            text=True,
        )
        parsed = parse_wrk(done.stdout)
        if parsed["failed"]:
            raise SystemExit(f"act throughput: {parsed['failed']:g} failed requests")
        rates.append(parsed["requests"] / parsed["seconds"])
    return statistics.median(rates)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--session-store", default=None, help="Redis or PostgreSQL URL")
    parser.add_argument("--sessions", default="10,20,40,60,80,100")
    parser.add_argument("--duration", type=float, default=10.0)
    parser.add_argument("--processes", type=int, default=2)
    parser.add_argument("--throughput", action="store_true")
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    if args.workers > 1 and not args.session_store:
        raise SystemExit("--workers > 1 needs --session-store (sessions shared by the workers)")

    with tempfile.TemporaryDirectory() as tmp:
        url = f"sqlite:///{Path(tmp) / 'models.db'}"
        size = build_store(url)
        port = free_port()
        server = start(url, port, args.workers, args.session_store)
        store = args.session_store.split("://")[0] if args.session_store else "memory"
        print(f"networks {size}; {args.workers} worker(s); sessions in {store}")
        try:
            if args.throughput:
                rate = throughput(port, args.duration, args.rounds, Path(tmp))
                print(f"act c=32: {rate:.0f} req/s (median of {args.rounds} rounds)")
            counts = [int(s) for s in args.sessions.split(",") if s.strip()]  # "": none
            if counts:
                print(
                    "\n| sessions | steps | done | p50 ms | p99 ms | errors | server CPU ms/step "
                    "| Redis CPU ms/step | held |"
                )
                print("|---|---|---|---|---|---|---|---|---|")
            if counts:  # every worker loads and stacks its networks first, untimed
                hold(port, 4 * args.workers, 3.0, args.processes, args.workers, server.pid, None)
            for n in counts:
                r = hold(
                    port,
                    n,
                    args.duration,
                    args.processes,
                    args.workers,
                    server.pid,
                    args.session_store,
                )
                held = r["p99_ms"] <= P99_MS and not r["errors"] and r["done"] >= 0.95
                print(
                    f"| {n} | {r['steps']} | {r['done']:.0%} | {r['p50_ms']:.2f} | "
                    f"{r['p99_ms']:.2f} | {r['errors']} | {r['cpu_ms']:.2f} | "
                    f"{r['redis_cpu_ms']:.3f} | "
                    f"{'yes' if held else 'no'} |",
                    flush=True,
                )
                if not held:
                    break
        finally:
            stop(server)


if __name__ == "__main__":
    main()
