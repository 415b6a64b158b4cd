"""Serving load test: REST (wrk) and gRPC (h2load) against the server's own no-op and against
bare servers that do nothing else (the floors).

Run: `.venv/bin/python benchmarks/serving.py [--duration 5] [--rounds 1] [--log-level warning]
[--json OUT]` (needs `wrk` and `h2load`: `apt-get install wrk nghttp2-client`).

The server is the real one, `coexist serve` (uvicorn with uvloop + httptools, one worker, gRPC
in the same process on grpcio's sync server with 8 threads), pinned to CPU 0; the load
generators are C programs pinned to CPU 1: `wrk` for HTTP/1.1 and `h2load` for gRPC (gRPC is
HTTP/2: h2load posts the length-prefixed protobuf with `content-type: application/grpc`). Each
case warms up for 1 s, then runs for `--duration` seconds on persistent connections.

The floors (`floor_servers.py`), started by this run on the same CPU: a bare FastAPI app whose
only route is the same `GET /healthz` on the same uvicorn settings (uvloop, httptools, one
worker), and a bare grpcio server (same thread pool) with the standard health servicer and an
act-shaped `Act` ("floor act", c = 1, informational: it parses the act's request and answers a
fixed message of the shape of coexist's answer, so coexist's act p50 minus its p50 is the time
coexist's handler and interceptor add inside grpcio's server; printed after the targets). Only
one server runs at a time: each round starts coexist, measures its cases and stops it, then
does the same for each floor (odd rounds the floors first), so a round's ratios come from
servers measured minutes apart at most, each alone on its CPU.

| case       | REST                         | gRPC                                  | per call       |
|------------|------------------------------|---------------------------------------|----------------|
| no-op      | `GET /healthz`               | `grpc.health.v1.Health/Check`         | nothing: floor |
| act        | `POST /v1/act`               | `coexist.v1.PolicyService/Act`        | AAIL, 1 ego +  |
|            |                              |                                       | 4 partners     |
| batch      | `POST /v1/act:batch`, 256    | `PolicyService/ActBatch`, 256 rows as | the same x 256 |
|            | rows, `"format": "columns"`  | `observation_matrix`, COLUMNS answer  |                |
| batch rows | the same, rows answer        | 256 `Vector`s, ROWS answer            | (c = 1 only)   |
| act default| the act's body without       | the act's message without `method`    | AAIL-B, c = 1  |
|            | `method`: the server default |                                       | (informational)|

Targets against its own no-op, per transport: act p50 at c=1 <= 2x the no-op p50; act
throughput at c=32 >= 40 % of the no-op's; batch actions/s >= 30x the single-request rate (both
at c=1), with the columnar batch ("batch rows" is informational: the default format, one result
per row). Against the floors, at c=1 unless said: REST no-op p50 <= 1.15x the bare FastAPI
no-op's, act p50 <= 1.8x it, act req/s at c=32 >= 40 % of its req/s at c=32; gRPC health p50
<= 1.15x the bare grpcio health server's, act p50 <= 1.5x it.
With `--rounds N` the whole plan runs N times one after the other; the table shows each case's
median p50 and req/s over the rounds, and each target is the median of its per-round ratios
(a ratio's two cases run minutes apart at most, so a burst of load from a neighbour on a shared
machine moves one round, not the verdict).
Every payload is checked once for a correct answer before it is timed; a run with any non-2xx
HTTP answer or failed gRPC stream is reported as failed. The store is a temporary SQLite file
with the FIVE_AGENTS networks (task a2; impact a0, b2, c4, e1) at the served size (hidden
128-128, random weights). The access log is at `--log-level` (default warning: at info every
act writes an access line while the no-op floor's probe lines are debug, which would tilt the
comparison; `--log-level info` measures that cost).
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import httpx
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from machine import describe  # noqa: E402
from wrk_server import (  # noqa: E402
    LOAD_CPU,
    SERVER_CPU,
    UNIT_MS,
    free_port,
    start_floor,
    start_server,
    stop,
)

from envs.particle.scenarios import FIVE_AGENTS  # noqa: E402

EGO, PARTNERS = FIVE_AGENTS
BATCH = 256
ACT = "/coexist.v1.PolicyService/Act"
ACT_BATCH = "/coexist.v1.PolicyService/ActBatch"
HEALTH = "/grpc.health.v1.Health/Check"
# (transport, case, rows per request, concurrencies, runner(concurrency, tmp) -> Case)
Planned = tuple[str, str, int, tuple[int, ...], Callable[[int, Path], "Case"]]


def build_store(url: str) -> None:
    """Register the FIVE_AGENTS networks (served size, random weights) at `url`."""
    import torch

    from model_store import Lineage, impact_model_name, open_store, task_model_name
    from policy.qnet import QNetSpec, QNetwork, weights_to_safetensors

    spec = QNetSpec(obs_dim=8, n_actions=5, hidden=(128, 128))
    names = [(task_model_name("particle", EGO), "task", EGO)]
    names += [(impact_model_name("particle", g), "impact", g) for g in PARTNERS]
    with open_store(url, create=True) as store:
        for seed, (name, kind, goal) in enumerate(names):
            torch.manual_seed(seed)
            store.create_model(
                name, env="particle", kind=kind, goals=[goal], obs_dim=8, n_actions=5, exist_ok=True
            )
            store.register_version(
                name,
                spec=spec.to_json(),
                weights=weights_to_safetensors(QNetwork(spec)),
                lineage=Lineage(config={"alpha": 0.02}, seed=seed),
                aliases=("production",),
            )


def observations(rows: int) -> np.ndarray:
    rng = np.random.default_rng(0)
    obs_BD = rng.uniform(-1, 1, (rows, 4 * (1 + len(PARTNERS))))
    obs_BD[:, 2::4] *= 0.3  # velocities within the speed cap
    obs_BD[:, 3::4] *= 0.3
    return obs_BD


def rest_bodies() -> dict[str, bytes]:
    partners = [{"index": i + 1, "goal": g} for i, g in enumerate(PARTNERS)]
    common = {"env": "particle", "ego_goal": EGO, "partners": partners, "method": "aail"}
    act = {**common, "observation": observations(1)[0].tolist()}
    rows = {**common, "observations": observations(BATCH).tolist()}
    default = {k: v for k, v in act.items() if k != "method"}  # aail_bounded, what users get
    bodies = {
        "act": act,
        "batch": {**rows, "format": "columns"},
        "batch rows": rows,
        "act default": default,
    }
    return {name: json.dumps(body).encode() for name, body in bodies.items()}


def grpc_bodies() -> dict[str, bytes]:
    """Length-prefixed (uncompressed) protobuf messages, as they travel in a gRPC stream."""
    from grpc_health.v1 import health_pb2

    from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb

    partners = [pb.PartnerSpec(index=i + 1, goal=g) for i, g in enumerate(PARTNERS)]
    act = pb.ActRequest(
        env="particle",
        ego_goal=EGO,
        observation=observations(1)[0],
        partners=partners,
        method="aail",
    )
    obs_BD = observations(BATCH)
    matrix = pb.Matrix(rows=BATCH, cols=obs_BD.shape[1], values=obs_BD.ravel())
    batch = pb.ActBatchRequest(
        env="particle",
        ego_goal=EGO,
        observation_matrix=matrix,
        partners=partners,
        method="aail",
        format=pb.BATCH_FORMAT_COLUMNS,
    )
    rows = pb.ActBatchRequest(
        env="particle",
        ego_goal=EGO,
        partners=partners,
        method="aail",
        observations=[pb.Vector(values=row) for row in obs_BD],
    )
    default = pb.ActRequest(
        env="particle", ego_goal=EGO, observation=observations(1)[0], partners=partners
    )
    messages = {
        "noop": health_pb2.HealthCheckRequest(),
        "act": act,
        "batch": batch,
        "batch rows": rows,
        "act default": default,
    }

    def frame(data: bytes) -> bytes:
        return b"\x00" + len(data).to_bytes(4, "big") + data

    return {name: frame(m.SerializeToString()) for name, m in messages.items()}


def check_payloads(http_port: int, grpc_port: int, rest: dict[str, bytes]) -> None:
    """One correct answer per payload before anything is timed."""
    import grpc

    from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb
    from services.grpc_api.gen.coexist.v1 import policy_pb2_grpc as pb_grpc

    base = f"http://127.0.0.1:{http_port}"

    def post(path: str, body: bytes) -> dict[str, Any]:
        reply = httpx.post(base + path, content=body, headers={"content-type": "application/json"})
        reply.raise_for_status()
        answer: dict[str, Any] = reply.json()
        return answer

    assert len(post("/v1/act", rest["act"])["probs"]) == 5
    assert post("/v1/act", rest["act default"])["method"] == "aail_bounded"
    columns = post("/v1/act:batch", rest["batch"])
    assert len(columns["actions"]) == len(columns["probs"]) == BATCH, "REST columns"
    assert len(post("/v1/act:batch", rest["batch rows"])["results"]) == BATCH, "REST rows"
    with grpc.insecure_channel(f"127.0.0.1:{grpc_port}") as channel:
        stub = pb_grpc.PolicyServiceStub(channel)
        bodies = grpc_bodies()
        act = pb.ActRequest.FromString(bodies["act"][5:])
        default = pb.ActRequest.FromString(bodies["act default"][5:])
        assert stub.Act(default).method == "aail_bounded"
        assert len(stub.Act(act).probs) == 5
        answer = stub.ActBatch(pb.ActBatchRequest.FromString(bodies["batch"][5:])).columns
        assert answer.rows == len(answer.actions) == BATCH, "gRPC columns"
        assert len(answer.probs) == BATCH * answer.n_actions, "gRPC columns"
        rows = pb.ActBatchRequest.FromString(bodies["batch rows"][5:])
        assert len(stub.ActBatch(rows).results) == BATCH, "gRPC rows"


@dataclass
class Case:
    transport: str
    case: str
    concurrency: int
    requests: int
    seconds: float
    p50_ms: float
    rows: int  # observations per request
    failed: int

    @property
    def rps(self) -> float:
        return self.requests / self.seconds

    @property
    def actions_per_s(self) -> float:
        return self.rps * self.rows


def run_wrk(url: str, body: bytes | None, concurrency: int, duration: float, tmp: Path) -> Case:
    script = tmp / "wrk.lua"
    if body is None:
        script.write_text("wrk.method = 'GET'\n")
    else:
        (tmp / "body.json").write_bytes(body)
        script.write_text(
            "wrk.method = 'POST'\n"
            "wrk.headers['Content-Type'] = 'application/json'\n"
            f"local f = io.open('{tmp / 'body.json'}', 'rb'); wrk.body = f:read('*a'); f:close()\n"
        )
    base = [
        "taskset",
        "-c",
        LOAD_CPU,
        "wrk",
        "-t1",
        f"-c{concurrency}",
        "--timeout",
        "10s",
        "-s",
        str(script),
    ]
    subprocess.run([*base, "-d1s", url], check=True, capture_output=True)  # warm-up
    out = subprocess.run(
        [*base, f"-d{round(duration)}s", "--latency", url],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    requests, seconds, p50_ms, failed = parse_wrk(out)
    return Case("REST", "", concurrency, requests, seconds, p50_ms, 1, failed)


def parse_wrk(out: str) -> tuple[int, float, float, int]:
    """(requests, seconds, p50 ms, failed) from `wrk --latency` output; failed counts non-2xx
    answers and socket errors (connect, read, write, timeout)."""
    took = re.search(r"(\d+) requests in ([\d.]+)(ms|s|m),", out)
    p50 = re.search(r"50%\s+([\d.]+)(us|ms|s)", out)
    if took is None or p50 is None:
        raise ValueError(f"unexpected wrk output:\n{out}")
    seconds = float(took.group(2)) * {"ms": 1e-3, "s": 1.0, "m": 60.0}[took.group(3)]
    failed = re.search(r"Non-2xx or 3xx responses: (\d+)", out)
    errors = re.search(r"Socket errors: .*", out)
    n_failed = int(failed.group(1)) if failed else 0
    if errors:
        n_failed += sum(int(n) for n in re.findall(r"\d+", errors.group(0)))
    return int(took.group(1)), seconds, float(p50.group(1)) * UNIT_MS[p50.group(2)], n_failed


def run_h2load(url: str, body: bytes, concurrency: int, duration: float, tmp: Path) -> Case:
    data, log = tmp / "body.grpc", tmp / "h2load.log"
    data.write_bytes(body)
    log.unlink(missing_ok=True)
    command = [
        "taskset",
        "-c",
        LOAD_CPU,
        "h2load",
        "-t1",
        f"-c{concurrency}",
        "-m1",
        "-H",
        "content-type: application/grpc",
        "-H",
        "te: trailers",
        "-d",
        str(data),
        "--warm-up-time",
        "1",
        "-D",
        str(round(duration)),
        "--log-file",
        str(log),
        url,
    ]
    out = subprocess.run(command, check=True, capture_output=True, text=True).stdout
    requests, seconds, p50_ms, failed = parse_h2load(out, log.read_text())
    return Case("gRPC", "", concurrency, requests, seconds, p50_ms, 1, failed)


def parse_h2load(out: str, log_text: str) -> tuple[int, float, float, int]:
    """(requests, seconds, p50 ms, failed) from h2load's output and its `--log-file` (one line
    per request: start time, status, microseconds to the end of the response)."""
    found = re.search(r"finished in ([\d.]+)(ms|s), ([\d.]+) req/s", out)
    status = re.search(
        r"requests: \d+ total, \d+ started, (\d+) done, (\d+) succeeded, "
        r"(\d+) failed, (\d+) errored",
        out,
    )
    micros = [int(line.split("\t")[2]) for line in log_text.splitlines() if line.strip()]
    if found is None or status is None or not micros:
        raise ValueError(f"unexpected h2load output:\n{out}")
    seconds = float(found.group(1)) * (1e-3 if found.group(2) == "ms" else 1.0)
    failed = int(status.group(3)) + int(status.group(4))
    return int(status.group(2)), seconds, statistics.median(micros) / 1000.0, failed


def coexist_plan(http_port: int, grpc_port: int, duration: float) -> list[Planned]:
    rest, grpc_b = rest_bodies(), grpc_bodies()
    http, h2 = f"http://127.0.0.1:{http_port}", f"http://127.0.0.1:{grpc_port}"
    both, one = (1, 32), (1,)
    return [
        ("REST", "no-op", 1, both, lambda c, t: run_wrk(http + "/healthz", None, c, duration, t)),
        (
            "REST",
            "act",
            1,
            both,
            lambda c, t: run_wrk(http + "/v1/act", rest["act"], c, duration, t),
        ),
        (
            "REST",
            "batch",
            BATCH,
            both,
            lambda c, t: run_wrk(http + "/v1/act:batch", rest["batch"], c, duration, t),
        ),
        (
            "REST",
            "batch rows",
            BATCH,
            one,
            lambda c, t: run_wrk(http + "/v1/act:batch", rest["batch rows"], c, duration, t),
        ),
        (
            "REST",
            "act default",
            1,
            one,
            lambda c, t: run_wrk(http + "/v1/act", rest["act default"], c, duration, t),
        ),
        (
            "gRPC",
            "no-op",
            1,
            both,
            lambda c, t: run_h2load(h2 + HEALTH, grpc_b["noop"], c, duration, t),
        ),
        ("gRPC", "act", 1, both, lambda c, t: run_h2load(h2 + ACT, grpc_b["act"], c, duration, t)),
        (
            "gRPC",
            "batch",
            BATCH,
            both,
            lambda c, t: run_h2load(h2 + ACT_BATCH, grpc_b["batch"], c, duration, t),
        ),
        (
            "gRPC",
            "batch rows",
            BATCH,
            one,
            lambda c, t: run_h2load(h2 + ACT_BATCH, grpc_b["batch rows"], c, duration, t),
        ),
        (
            "gRPC",
            "act default",
            1,
            one,
            lambda c, t: run_h2load(h2 + ACT, grpc_b["act default"], c, duration, t),
        ),
    ]


def floor_plan(kind: str, port: int, duration: float) -> list[Planned]:
    """The bare server's no-op (`floor_servers.py`), at the concurrencies of coexist's no-op;
    for gRPC also its act-shaped act at c = 1."""
    if kind == "rest":
        url = f"http://127.0.0.1:{port}/healthz"
        return [
            ("REST", "floor no-op", 1, (1, 32), lambda c, t: run_wrk(url, None, c, duration, t))
        ]
    h2, bodies = f"http://127.0.0.1:{port}", grpc_bodies()
    return [
        (
            "gRPC",
            "floor no-op",
            1,
            (1, 32),
            lambda c, t: run_h2load(h2 + HEALTH, bodies["noop"], c, duration, t),
        ),
        (
            "gRPC",
            "floor act",
            1,
            (1,),
            lambda c, t: run_h2load(h2 + ACT, bodies["act"], c, duration, t),
        ),
    ]


def measure(plan: list[Planned]) -> list[Case]:
    cases = []
    with tempfile.TemporaryDirectory() as tmp:
        for transport, case, rows, concurrencies, runner in plan:
            for concurrency in concurrencies:
                result = runner(concurrency, Path(tmp))
                result.transport, result.case, result.rows = transport, case, rows
                print(
                    f"  {transport:4} {case:11} c={concurrency:<2} p50 {result.p50_ms:7.3f} ms "
                    f"{result.rps:9,.0f} req/s  failed {result.failed}",
                    flush=True,
                )
                cases.append(result)
    return cases


def measure_round(url: str, duration: float, log_level: str, floors_first: bool) -> list[Case]:
    """One round: coexist's cases with only coexist running, then each floor alone (the other
    order with `floors_first`); the cases come back in one fixed order whatever the order."""

    def coexist() -> list[Case]:
        http_port, grpc_port = free_port(), free_port()
        server = start_server(url, http_port, grpc_port=grpc_port, log_level=log_level)
        try:
            check_payloads(http_port, grpc_port, rest_bodies())
            return measure(coexist_plan(http_port, grpc_port, duration))
        finally:
            stop(server)

    def floor(kind: str) -> list[Case]:
        port = free_port()
        server = start_floor(kind, port)
        try:
            return measure(floor_plan(kind, port, duration))
        finally:
            stop(server)

    if floors_first:
        floors = floor("rest") + floor("grpc")
        return coexist() + floors
    ours = coexist()
    return ours + floor("rest") + floor("grpc")


def verdicts(cases: list[Case]) -> list[tuple[str, float, float, bool]]:
    """(target, measured ratio, required, met) per transport."""
    get = {(c.transport, c.case, c.concurrency): c for c in cases}
    rows = []
    for t in ("REST", "gRPC"):
        latency = get[t, "act", 1].p50_ms / get[t, "no-op", 1].p50_ms
        rows.append((f"{t}: act p50 / no-op p50 (c=1)", latency, 2.0, latency <= 2.0))
        share = get[t, "act", 32].rps / get[t, "no-op", 32].rps
        rows.append((f"{t}: act req/s / no-op req/s (c=32)", share, 0.4, share >= 0.4))
        batch = get[t, "batch", 1].actions_per_s / get[t, "act", 1].rps
        rows.append((f"{t}: batch actions/s / act req/s (c=1)", batch, 30.0, batch >= 30.0))
    if ("REST", "floor no-op", 1) in get and ("gRPC", "floor no-op", 1) in get:
        rows += floor_verdicts(get)
    return rows


def floor_verdicts(get: dict[tuple[str, str, int], Case]) -> list[tuple[str, float, float, bool]]:
    """The floor targets: coexist against the bare servers (what coexist adds to a request)."""
    rows = []
    floor_rest, floor_grpc = get["REST", "floor no-op", 1], get["gRPC", "floor no-op", 1]
    against = [
        (
            "REST: no-op p50 / bare FastAPI no-op p50 (c=1)",
            get["REST", "no-op", 1],
            floor_rest,
            1.15,
        ),
        ("REST: act p50 / bare FastAPI no-op p50 (c=1)", get["REST", "act", 1], floor_rest, 1.8),
        (
            "gRPC: health p50 / bare grpcio health p50 (c=1)",
            get["gRPC", "no-op", 1],
            floor_grpc,
            1.15,
        ),
        ("gRPC: act p50 / bare grpcio health p50 (c=1)", get["gRPC", "act", 1], floor_grpc, 1.5),
    ]
    for name, ours, floor, required in against:
        ratio = ours.p50_ms / floor.p50_ms
        rows.append((name, ratio, required, ratio <= required))
    share = get["REST", "act", 32].rps / get["REST", "floor no-op", 32].rps
    rows.append(("REST: act req/s / bare FastAPI no-op req/s (c=32)", share, 0.4, share >= 0.4))
    return rows


def median_cases(rounds: list[list[Case]]) -> list[Case]:
    """Per case, the median p50 and the median req/s over the rounds (as one 1 s `Case`)."""
    merged = []
    for same in zip(*rounds, strict=True):
        first = same[0]
        merged.append(
            Case(
                first.transport,
                first.case,
                first.concurrency,
                round(statistics.median(c.rps for c in same)),
                1.0,
                statistics.median(c.p50_ms for c in same),
                first.rows,
                sum(c.failed for c in same),
            )
        )
    return merged


def median_verdicts(rounds: list[list[Case]]) -> list[tuple[str, float, float, bool]]:
    """Each target's median over the rounds of its per-round ratio."""
    per_round = [verdicts(cases) for cases in rounds]
    out = []
    for same in zip(*per_round, strict=True):
        name, _, required, _ = same[0]
        value = statistics.median(v for _, v, _, _ in same)
        out.append(
            (name, value, required, value <= required if "p50" in name else value >= required)
        )
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--duration", type=float, default=5.0)
    parser.add_argument("--rounds", type=int, default=1, help="run the whole plan N times")
    parser.add_argument("--log-level", default="warning", choices=("info", "warning"))
    parser.add_argument("--json", type=Path, help="also write the figures here")
    args = parser.parse_args()
    for tool in ("wrk", "h2load", "taskset"):
        if shutil.which(tool) is None:
            raise SystemExit(f"{tool} not found: apt-get install wrk nghttp2-client util-linux")
    with tempfile.TemporaryDirectory() as tmp:
        url = f"sqlite:///{tmp}/models.db"
        build_store(url)
        print(describe())
        print(
            f"servers on CPU {SERVER_CPU} (one at a time), load generators on CPU {LOAD_CPU}, "
            f"{args.duration:g} s per case, log level {args.log_level}"
        )
        rounds = []
        for r in range(args.rounds):
            if args.rounds > 1:
                print(f"round {r + 1} of {args.rounds}", flush=True)
            rounds.append(measure_round(url, args.duration, args.log_level, r % 2 == 1))
    cases = median_cases(rounds)
    what = f" (medians of {args.rounds} rounds)" if args.rounds > 1 else ""
    print(f"\n| transport | case | c | p50 ms | req/s | actions/s | failed |{what}")
    print("|---|---|---|---|---|---|---|")
    for c in cases:
        print(
            f"| {c.transport} | {c.case} | {c.concurrency} | {c.p50_ms:.3f} | {c.rps:,.0f} | "
            f"{c.actions_per_s:,.0f} | {c.failed} |"
        )
    print("\n| target | measured | required | met |\n|---|---|---|---|")
    results = median_verdicts(rounds)
    for name, value, required, met in results:
        sign = "<=" if "p50" in name else ">="
        print(f"| {name} | {value:.2f} | {sign} {required:g} | {'yes' if met else 'NO'} |")
    if args.json:
        args.json.write_text(
            json.dumps(
                {
                    "machine": describe(),
                    "cases": [
                        {**asdict(c), "rps": c.rps, "actions_per_s": c.actions_per_s} for c in cases
                    ],
                    "rounds": [[{**asdict(c), "rps": c.rps} for c in cases] for cases in rounds],
                    "targets": [
                        {"target": n, "measured": v, "required": r, "met": m}
                        for n, v, r, m in results
                    ],
                },
                indent=2,
            )
        )
    handler = handler_share(cases)
    if handler is not None:
        print(
            "\ngRPC act p50 = the act-shaped floor's {:.3f} ms + {:.3f} ms of coexist's handler "
            "and interceptor in grpcio's server".format(*handler)
        )
    if any(c.failed for c in cases):
        raise SystemExit("some requests failed: the figures above are not valid")


def handler_share(cases: list[Case]) -> tuple[float, float] | None:
    """(the act-shaped floor's p50, coexist's gRPC act p50 minus it) in ms, at c = 1; None
    without the floor."""
    get = {(c.transport, c.case, c.concurrency): c for c in cases}
    floor, ours = get.get(("gRPC", "floor act", 1)), get.get(("gRPC", "act", 1))
    if floor is None or ours is None:
        return None
    return floor.p50_ms, ours.p50_ms - floor.p50_ms


if __name__ == "__main__":
    main()
