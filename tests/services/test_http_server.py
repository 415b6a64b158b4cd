"""SIGTERM answers every request clients had already sent (`services.http_server`): 40 batches
of 4,096 rows, each sent in full on its own connection while the machine is busy, then the
signal; all 40 are answered 200 and the server exits within its grace period."""

from __future__ import annotations

import json
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
from live_serve import serving, zoo_copy
from replica_cluster import OBS, Server

ROWS, CLIENTS, GRACE_S = 4096, 40, 60


def _address(server: Server) -> tuple[str, int]:
    host, port = server.http_url.removeprefix("http://").split(":")
    return host, int(port)


def _status_of_answer(sock: socket.socket, timeout: float) -> int | str:
    """The status code of the answer on `sock`, or what went wrong instead."""
    sock.settimeout(timeout)
    data = b""
    try:
        while b"\r\n" not in data:
            chunk = sock.recv(65536)
            if not chunk:
                return f"closed after {len(data)} bytes"
            data += chunk
    except OSError as err:
        return type(err).__name__
    return int(data.split(b" ", 2)[1])


@pytest.mark.slow
def test_sigterm_answers_every_batch_already_sent(tmp_path: Path, _tiny_zoo_template: Path) -> None:
    url = zoo_copy(_tiny_zoo_template, tmp_path / "store")
    body = json.dumps(
        {
            "env": "particle",
            "ego_goal": "a2",
            "observations": [OBS] * ROWS,
            "partners": [{"index": 1, "goal": "b3"}],
        }
    ).encode()
    head = (
        f"POST /v1/act:batch HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
        f"Content-Length: {len(body)}\r\n\r\n"
    ).encode()
    burner = subprocess.Popen([sys.executable, "-c", "while True: pass"])  # a loaded machine
    try:
        with serving(tmp_path, url, COEXIST_SHUTDOWN_GRACE_S=str(GRACE_S)) as server:
            clients = [
                socket.create_connection(_address(server), timeout=30) for _ in range(CLIENTS)
            ]
            for sock in clients:
                sock.sendall(head + body)
            server.process.send_signal(signal.SIGTERM)
            signalled = time.monotonic()
            answers = [_status_of_answer(sock, timeout=GRACE_S) for sock in clients]
            code = server.process.wait(timeout=GRACE_S + 10)
            took = time.monotonic() - signalled
            for sock in clients:
                sock.close()
    finally:
        burner.kill()
        burner.wait()
    assert answers == [200] * CLIENTS, answers
    assert code in (0, -signal.SIGTERM) and took < GRACE_S, (code, took)  # uvicorn re-raises it
