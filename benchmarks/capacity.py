"""Capacity: how many robots one server holds, each a REST session stepping at a fixed rate
(`HZ`) with inferred partners (`PARTNER_GOALS`), within a step-latency bound (`P99_MS`) and
without errors; and act throughput under concurrent load, one worker against two; the same
robots on two replicas sharing their sessions, each robot's steps alternating between them
(or each robot kept to one); and the same load against Ray Serve running the same maths, the
anchor.

Run: `OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/capacity.py [--workers 1]
[--replicas 2 [--sticky]] [--session-store redis://127.0.0.1:6379/0] [--sessions 10,20,40,60,80]
[--duration 10] [--processes 2] [--throughput] [--servers coexist ray] [--alternations 2]
[--method aail] [--ray-max-ongoing-requests N]` (needs `taskset`; `--throughput` needs `wrk`).

| part        | what                                                                         |
|-------------|------------------------------------------------------------------------------|
| server      | `coexist serve --no-bootstrap --workers W` on a temporary SQLite store of     |
|             | every particle network at the trainer's size (`session_scene.build_store`),   |
|             | REST only; one worker pinned to CPU 0, two workers on both CPUs; sessions in  |
|             | memory, or in the shared store of `--session-store` (required for W > 1)     |
| replicas    | `--replicas R`: R such servers of one worker each, unpinned, on one model     |
|             | store and one `--session-store` with one session secret (as the compose       |
|             | file's replicas); a robot creates its session on the first and sends step k   |
|             | to replica k mod R over its own connection to each: every step is served by a |
|             | replica that did not serve the one before (R > 1). `--sticky`: robot i keeps  |
|             | to replica i mod R (as Envoy routes a session), the figure to plan with       |
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
| anchor      | `--servers coexist ray`: the plain app of `alternative_servers.py` (its       |
|             | numpy sessions: coexist's default belief, the AAIL act blending each partner's |
|             | impact networks by it) as a one-replica Ray Serve deployment on a one-CPU Ray |
|             | pinned to CPU 0, the replica on the server's one core (one worker only: the   |
|             | sessions live in the replica's memory), under the same robots. Both servers   |
|             | then act with method aail (the numpy sessions' only method; coexist's default |
|             | is aail_bounded). Before Ray's ladder, its answers to `CHECK_STEPS` steps of a |
|             | seeded session must equal a coexist `Session`'s in process on the same store  |
|             | (probabilities within `PROBS_ATOL`, the same actions), else the run stops.    |
|             | Each server runs its ladder alone, `--alternations` times, the order reversed |
|             | each time; the summary gives the medians and coexist's over Ray's             |
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

SERVERS = ("coexist", "ray")
CHECK_STEPS = 6  # steps of one seeded session checked against coexist's before Ray is timed
PROBS_ATOL = 1e-5
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
def start(
    store_url: str,
    port: int,
    workers: int,
    session_store: str | None,
    secret: str | None = None,
    pin: bool = True,
) -> Any:
    """`coexist serve` (REST only) on `port`, ready; pinned to CPU 0 when it has one worker
    and `pin`. Replicas share `secret`, the key that signs their shared session records."""
    env = {
        **os.environ,
        "COEXIST_DEV_MODE": "1",
        "COEXIST_LOG_LEVEL": "warning",
        "COEXIST_MAX_SESSIONS": "100000",
        "COEXIST_MAX_SESSIONS_PER_CLIENT": "100000",
    }
    if session_store:
        env["COEXIST_SESSION_STORE_URL"] = session_store
        env["COEXIST_SESSION_SECRET"] = secret or os.urandom(24).hex()
    taskset = ["taskset", "-c", "0"] if workers == 1 and pin else []
    command = [
        *taskset,
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
    """A keep-alive HTTP/1.1 POST of `body` to `path`, as bytes."""
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
    ports: list[int],
    create: bytes,
    bodies: list[bytes],
    start_at: float,
    until: float,
    out: dict[str, Any],
) -> None:
    """One robot: its session created on `ports[0]`, step k sent to `ports[k % len(ports)]`,
    one keep-alive connection to each."""
    links = [await asyncio.open_connection("127.0.0.1", port) for port in ports]
    try:
        reader, writer = links[0]
        writer.write(_request(ports[0], "/v1/sessions", create))
        status, created = await _answer(reader)
        if status != 201:
            out["errors"] += 1
            return
        path = f"/v1/sessions/{json.loads(created)['session_id']}/steps"
        # step 0 brings no evidence (nothing was observed before it); the cycle's first body
        # (the episode's last actions, wrapped) only from its second round on
        requests = [[_request(port, path, b) for b in bodies] for port in ports]
        first = _request(ports[0], path, first_step(bodies))
        k = 0
        loop = asyncio.get_running_loop()
        while True:
            due = start_at + k / HZ
            if due >= until:
                return
            delay = due - loop.time()
            if delay > 0:
                await asyncio.sleep(delay)
            reader, writer = links[k % len(links)]
            writer.write(requests[k % len(links)][k % len(bodies)] if k else first)
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
        for _, writer in links:
            writer.close()


def first_step(bodies: list[bytes]) -> bytes:
    """Step 0's body: the first body's observation without evidence (nothing observed yet)."""
    return json.dumps({"observation": json.loads(bodies[0])["observation"]}).encode()


def _robots(
    routes: list[list[int]], create: bytes, duration: float, bodies: list[bytes], seed: int
) -> dict[str, Any]:
    """One load process: a robot per route (the ports its steps go to, in turn) for `duration`
    s (after creating their sessions)."""
    import uvloop

    async def run() -> dict[str, Any]:
        out: dict[str, Any] = {"latencies": [], "errors": 0, "due": 0}
        loop = asyncio.get_running_loop()
        rng = random.Random(seed)
        begin = loop.time() + 1.0  # every session created by then
        until = begin + WARMUP_S + duration
        await asyncio.gather(
            *(
                _robot(ports, create, bodies, begin + rng.random() / HZ, until, out)
                for ports in routes
            )
        )
        return out

    return uvloop.run(run())


def hold(
    ports: list[int],
    create: bytes,
    n: int,
    duration: float,
    processes: int,
    pinned: bool,
    server_pids: list[int],
    session_store: str | None,
    sticky: bool = False,
) -> dict[str, float]:
    """`n` robots on `ports` for `duration` s from `processes` load processes (on CPU 1 when
    the server is `pinned` to CPU 0): the level's latencies, errors and CPU per step. Each
    robot's steps go to every port in turn, or (`sticky`) robot i's to port i mod len(ports)."""
    obs_TD, act_TP = episode(N_AGENTS, 400, seed=3)
    bodies = step_bodies(obs_TD, act_TP, observed=True)
    routes = [[ports[i % len(ports)]] if sticky else ports for i in range(n)]
    shares = [n // processes + (k < n % processes) for k in range(processes)]
    starts = [sum(shares[:k]) for k in range(processes)]
    if pinned:  # the server has CPU 0: the load takes CPU 1
        os.sched_setaffinity(0, {1})
    cpu_before = sum(cpu_seconds(pid) for pid in server_pids)
    redis_before = redis_cpu_seconds(session_store)
    with multiprocessing.get_context("fork").Pool(processes) as pool:
        parts = pool.starmap(
            _robots,
            [
                (routes[start : start + s], create, duration, bodies, k)
                for k, (start, s) in enumerate(zip(starts, shares, strict=True))
                if s
            ],
        )
    server_cpu = sum(cpu_seconds(pid) for pid in server_pids) - cpu_before
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


# --- the anchor's answers against coexist's ------------------------------------------------
def check_bodies(steps: int = CHECK_STEPS) -> list[bytes]:
    """The robots' first `steps` step bodies: step 0 without evidence, then the episode's."""
    obs_TD, act_TP = episode(N_AGENTS, 400, seed=3)
    bodies = step_bodies(obs_TD, act_TP, observed=True)
    return [first_step(bodies), *bodies[1:steps]]


def coexist_session_answers(
    store_url: str, create: dict[str, Any], bodies: list[bytes]
) -> list[tuple[np.ndarray, int]]:
    """(probs, action) of each step of a coexist `Session` in process on the store: the
    engine `coexist serve` runs, the same settings as the robots' sessions."""
    from model_store import open_store
    from services.engine.engine import InferenceEngine
    from services.sessions import Observed, Session, SessionPartner, SessionSettings

    partners = tuple(SessionPartner(p["index"], infer=p["infer"]) for p in create["partners"])
    extra = {"method": create["method"]} if "method" in create else {}
    settings = SessionSettings(
        create["env"], create["ego_goal"], partners, seed=create.get("seed"), **extra
    )
    answers = []
    with open_store(store_url) as store:
        session = Session(InferenceEngine(store), settings)
        for body in bodies:
            step = json.loads(body)
            observed = [Observed(o["index"], o["action"]) for o in step.get("observed", [])]
            result = session.step(step["observation"], observed).result
            answers.append((np.asarray(result.probs, dtype=np.float64), int(result.action)))
    return answers


def http_session_answers(
    client: Any, create: dict[str, Any], bodies: list[bytes]
) -> list[tuple[np.ndarray, int]]:
    """(probs, action) of each step of a session over HTTP; `client` posts to the server
    (an `httpx.Client` with its base URL, or a test client)."""
    created = client.post("/v1/sessions", json=create)
    if created.status_code != 201:
        raise SystemExit(f"creating a session: {created.status_code} {created.text[:500]}")
    path = f"/v1/sessions/{created.json()['session_id']}/steps"
    answers = []
    for body in bodies:
        reply = client.post(path, content=body, headers={"content-type": "application/json"})
        if reply.status_code != 200:
            raise SystemExit(f"a session step: {reply.status_code} {reply.text[:500]}")
        answer = reply.json()
        answers.append((np.asarray(answer["probs"], dtype=np.float64), int(answer["action"])))
    return answers


def check_same_answers(
    kind: str, answers: list[tuple[np.ndarray, int]], reference: list[tuple[np.ndarray, int]]
) -> None:
    """Fail loudly unless every step's probabilities are coexist's within `PROBS_ATOL` and
    its action the same."""
    for t, ((probs, action), (ref_probs, ref_action)) in enumerate(
        zip(answers, reference, strict=True)
    ):
        same_shape = probs.shape == ref_probs.shape
        gap = float(np.max(np.abs(probs - ref_probs))) if same_shape else np.inf
        if not gap <= PROBS_ATOL or action != ref_action:
            raise SystemExit(
                f"{kind}: step {t} answers {probs.tolist()} (action {action}), coexist "
                f"{ref_probs.tolist()} (action {ref_action}): not the same maths, nothing timed"
            )


# --- one server's ladder -----------------------------------------------------------------------
def run_server(kind: str, args: argparse.Namespace, url: str, tmp: Path) -> list[dict[str, Any]]:
    """Start `kind` alone, check it (Ray) and measure throughput (if asked) and the ladder of
    session counts up to the first level not held; the ladder's rows."""
    import httpx
    from alternatives_bench import start_alternative, stop_alternative

    create = dict(CREATE, **({"method": args.method} if args.method else {}))
    create_body = json.dumps(create).encode()
    ports = [free_port() for _ in range(1 if kind == "ray" else args.replicas)]
    port = ports[0]
    servers = []
    if kind == "ray":
        extra = (str(args.ray_max_ongoing_requests),) if args.ray_max_ongoing_requests else ()
        servers.append(start_alternative("ray", port, url, tmp / "ray.log", extra))
    else:
        secret = os.urandom(24).hex()
        pin = args.replicas == 1
        for p in ports:
            servers.append(start(url, p, args.workers, args.session_store, secret, pin))
    server = servers[0]
    pids = [s.pid for s in servers]
    rows = []
    try:
        if kind == "ray":
            bodies = check_bodies()
            with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=30) as client:
                answers = http_session_answers(client, create, bodies)
            check_same_answers("ray", answers, coexist_session_answers(url, create, bodies))
            print(f"ray: {len(bodies)} session steps answered as coexist's", flush=True)
        if args.throughput:
            rate = throughput(port, args.duration, args.rounds, tmp)
            print(f"{kind}: act c=32: {rate:.0f} req/s (median of {args.rounds} rounds)")
        counts = [int(c) for c in args.sessions.split(",") if c.strip()]  # "": none
        workers = 1 if kind == "ray" else args.workers * len(ports)
        pinned = workers == 1
        store = None if kind == "ray" else args.session_store
        if counts:  # every worker loads and stacks its networks first, untimed
            hold(ports, create_body, 4 * workers, 3.0, args.processes, pinned, pids, None)
        for n in counts:
            r = hold(
                ports,
                create_body,
                n,
                args.duration,
                args.processes,
                pinned,
                pids,
                store,
                args.sticky,
            )
            r["held"] = r["p99_ms"] <= P99_MS and not r["errors"] and r["done"] >= 0.95
            rows.append(r)
            print(
                f"| {kind} | {n} | {r['steps']} | {r['done']:.0%} | {r['p50_ms']:.2f} | "
                f"{r['p99_ms']:.2f} | {r['errors']} | {r['cpu_ms']:.2f} | "
                f"{r['redis_cpu_ms']:.3f} | {'yes' if r['held'] else 'no'} |",
                flush=True,
            )
            if not r["held"]:
                break
    finally:
        if kind == "ray":
            stop_alternative(server)
        else:
            for s in servers:
                stop(s)
    return rows


def held(rows: list[dict[str, Any]]) -> int:
    """The most sessions a ladder held (0: not its first level)."""
    return max((int(r["sessions"]) for r in rows if r["held"]), default=0)


def summary(ladders: dict[str, list[list[dict[str, Any]]]]) -> str:
    """Per server: sessions held in each alternation and their median, and the median server
    CPU per step over every level measured (a saturated server's too: its cost per step); the
    ratios of the medians when both servers ran."""
    lines = [
        "| server | sessions held, each alternation | median | server CPU ms/step |",
        "|---|---|---:|---:|",
    ]
    sessions: dict[str, float] = {}
    cpu: dict[str, float] = {}
    for kind, runs in ladders.items():
        counts = [held(rows) for rows in runs]
        sessions[kind] = float(statistics.median(counts))
        cpu[kind] = float(statistics.median(r["cpu_ms"] for rows in runs for r in rows))
        shown = ", ".join(map(str, counts))
        lines.append(f"| {kind} | {shown} | {sessions[kind]:g} | {cpu[kind]:.2f} |")
    if len(ladders) == 2:
        held_ratio = (
            f"{sessions['coexist'] / sessions['ray']:.1f}x"
            if sessions["ray"]
            else f"{sessions['coexist']:g} against none of the levels tried"
        )
        lines.append(
            f"\ncoexist over Ray Serve: sessions held {held_ratio}; "
            f"Ray's server CPU per step / coexist's {cpu['ray'] / cpu['coexist']:.1f}x"
        )
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument(
        "--replicas",
        type=int,
        default=1,
        help="servers sharing --session-store (each robot's steps alternate between them)",
    )
    parser.add_argument(
        "--sticky", action="store_true", help="with --replicas: robot i keeps to replica i mod R"
    )
    parser.add_argument("--session-store", default=None, help="Redis or PostgreSQL URL")
    parser.add_argument("--sessions", default="10,20,40,60,80,100")
    parser.add_argument("--duration", type=float, default=10.0)
    parser.add_argument("--processes", type=int, default=2)
    parser.add_argument("--throughput", action="store_true")
    parser.add_argument("--rounds", type=int, default=3, help="throughput rounds")
    parser.add_argument("--servers", nargs="+", choices=SERVERS, default=["coexist"])
    parser.add_argument(
        "--alternations", type=int, default=1, help="ladders per server, the order reversed"
    )
    parser.add_argument(
        "--method", default=None, help="the sessions' method (default: the server's)"
    )
    parser.add_argument(
        "--ray-max-ongoing-requests",
        type=int,
        help="the Ray Serve deployment's max_ongoing_requests (default: Serve's)",
    )
    args = parser.parse_args()
    if args.workers < 1 or args.replicas < 1:
        raise SystemExit("--workers and --replicas: at least 1")
    if (args.workers > 1 or args.replicas > 1) and not args.session_store:
        raise SystemExit(
            "--workers > 1 or --replicas > 1 needs --session-store (sessions shared by them)"
        )
    if args.sticky and args.replicas == 1:
        raise SystemExit("--sticky: with --replicas > 1 only")
    if args.replicas > 1 and args.throughput:
        raise SystemExit("--throughput: one server (its workers); not with --replicas")
    if "ray" in args.servers:
        if args.workers != 1 or args.replicas != 1 or args.session_store:
            raise SystemExit("--servers ray: one worker, sessions in memory (as Ray's replica)")
        if args.method not in (None, "aail"):
            raise SystemExit("--servers ray: method aail only (the numpy sessions' method)")
        args.method = "aail"

    ladders: dict[str, list[list[dict[str, Any]]]] = {kind: [] for kind in args.servers}
    with tempfile.TemporaryDirectory() as tmp:
        url = f"sqlite:///{Path(tmp) / 'models.db'}"
        size = build_store(url)
        store = args.session_store.split("://")[0] if args.session_store else "memory"
        print(
            f"networks {size}; {args.replicas} replica(s) of {args.workers} worker(s)"
            f"{', sticky' if args.sticky else ''}; "
            f"sessions in {store}; "
            f"method {args.method or 'the server default'}"
        )
        print(
            "\n| server | sessions | steps | done | median step, ms | 99th percentile, ms | errors | "
            "server CPU ms/step | Redis CPU ms/step | held |"
        )
        print("|---|---|---|---|---|---|---|---|---|---|")
        for a in range(args.alternations):
            order = args.servers if a % 2 == 0 else args.servers[::-1]
            for kind in order:
                ladders[kind].append(run_server(kind, args, url, Path(tmp)))
    if args.sessions.strip():
        print(f"\n{summary(ladders)}")


if __name__ == "__main__":
    main()
