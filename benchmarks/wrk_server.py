"""The load-test plumbing of `benchmarks/session_bench.py`: the real server as a child process
pinned to one CPU, and `wrk` on the other posting a list of JSON bodies in turn (a Lua script).

| function       | what                                                                  |
|----------------|-----------------------------------------------------------------------|
| `start_server` | `coexist serve --no-bootstrap` (REST; gRPC too with `grpc_port`) on   |
|                | `taskset -c SERVER_CPU`, waits for `/readyz`                          |
| `start_floor`  | a bare REST or gRPC server (`floor_servers.py`) on the same CPU, ready |
| `wait_ready`   | polls a started server until it answers (or exits: SystemExit)       |
| `http_ok`,     | whether a GET answers 200; whether a gRPC health check answers       |
| `grpc_ok`      | SERVING                                                               |
| `stop`         | ends a server started here and waits for it                           |
| `lua_script`   | a wrk script POSTing the bodies in turn (one wrk thread: a counter)   |
| `run_wrk`      | 1 s of warm-up, then the timed run, c = 1, on `taskset -c LOAD_CPU`   |
| `parse_wrk`    | requests, seconds, p50/p90/p99 and failures from `wrk --latency`      |
"""

from __future__ import annotations

import os
import re
import socket
import subprocess
import time
from collections.abc import Callable
from pathlib import Path

import httpx

ROOT = Path(__file__).resolve().parents[1]
SERVER_CPU, LOAD_CPU = "0", "1"
UNIT_MS = {"us": 1e-3, "ms": 1.0, "s": 1000.0}


def lua_script(path: str, bodies: list[bytes], pause_ms: float = 0.0) -> str:
    """A wrk script POSTing `bodies` to `path` in turn (one wrk thread: a plain counter);
    `pause_ms` > 0: wrk waits that long after each answer before sending the next request
    (wrk's `delay`; latency still runs from the request's send to its answer)."""
    items = ",\n".join(f"[==[{b.decode()}]==]" for b in bodies)
    pause = f"delay = function()\n  return {pause_ms:g}\nend\n" if pause_ms > 0 else ""
    return pause + (
        "local bodies = {\n" + items + "\n}\n"
        "local i = 0\n"
        "local headers = {['Content-Type'] = 'application/json'}\n"
        "request = function()\n"
        "  i = i % #bodies + 1\n"
        f"  return wrk.format('POST', '{path}', headers, bodies[i])\n"
        "end\n"
    )


def parse_wrk(out: str) -> dict[str, float]:
    """requests, seconds, p50/p90/p99 in ms and failures from `wrk --latency` output."""
    found = re.search(r"(\d+) requests in ([\d.]+)(ms|s|m)", out)
    if found is None:
        raise ValueError(f"wrk output without a request count:\n{out}")
    seconds = float(found.group(2)) * {"ms": 1e-3, "s": 1.0, "m": 60.0}[found.group(3)]
    parsed = {"requests": float(found.group(1)), "seconds": seconds}
    for q in (50, 90, 99):
        value = re.search(rf"^\s*{q}%\s+([\d.]+)(us|ms|s)\s*$", out, re.MULTILINE)
        if value is None:
            raise ValueError(f"wrk output without a {q}% latency (run with --latency):\n{out}")
        parsed[f"p{q}_ms"] = float(value.group(1)) * UNIT_MS[value.group(2)]
    failed = re.search(r"Non-2xx or 3xx responses: (\d+)", out)
    errors = re.search(r"Socket errors: (.*)", out)
    parsed["failed"] = float(failed.group(1)) if failed else 0.0
    if errors:
        parsed["failed"] += sum(int(n) for n in re.findall(r"\d+", errors.group(1)))
    return parsed


def run_wrk(
    base: str, path: str, bodies: list[bytes], duration: float, tmp: Path, pause_ms: float = 0.0
) -> tuple[dict[str, float], int]:
    """The timed run's figures and the requests of both runs (warm-up included); `pause_ms`
    as `lua_script` takes it."""
    script = tmp / "bench.lua"
    script.write_text(lua_script(path, bodies, pause_ms))
    command = [
        "taskset",
        "-c",
        LOAD_CPU,
        "wrk",
        "-t1",
        "-c1",
        "--timeout",
        "10s",
        "-s",
        str(script),
        "--latency",
    ]
    runs = []
    for seconds in (1, round(duration)):  # warm-up, then the timed run
        done = subprocess.run(
            [*command, f"-d{seconds}s", base], check=True, capture_output=True, text=True
        )
        runs.append(parse_wrk(done.stdout))
    return runs[1], int(runs[0]["requests"] + runs[1]["requests"])


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def start_server(
    url: str, port: int, *, grpc_port: int = 0, log_level: str = "warning"
) -> subprocess.Popen[bytes]:
    """`coexist serve` on CPU `SERVER_CPU` (gRPC too when `grpc_port` > 0), ready to answer."""
    env = {**os.environ, "COEXIST_DEV_MODE": "1", "COEXIST_LOG_LEVEL": log_level}
    command = [
        "taskset",
        "-c",
        SERVER_CPU,
        str(ROOT / ".venv/bin/coexist"),
        "serve",
        "--no-bootstrap",
        "--host",
        "127.0.0.1",
        "--http-port",
        str(port),
        "--grpc-port",
        str(grpc_port),
        "--store-url",
        url,
    ]
    server = subprocess.Popen(command, env=env, stdout=subprocess.DEVNULL)
    if wait_ready(server, lambda: http_ok(f"http://127.0.0.1:{port}/readyz"), "the server", 120):
        return server
    server.kill()
    raise SystemExit("the server did not become ready within 120 s")


def start_floor(kind: str, port: int) -> subprocess.Popen[bytes]:
    """`floor_servers.py kind port` on CPU `SERVER_CPU`, once it answers its health check."""
    command = [
        "taskset",
        "-c",
        SERVER_CPU,
        str(ROOT / ".venv/bin/python"),
        str(ROOT / "benchmarks/floor_servers.py"),
        kind,
        str(port),
    ]
    server = subprocess.Popen(command, stdout=subprocess.DEVNULL)
    if wait_ready(server, lambda: _floor_answers(kind, port), f"the {kind} floor", 60):
        return server
    server.kill()
    raise SystemExit(f"the {kind} floor did not answer within 60 s")


def wait_ready(
    server: subprocess.Popen[bytes],
    ready: Callable[[], bool],
    what: str,
    seconds: float,
    exited: Callable[[], str] = lambda: "",
) -> bool:
    """Poll `ready` every 0.3 s until it is true (True) or `seconds` have passed (False; the
    caller stops the server). A server that exits first is `SystemExit`, saying `what` exited
    and, after its return code, `exited()` (a log's tail)."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if server.poll() is not None:
            raise SystemExit(f"{what} exited with {server.returncode}{exited()}")
        if ready():
            return True
        time.sleep(0.3)
    return False


def http_ok(url: str, timeout: float = 1.0) -> bool:
    """Whether a GET of `url` answers 200 (a refused or timed-out connection: False)."""
    try:
        return httpx.get(url, timeout=timeout).status_code == 200
    except httpx.HTTPError:
        return False


def _floor_answers(kind: str, port: int) -> bool:
    if kind == "rest":
        return http_ok(f"http://127.0.0.1:{port}/healthz")
    return grpc_ok(port)


def grpc_ok(port: int) -> bool:
    """Whether the standard gRPC health service on `port` answers SERVING."""
    import grpc
    from grpc_health.v1 import health_pb2, health_pb2_grpc

    with grpc.insecure_channel(f"127.0.0.1:{port}") as channel:
        try:
            stub = health_pb2_grpc.HealthStub(channel)
            answer = stub.Check(health_pb2.HealthCheckRequest(), timeout=1)
        except grpc.RpcError:
            return False
    return bool(answer.status == health_pb2.HealthCheckResponse.SERVING)


def stop(server: subprocess.Popen[bytes]) -> None:
    """SIGTERM, then wait (SIGKILL after 30 s)."""
    server.terminate()
    try:
        server.wait(timeout=30)
    except subprocess.TimeoutExpired:
        server.kill()
        server.wait()
