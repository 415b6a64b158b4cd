"""What the direct JSON path (`services/rest/direct_route.py`) is worth over sockets: `POST
/v1/act` on `coexist serve` with it and with FastAPI's router alone (`COEXIST_DIRECT_JSON=0`),
in alternated rounds.

Run: `.venv/bin/python benchmarks/dispatch.py [--rounds 5] [--duration 3]` (needs `wrk`).

Each round starts the server once per way (the order alternates between rounds), pinned to CPU
0 with `wrk` on CPU 1 as `benchmarks/serving.py` does, on its store and act body, and measures
the act's p50 at c = 1, its req/s at c = 32 and the server's CPU time per request at c = 32 (its
processes' user + system time over the timed run: what a saturated core spends per act, the
figure least moved by a neighbour's load on a shared machine). The table shows each figure's
median over the rounds and the median of the per-round ratios.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import serving  # noqa: E402
from machine import describe  # noqa: E402
from wrk_server import LOAD_CPU, free_port, start_server, stop  # noqa: E402

WAYS = {"direct": "1", "FastAPI's router": "0"}  # COEXIST_DIRECT_JSON
FIGURES = {  # name: format
    "p50 ms, c = 1": ".3f",
    "req/s, c = 32": ",.0f",
    "server CPU µs per request, c = 32": ".0f",
}
TICK = os.sysconf("SC_CLK_TCK")


def tree_cpu_s(pid: int) -> float:
    """User + system seconds of a process and its descendants (from /proc)."""
    pending, total = [pid], 0.0
    while pending:
        proc = Path(f"/proc/{pending.pop()}")
        try:
            fields = (proc / "stat").read_text().rsplit(")", 1)[1].split()
            total += (int(fields[11]) + int(fields[12])) / TICK
            for task in (proc / "task").iterdir():
                pending += [int(k) for k in (task / "children").read_text().split()]
        except FileNotFoundError:  # gone meanwhile
            continue
    return total


def run_wrk(
    url: str, body: bytes, concurrency: int, seconds: int, tmp: Path, pid: int
) -> tuple[float, float, float]:
    """(p50 ms, req/s, server CPU µs per request) of a timed run after a 1 s warm-up."""
    (tmp / "body.json").write_bytes(body)
    (tmp / "wrk.lua").write_text(
        "wrk.method = 'POST'\nwrk.headers['Content-Type'] = 'application/json'\n"
        f"local f = io.open('{tmp / 'body.json'}', 'rb'); wrk.body = f:read('*a'); f:close()\n"
    )
    command = ["taskset", "-c", LOAD_CPU, "wrk", "-t1", f"-c{concurrency}", "--timeout", "10s"]
    command += ["-s", str(tmp / "wrk.lua")]
    subprocess.run([*command, "-d1s", url], check=True, capture_output=True)
    before = tree_cpu_s(pid)
    out = subprocess.run(
        [*command, f"-d{seconds}s", "--latency", url], check=True, capture_output=True, text=True
    ).stdout
    cpu_s = tree_cpu_s(pid) - before
    requests, took_s, p50_ms, failed = serving.parse_wrk(out)
    if failed:
        raise SystemExit(f"{failed} failed requests at c = {concurrency}")
    return p50_ms, requests / took_s, cpu_s / requests * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--duration", type=int, default=3, help="seconds per timed run")
    args = parser.parse_args()
    found: dict[str, list[tuple[float, float, float]]] = {way: [] for way in WAYS}
    with tempfile.TemporaryDirectory() as name:
        tmp = Path(name)
        url = f"sqlite:///{tmp}/models.db"
        serving.build_store(url)
        body = serving.rest_bodies()["act"]
        for r in range(args.rounds):
            for way in list(WAYS)[:: 1 if r % 2 == 0 else -1]:
                os.environ["COEXIST_DIRECT_JSON"] = WAYS[way]
                port = free_port()
                server = start_server(url, port)
                try:
                    act = f"http://127.0.0.1:{port}/v1/act"
                    p50_ms, _, _ = run_wrk(act, body, 1, args.duration, tmp, server.pid)
                    _, rps, cpu_us = run_wrk(act, body, 32, args.duration, tmp, server.pid)
                finally:
                    stop(server)
                found[way].append((p50_ms, rps, cpu_us))
    print(describe())
    direct, router = found["direct"], found["FastAPI's router"]
    print("| `POST /v1/act` | direct | FastAPI's router | direct / router (rounds' median) |")
    print("|---|---:|---:|---:|")
    for i, (figure, form) in enumerate(FIGURES.items()):
        ratio = statistics.median(a[i] / b[i] for a, b in zip(direct, router, strict=True))
        medians = [statistics.median(row[i] for row in rows) for rows in (direct, router)]
        print(f"| {figure} | {medians[0]:{form}} | {medians[1]:{form}} | {ratio:.2f} |")


if __name__ == "__main__":
    main()
