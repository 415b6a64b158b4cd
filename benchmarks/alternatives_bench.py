"""coexist's server beside what a user would pick instead, measured in one run: the same AAIL
act on the same networks, served by `coexist serve` (REST and gRPC), by a bare FastAPI app with
numpy, by Ray Serve and by a hand-written grpcio server with numpy.

Run: `nice -n -15 .venv/bin/python benchmarks/alternatives_bench.py [--duration 3] [--rounds 3]
[--servers coexist fastapi ray grpcio] [--ray-max-ongoing-requests N] [--json OUT]` (needs
`wrk`, `h2load` and `taskset`; Ray Serve is in the venv).

| server    | what                                                                             |
|-----------|----------------------------------------------------------------------------------|
| `coexist` | `coexist serve` (REST only) as `benchmarks/serving.py` starts it                  |
| `fastapi` | `alternative_servers.py fastapi`: a FastAPI app on coexist's uvicorn settings     |
|           | (uvloop, httptools, one worker, no access log), a pydantic body, the networks'    |
|           | production versions read once from the store, the act in numpy (`NumpyAAIL`)     |
| `ray`     | `alternative_servers.py ray`: the same app as the ingress of a one-replica Ray    |
|           | Serve deployment on a local Ray with one CPU, Serve's defaults otherwise (its    |
|           | `max_ongoing_requests` unless `--ray-max-ongoing-requests`: beyond it the        |
|           | replica rejects a request and the proxy retries it after a back-off, at c = 32)  |
| `grpcio`  | `alternative_servers.py grpcio`: the project's `PolicyService/Act` written by     |
|           | hand on grpcio's sync server with coexist's thread pool, the act in numpy         |

Why: coexist's own targets compare it with bare servers that do nothing (`serving.py`'s
floors); this compares it with servers that do the same work, the way a user would write it
without coexist's engine and compiled kernels.

Every server runs alone, pinned to CPU 0 (`taskset`; Ray's processes inherit it), the load
generator on CPU 1, on `benchmarks/serving.py`'s store (`build_store`: task a2, impact a0, b2,
c4, e1, hidden 128-128) and its act (1 ego + 4 partners, method aail): the REST body
`rest_bodies()["act"]` under `wrk`, the same request as protobuf (`grpc_bodies()["act"]`) under
`h2load`. Cases, each 1 s of warm-up then `--duration` seconds on persistent connections: over
REST (coexist, fastapi, ray) the no-op (`GET /healthz`) at c = 1 and the act (`POST /v1/act`)
at c = 1 and c = 32; over gRPC (coexist, grpcio) the act (`coexist.v1.PolicyService/Act`) at
c = 1 and c = 32. Before any case is timed, each server's `probs` for the act (both transports
for coexist) must equal coexist's REST answer within 1e-5 (the same maths), else the run
stops. A round measures every server, one after the other (round 1 starts with coexist, whose
answer is the reference; even rounds run the other way round); the tables show each figure's
median over the rounds and the ratios of the medians: to coexist's, and the two gRPC targets
(coexist's gRPC act p50 <= its REST act p50 on the same request; coexist's gRPC act req/s at
c = 32 >= 1.3x the grpcio server's). A run with any failed request (non-2xx answer, socket
error, failed gRPC stream) fails.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
from dataclasses import asdict
from pathlib import Path

import httpx
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from machine import describe  # noqa: E402
from serving import ACT, Case, build_store, grpc_bodies, rest_bodies, run_h2load, run_wrk  # noqa: E402
from wrk_server import (  # noqa: E402
    LOAD_CPU,
    SERVER_CPU,
    free_port,
    grpc_ok,
    http_ok,
    start_server,
    stop,
    wait_ready,
)

SERVERS = ("coexist", "fastapi", "ray", "grpcio")
LABELS = {
    "coexist": "coexist (`coexist serve`)",
    "fastapi": "FastAPI + numpy",
    "ray": "Ray Serve, 1 replica",
    "grpcio": "grpcio + numpy, by hand",
}
REST_SERVERS = ("coexist", "fastapi", "ray")
GRPC_SERVERS = ("coexist", "grpcio")
# case -> (its p50's key, its req/s's key) in `medians`' figures (None: not shown)
FIGURES = {
    "no-op c=1": ("noop_p50_ms", "noop_rps_c1"),
    "act c=1": ("act_p50_ms", "act_rps_c1"),
    "act c=32": (None, "act_rps_c32"),
    "grpc act c=1": ("grpc_act_p50_ms", "grpc_act_rps_c1"),
    "grpc act c=32": (None, "grpc_act_rps_c32"),
}
GRPC_P50_OVER_REST = 1.0  # coexist's gRPC act p50 / its REST act p50, at most
GRPC_OVER_GRPCIO = 1.3  # coexist's gRPC act req/s at c = 32 / the grpcio server's, at least
PROBS_ATOL = 1e-5
READY_S = 180.0  # Ray starts its head node, Serve's controller, proxy and replica on one CPU
STOP_S = 60.0


def start_alternative(
    kind: str, port: int, url: str, log: Path, extra: tuple[str, ...] = ()
) -> subprocess.Popen[bytes]:
    """`alternative_servers.py kind port url` on CPU `SERVER_CPU` in a session of its own,
    once `/healthz` answers (through Ray Serve's proxy and replica for `ray`; the health
    service's `Check` for `grpcio`)."""
    command = [
        "taskset",
        "-c",
        SERVER_CPU,
        sys.executable,
        str(ROOT / "benchmarks/alternative_servers.py"),
        kind,
        str(port),
        url,
        *extra,
    ]
    with log.open("wb") as out:
        server = subprocess.Popen(
            command, stdout=out, stderr=subprocess.STDOUT, start_new_session=True
        )
    health = f"http://127.0.0.1:{port}/healthz"
    log_tail = lambda: f":\n{log.read_text()[-3000:]}"  # noqa: E731  (read once it exited)
    ready = (lambda: grpc_ok(port)) if kind == "grpcio" else (lambda: http_ok(health, timeout=2))
    if wait_ready(server, ready, f"the {kind} server", READY_S, log_tail):
        return server
    stop_alternative(server)
    raise SystemExit(f"the {kind} server did not answer within {READY_S:g} s")


def session_members(sid: int) -> list[int]:
    """The processes of session `sid` (this run's server and what it started: Ray's daemons
    and actors run in process groups of their own, but in the server's session)."""
    members = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2 :].split()  # after "pid (comm) "
        if int(fields[3]) == sid and fields[0] != "Z":  # fields: state, ppid, pgrp, session
            members.append(int(entry.name))
    return members


def stop_alternative(server: subprocess.Popen[bytes]) -> None:
    """SIGTERM to the server alone (it shuts Serve and Ray down), then SIGKILL to whatever of
    its session is left after `STOP_S` s or after it exited."""
    try:
        server.send_signal(signal.SIGTERM)
        server.wait(timeout=STOP_S)
    except subprocess.TimeoutExpired:
        pass
    for pid in session_members(server.pid):
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)
    server.wait()


def act_probs(port: int) -> np.ndarray:
    reply = httpx.post(
        f"http://127.0.0.1:{port}/v1/act",
        content=rest_bodies()["act"],
        headers={"content-type": "application/json"},
        timeout=30,
    )
    reply.raise_for_status()
    probs: list[float] = reply.json()["probs"]
    return np.asarray(probs, dtype=np.float64)


def grpc_act_probs(port: int) -> np.ndarray:
    """The probabilities of the gRPC act `h2load` posts, through a grpcio channel."""
    import grpc

    from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb

    request = pb.ActRequest.FromString(grpc_bodies()["act"][5:])  # after the 5-byte prefix
    with grpc.insecure_channel(f"127.0.0.1:{port}") as channel:
        act = channel.unary_unary(
            ACT,
            request_serializer=pb.ActRequest.SerializeToString,
            response_deserializer=pb.ActResponse.FromString,
        )
        answer = act(request, timeout=30)
    return np.asarray(answer.probs, dtype=np.float64)


def check_same_probs(kind: str, probs: np.ndarray, reference: np.ndarray) -> None:
    """Fail loudly unless `probs` are coexist's within `PROBS_ATOL`."""
    gap = float(np.max(np.abs(probs - reference))) if probs.shape == reference.shape else np.inf
    if not gap <= PROBS_ATOL:
        raise SystemExit(
            f"{kind}: probs {probs.tolist()} differ from coexist's {reference.tolist()} by "
            f"{gap:.2e} > {PROBS_ATOL:g}: not the same maths, nothing timed"
        )


def measure_server(
    kind: str,
    url: str,
    duration: float,
    tmp: Path,
    reference: dict[str, np.ndarray],
    ray_max_ongoing: int | None = None,
) -> dict[str, Case]:
    """The cases of one server, started alone and stopped after; coexist's REST act answer
    becomes `reference["probs"]`, every other answer is checked against it first."""
    port = free_port()
    grpc_port = free_port() if kind == "coexist" else port
    if kind == "coexist":
        server = start_server(url, port, grpc_port=grpc_port)
    else:
        extra = (str(ray_max_ongoing),) if kind == "ray" and ray_max_ongoing else ()
        server = start_alternative(kind, port, url, tmp / f"{kind}.log", extra)
    try:
        if kind in REST_SERVERS:
            probs = act_probs(port)
            if kind == "coexist":
                reference.setdefault("probs", probs)
            check_same_probs(kind, probs, reference["probs"])
        if kind in GRPC_SERVERS:
            check_same_probs(f"{kind} (gRPC)", grpc_act_probs(grpc_port), reference["probs"])
        cases = {}
        if kind in REST_SERVERS:
            base, act = f"http://127.0.0.1:{port}", rest_bodies()["act"]
            cases["no-op c=1"] = run_wrk(f"{base}/healthz", None, 1, duration, tmp)
            cases["act c=1"] = run_wrk(f"{base}/v1/act", act, 1, duration, tmp)
            cases["act c=32"] = run_wrk(f"{base}/v1/act", act, 32, duration, tmp)
        if kind in GRPC_SERVERS:
            target, message = f"http://127.0.0.1:{grpc_port}{ACT}", grpc_bodies()["act"]
            cases["grpc act c=1"] = run_h2load(target, message, 1, duration, tmp)
            cases["grpc act c=32"] = run_h2load(target, message, 32, duration, tmp)
    finally:
        if kind == "coexist":
            stop(server)
        else:
            stop_alternative(server)
    for name, case in cases.items():
        case.case = name
        print(
            f"  {kind:8} {name:13} p50 {case.p50_ms:8.3f} ms {case.rps:9,.0f} req/s  "
            f"failed {case.failed}",
            flush=True,
        )
    return cases


def medians(rounds: list[dict[str, dict[str, Case]]]) -> dict[str, dict[str, float]]:
    """Per server, the median over the rounds of each figure of the tables (the cases it
    served), and its failed requests over all rounds."""
    figures: dict[str, dict[str, float]] = {}
    for kind, cases in rounds[0].items():
        figures[kind] = {}
        for case, (p50_key, rps_key) in FIGURES.items():
            if case not in cases:
                continue
            if p50_key is not None:
                figures[kind][p50_key] = statistics.median(r[kind][case].p50_ms for r in rounds)
            figures[kind][rps_key] = statistics.median(r[kind][case].rps for r in rounds)
        figures[kind]["failed"] = float(sum(c.failed for r in rounds for c in r[kind].values()))
    return figures


def targets(figures: dict[str, dict[str, float]]) -> list[tuple[str, float, str, bool]]:
    """(target, ratio of the medians, required, met) for the gRPC targets whose servers ran."""
    ours = figures["coexist"]
    rows = []
    if "grpc_act_p50_ms" in ours and "act_p50_ms" in ours:
        ratio = ours["grpc_act_p50_ms"] / ours["act_p50_ms"]
        rows.append(
            (
                "coexist: gRPC act p50 / REST act p50 (c=1, the same request)",
                ratio,
                f"<= {GRPC_P50_OVER_REST:g}",
                ratio <= GRPC_P50_OVER_REST,
            )
        )
    if "grpcio" in figures:
        ratio = ours["grpc_act_rps_c32"] / figures["grpcio"]["grpc_act_rps_c32"]
        rows.append(
            (
                "coexist gRPC act req/s / grpcio + numpy's (c=32)",
                ratio,
                f">= {GRPC_OVER_GRPCIO:g}",
                ratio >= GRPC_OVER_GRPCIO,
            )
        )
    return rows


def tables(figures: dict[str, dict[str, float]]) -> str:
    """The servers' tables, their ratios to coexist's figures and the gRPC targets, in
    markdown."""
    ours = figures["coexist"]
    rest = {kind: f for kind, f in figures.items() if "act_p50_ms" in f}
    grpc = {kind: f for kind, f in figures.items() if "grpc_act_p50_ms" in f}
    lines = [
        "| server | no-op p50 | no-op req/s c=1 | act p50 | act req/s c=1 | act req/s c=32 |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for kind, f in rest.items():
        lines.append(
            f"| {LABELS[kind]} | {f['noop_p50_ms']:.3f} ms | {f['noop_rps_c1']:,.0f} | "
            f"{f['act_p50_ms']:.3f} ms | {f['act_rps_c1']:,.0f} | {f['act_rps_c32']:,.0f} |"
        )
    lines += [
        "",
        "| server | act p50 / coexist's | act req/s c=1 / coexist's | act req/s c=32 / coexist's |",
        "|---|---:|---:|---:|",
    ]
    for kind, f in rest.items():
        lines.append(
            f"| {LABELS[kind]} | {f['act_p50_ms'] / ours['act_p50_ms']:.2f}x | "
            f"{f['act_rps_c1'] / ours['act_rps_c1']:.2f}x | "
            f"{f['act_rps_c32'] / ours['act_rps_c32']:.2f}x |"
        )
    if grpc:
        lines += [
            "",
            "| server, gRPC | act p50 | act req/s c=1 | act req/s c=32 |",
            "|---|---:|---:|---:|",
        ]
        for kind, f in grpc.items():
            lines.append(
                f"| {LABELS[kind]} | {f['grpc_act_p50_ms']:.3f} ms | "
                f"{f['grpc_act_rps_c1']:,.0f} | {f['grpc_act_rps_c32']:,.0f} |"
            )
    found = targets(figures)
    if found:
        lines += ["", "| target | measured | required | met |", "|---|---:|---|---|"]
        for name, ratio, required, met in found:
            lines.append(f"| {name} | {ratio:.2f} | {required} | {'yes' if met else 'NO'} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--duration", type=float, default=3.0, help="seconds per case")
    parser.add_argument("--rounds", type=int, default=3, help="medians over this many rounds")
    parser.add_argument("--servers", nargs="+", choices=SERVERS, default=list(SERVERS))
    parser.add_argument(
        "--ray-max-ongoing-requests",
        type=int,
        help="the Ray Serve deployment's max_ongoing_requests (default: Serve's)",
    )
    parser.add_argument("--json", type=Path, help="also write the figures here")
    args = parser.parse_args()
    if "coexist" not in args.servers:
        parser.error("--servers: coexist is the reference every alternative is checked against")
    for tool in ("wrk", "h2load", "taskset"):
        if shutil.which(tool) is None:
            raise SystemExit(f"{tool} not found: apt-get install wrk nghttp2-client util-linux")
    order = ["coexist"] + [s for s in SERVERS if s in args.servers and s != "coexist"]
    reference: dict[str, np.ndarray] = {}
    with tempfile.TemporaryDirectory(prefix="coexist-alternatives-") as tmp_dir:
        tmp = Path(tmp_dir)
        url = f"sqlite:///{tmp / 'models.db'}"
        build_store(url)
        print(describe())
        print(
            f"servers on CPU {SERVER_CPU} (one at a time), wrk and h2load on CPU {LOAD_CPU}, "
            f"{args.duration:g} s per case, {args.rounds} round(s)",
            flush=True,
        )
        rounds = []
        for r in range(args.rounds):
            print(f"round {r + 1} of {args.rounds}", flush=True)
            this_order = order if r % 2 == 0 else order[::-1]
            measured = {
                kind: measure_server(
                    kind, url, args.duration, tmp, reference, args.ray_max_ongoing_requests
                )
                for kind in this_order
            }
            rounds.append({kind: measured[kind] for kind in order})
    figures = medians(rounds)
    what = f"medians of {args.rounds} rounds" if args.rounds > 1 else "one round"
    print(f"\n{tables(figures)}\n\n({what}, {args.duration:g} s per case)")
    if args.json:
        args.json.write_text(
            json.dumps(
                {
                    "machine": describe(),
                    "duration_s": args.duration,
                    "ray_max_ongoing_requests": args.ray_max_ongoing_requests,
                    "medians": figures,
                    "targets": [
                        {"target": n, "measured": v, "required": r, "met": m}
                        for n, v, r, m in targets(figures)
                    ],
                    "reference_probs": reference["probs"].tolist(),
                    "rounds": [
                        {
                            kind: {name: {**asdict(c), "rps": c.rps} for name, c in cases.items()}
                            for kind, cases in measured_round.items()
                        }
                        for measured_round in rounds
                    ],
                },
                indent=2,
            )
        )
    if any(f["failed"] for f in figures.values()):
        raise SystemExit("some requests failed: the figures above are not valid")


if __name__ == "__main__":
    main()
