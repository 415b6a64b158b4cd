"""coexist's REST server beside what a user would pick instead, measured in one run:
the same AAIL act on the same networks, served by `coexist serve`, by a bare FastAPI app with
numpy and by Ray Serve.

Run: `nice -n -15 .venv/bin/python benchmarks/alternatives_bench.py [--duration 3] [--rounds 3]
[--servers coexist fastapi ray] [--ray-max-ongoing-requests N] [--json OUT]` (needs `wrk` and `taskset`; Ray Serve is in the
venv).

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

Why: coexist's own targets compare it with bare servers that do nothing (`serving.py`'s
floors); this compares it with servers that do the same work, the way a user would write it
without coexist's engine and compiled kernels.

Every server runs alone, pinned to CPU 0 (`taskset`; Ray's processes inherit it), `wrk` on
CPU 1, on `benchmarks/serving.py`'s store (`build_store`: task a2, impact a0, b2, c4, e1, hidden
128-128) and its REST act body (`rest_bodies()["act"]`: 1 ego + 4 partners, method aail).
Cases, each 1 s of warm-up then `--duration` seconds on persistent connections: the no-op
(`GET /healthz`) at c = 1, the act (`POST /v1/act`) at c = 1 and at c = 32. Before any case is
timed, each alternative's `probs` for the act body must equal coexist's answer within 1e-5
(the same maths), else the run stops. A round measures every server, one after the other
(round 1 starts with coexist, whose answer is the reference; even rounds run the other way
round); the table shows each figure's median over the rounds and the ratios to coexist's
medians. A run with any failed request (non-2xx answer or socket error) fails.
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
from serving import Case, build_store, rest_bodies, run_wrk  # noqa: E402
from wrk_server import (  # noqa: E402
    LOAD_CPU,
    SERVER_CPU,
    free_port,
    http_ok,
    start_server,
    stop,
    wait_ready,
)

SERVERS = ("coexist", "fastapi", "ray")
LABELS = {
    "coexist": "coexist (`coexist serve`)",
    "fastapi": "FastAPI + numpy",
    "ray": "Ray Serve, 1 replica",
}
CASES = ("no-op c=1", "act c=1", "act c=32")
PROBS_ATOL = 1e-5
READY_S = 180.0  # Ray starts its head node, Serve's controller, proxy and replica on one CPU
STOP_S = 60.0


def start_alternative(
    kind: str, port: int, url: str, log: Path, extra: tuple[str, ...] = ()
) -> subprocess.Popen[bytes]:
    """`alternative_servers.py kind port url` on CPU `SERVER_CPU` in a session of its own,
    once `/healthz` answers (through Ray Serve's proxy and replica for `ray`)."""
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
    if wait_ready(
        server, lambda: http_ok(health, timeout=2), f"the {kind} server", READY_S, log_tail
    ):
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
    """The cases of one server, started alone and stopped after; coexist's act answer becomes
    `reference["probs"]`, every alternative's is checked against it first."""
    port = free_port()
    if kind == "coexist":
        server = start_server(url, port)
    else:
        extra = (str(ray_max_ongoing),) if kind == "ray" and ray_max_ongoing else ()
        server = start_alternative(kind, port, url, tmp / f"{kind}.log", extra)
    try:
        probs = act_probs(port)
        if kind == "coexist":
            reference.setdefault("probs", probs)
        check_same_probs(kind, probs, reference["probs"])
        base, act = f"http://127.0.0.1:{port}", rest_bodies()["act"]
        cases = {
            "no-op c=1": run_wrk(f"{base}/healthz", None, 1, duration, tmp),
            "act c=1": run_wrk(f"{base}/v1/act", act, 1, duration, tmp),
            "act c=32": run_wrk(f"{base}/v1/act", act, 32, duration, tmp),
        }
    finally:
        if kind == "coexist":
            stop(server)
        else:
            stop_alternative(server)
    for name, case in cases.items():
        case.case = name
        print(
            f"  {kind:8} {name:10} p50 {case.p50_ms:8.3f} ms {case.rps:9,.0f} req/s  "
            f"failed {case.failed}",
            flush=True,
        )
    return cases


def medians(rounds: list[dict[str, dict[str, Case]]]) -> dict[str, dict[str, float]]:
    """Per server, the median over the rounds of each figure of the table."""
    figures: dict[str, dict[str, float]] = {}
    for kind in rounds[0]:

        def median(case: str, what: str, kind: str = kind) -> float:
            return float(statistics.median(getattr(r[kind][case], what) for r in rounds))

        figures[kind] = {
            "noop_p50_ms": median("no-op c=1", "p50_ms"),
            "noop_rps_c1": median("no-op c=1", "rps"),
            "act_p50_ms": median("act c=1", "p50_ms"),
            "act_rps_c1": median("act c=1", "rps"),
            "act_rps_c32": median("act c=32", "rps"),
            "failed": float(sum(c.failed for r in rounds for c in r[kind].values())),
        }
    return figures


def tables(figures: dict[str, dict[str, float]]) -> str:
    """The servers' table and their ratios to coexist's figures, in markdown."""
    lines = [
        "| server | no-op p50 | no-op req/s c=1 | act p50 | act req/s c=1 | act req/s c=32 |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for kind, f in figures.items():
        lines.append(
            f"| {LABELS[kind]} | {f['noop_p50_ms']:.3f} ms | {f['noop_rps_c1']:,.0f} | "
            f"{f['act_p50_ms']:.3f} ms | {f['act_rps_c1']:,.0f} | {f['act_rps_c32']:,.0f} |"
        )
    ours = figures["coexist"]
    lines += [
        "",
        "| server | act p50 / coexist's | act req/s c=1 / coexist's | act req/s c=32 / coexist's |",
        "|---|---:|---:|---:|",
    ]
    for kind, f in figures.items():
        lines.append(
            f"| {LABELS[kind]} | {f['act_p50_ms'] / ours['act_p50_ms']:.2f}x | "
            f"{f['act_rps_c1'] / ours['act_rps_c1']:.2f}x | "
            f"{f['act_rps_c32'] / ours['act_rps_c32']:.2f}x |"
        )
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
    for tool in ("wrk", "taskset"):
        if shutil.which(tool) is None:
            raise SystemExit(f"{tool} not found: apt-get install wrk util-linux")
    order = ["coexist"] + [s for s in SERVERS if s in args.servers and s != "coexist"]
    reference: dict[str, np.ndarray] = {}
    with tempfile.TemporaryDirectory(prefix="coexist-alternatives-") as tmp_dir:
        tmp = Path(tmp_dir)
        url = f"sqlite:///{tmp / 'models.db'}"
        build_store(url)
        print(describe())
        print(
            f"servers on CPU {SERVER_CPU} (one at a time), wrk on CPU {LOAD_CPU}, "
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
