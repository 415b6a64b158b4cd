"""Slow and oversized HTTP clients against a real `coexist serve` (`services.http_protocol`): a
64 MiB header is refused with 431 without the server's memory growing with it; a socket that
sends nothing, or half a request head, is closed within the header timeout; and 1,100 slow
sockets against a server limited to 1,024 file descriptors leave `/healthz`, `/v1/act` and the
store answering for others."""

from __future__ import annotations

import json
import resource
import socket
import subprocess
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest
from live_serve import serving, wait_until, zoo_copy
from replica_cluster import OBS, Server, server_env
from serve_process import free_port, serve_command

from services.http_protocol import FD_RESERVE, connection_cap

ACT = {
    "env": "particle",
    "ego_goal": "a2",
    "observation": OBS,
    "partners": [{"index": 1, "goal": "b3"}],
}


def _address(server: Server) -> tuple[str, int]:
    host, port = server.http_url.removeprefix("http://").split(":")
    return host, int(port)


def _memory_kib(pid: int) -> dict[str, int]:
    """VmRSS (now) and VmHWM (the peak so far) of a process, in KiB."""
    fields = {}
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        name, _, value = line.partition(":")
        if name in ("VmRSS", "VmHWM"):
            fields[name] = int(value.split()[0])
    return fields


def _read_until_closed(sock: socket.socket, timeout: float) -> bytes:
    sock.settimeout(timeout)
    data = b""
    try:
        while chunk := sock.recv(65536):
            data += chunk
    except ConnectionResetError:
        pass
    return data


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory, _tiny_zoo_template: Path) -> Iterator[Server]:
    directory = tmp_path_factory.mktemp("http_protocol")
    url = zoo_copy(_tiny_zoo_template, directory / "store")
    with serving(directory, url) as running:  # the default limits
        yield running


def test_a_64_mib_header_is_refused_without_a_memory_spike(server: Server) -> None:
    before = _memory_kib(server.process.pid)
    with socket.create_connection(_address(server), timeout=10) as sock:
        head = b"GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Big: "

        def send() -> None:
            try:
                sock.sendall(head)
                chunk = b"a" * (1 << 20)
                for _ in range(64):
                    sock.sendall(chunk)
            except OSError:
                pass  # the server stopped reading and closed: expected

        sender = threading.Thread(target=send, daemon=True)
        sender.start()
        answer = _read_until_closed(sock, timeout=30)
        sender.join(timeout=30)
    assert answer.startswith(b"HTTP/1.1 431 "), answer[:200]
    error = json.loads(answer.partition(b"\r\n\r\n")[2])
    assert error["code"] == "headers_too_large" and error["field"] == "headers"
    assert "COEXIST_HTTP_MAX_HEADER_BYTES" in error["detail"]
    after = _memory_kib(server.process.pid)
    assert after["VmHWM"] - before["VmHWM"] < 16 << 10, (before, after)  # KiB: under 16 MiB
    assert httpx.get(f"{server.http_url}/healthz", timeout=5).status_code == 200


@pytest.mark.slow
def test_silent_and_half_sent_requests_are_closed_within_the_header_timeout(
    server: Server,
) -> None:
    """The default header timeout (10 s) closes both; the server answers others meanwhile."""
    start = time.monotonic()
    with (
        socket.create_connection(_address(server), timeout=5) as silent,
        socket.create_connection(_address(server), timeout=5) as half,
    ):
        half.sendall(b"GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\n")  # and never the end
        assert httpx.get(f"{server.http_url}/healthz", timeout=5).status_code == 200
        assert _read_until_closed(silent, timeout=30) == b""  # told nothing: it said nothing
        silent_closed = time.monotonic() - start
        answer = _read_until_closed(half, timeout=30)
        half_closed = time.monotonic() - start
    assert 9 < silent_closed < 30 and half_closed < 30, (silent_closed, half_closed)
    assert answer.startswith(b"HTTP/1.1 408 "), answer[:200]
    assert "COEXIST_HTTP_HEADER_TIMEOUT_S" in json.loads(answer.partition(b"\r\n\r\n")[2])["detail"]


def test_the_connection_cap_leaves_descriptors_beside_it() -> None:
    soft, _ = resource.getrlimit(resource.RLIMIT_NOFILE)
    assert connection_cap(None) == max(16, soft - FD_RESERVE)
    assert connection_cap(20) == min(20, connection_cap(None))


def _limit_descriptors() -> None:
    resource.setrlimit(resource.RLIMIT_NOFILE, (1024, 1024))


@pytest.mark.slow
def test_1100_slow_sockets_under_ulimit_1024_leave_the_server_answering(
    tmp_path: Path, _tiny_zoo_template: Path
) -> None:
    url = zoo_copy(_tiny_zoo_template, tmp_path / "store")
    http_port = free_port()
    log_path = tmp_path / "serve.log"
    with open(log_path, "wb") as log:
        process = subprocess.Popen(
            serve_command(url, http_port, free_port()),
            env=server_env(url, tmp_path),
            stdout=log,
            stderr=subprocess.STDOUT,
            preexec_fn=_limit_descriptors,
        )
    server = Server(process, f"http://127.0.0.1:{http_port}", "", log_path)
    slow: list[socket.socket] = []
    try:
        wait_until(server, "/readyz", {}, timeout=90.0)
        for k in range(1100):
            sock = socket.create_connection(("127.0.0.1", http_port), timeout=10)
            if k % 2:  # half of them start a request head and never finish it
                sock.sendall(b"POST /v1/act HTTP/1.1\r\nHost: 127.0.0.1\r\n")
            slow.append(sock)
        with httpx.Client(base_url=server.http_url, timeout=5.0) as client:
            for _ in range(3):
                start = time.monotonic()
                assert client.get("/healthz").status_code == 200
                assert client.post("/v1/act", json=ACT).status_code == 200
                assert client.get("/readyz").status_code == 200  # the store still opens
                assert time.monotonic() - start < 5.0
        assert process.poll() is None
    finally:
        for sock in slow:
            sock.close()
        server.stop()
    logged = log_path.read_text()
    assert "Too many open files" not in logged and "unable to open database" not in logged
