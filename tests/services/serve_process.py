"""`coexist serve` as a user starts it, for the tests that run it as a process (imported by them;
not a test module): a free loopback port, the command line, and the wait for `/readyz`."""

from __future__ import annotations

import socket
import subprocess
import sys
import time

import httpx

COEXIST = (sys.executable, "-m", "cli.main")  # the `coexist` command of this checkout
# a particle observation of two agents (ego, partner: x, y, vx, vy each) that the tiny zoo acts on
OBS = [0.1, 0.4, 0.0, 0.0, 0.7, 0.6, 0.0, 0.0]


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def serve_command(store_url: str, http_port: int, grpc_port: int = 0, *extra: str) -> list[str]:
    """`coexist serve --no-bootstrap` on the given ports (gRPC 0: off) over `store_url`; `extra`
    options follow."""
    ports = ["--http-port", str(http_port), "--grpc-port", str(grpc_port)]
    return [*COEXIST, "serve", "--no-bootstrap", *ports, "--store-url", store_url, *extra]


def wait_ready(url: str, process: subprocess.Popen[bytes], timeout: float = 60.0) -> None:
    """Until `url/readyz` answers 200; fails with the server's output if it exits first."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        assert process.poll() is None, process.communicate()[0].decode()
        try:
            if httpx.get(f"{url}/readyz", timeout=1.0).status_code == 200:
                return
        except httpx.TransportError:
            pass
        time.sleep(0.2)
    raise AssertionError("server did not become ready")
