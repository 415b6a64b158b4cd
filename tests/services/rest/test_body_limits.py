"""Request bodies against a real `coexist serve`: a declared or streamed body over
`COEXIST_MAX_BODY_BYTES` is refused with 413 before it is read, and large bodies under the limit
are refused quickly, with a short answer, without stalling other requests."""

from __future__ import annotations

import contextlib
import json
import select
import socket
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest
from live_serve import serving, zoo_copy
from replica_cluster import OBS, Server

LIMIT = 12 << 20  # the server's COEXIST_MAX_BODY_BYTES in these tests
LIMIT_TEXT = str(LIMIT)


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory, _tiny_zoo_template: Path) -> Iterator[Server]:
    directory = tmp_path_factory.mktemp("body_limits")
    url = zoo_copy(_tiny_zoo_template, directory / "store")
    with serving(directory, url, COEXIST_MAX_BODY_BYTES=LIMIT_TEXT) as running:
        yield running


def _address(server: Server) -> tuple[str, int]:
    host, port = server.http_url.removeprefix("http://").split(":")
    return host, int(port)


def _head(path: str, **headers: str) -> bytes:
    lines = [f"POST {path} HTTP/1.1", "Host: 127.0.0.1", "Content-Type: application/json"]
    lines += [f"{name.replace('_', '-')}: {value}" for name, value in headers.items()]
    return ("\r\n".join(lines) + "\r\n\r\n").encode()


def _read_response(sock: socket.socket, timeout: float) -> tuple[int, dict[str, str], bytes]:
    """Status, headers (lower-case names) and body of one response with a Content-Length."""
    sock.settimeout(timeout)
    data = b""
    while b"\r\n\r\n" not in data:
        chunk = sock.recv(65536)
        assert chunk, f"connection closed before a response: {data!r}"
        data += chunk
    head, _, body = data.partition(b"\r\n\r\n")
    status_line, *header_lines = head.decode("latin-1").split("\r\n")
    headers = {k.strip().lower(): v.strip() for k, v in (h.split(":", 1) for h in header_lines)}
    while len(body) < int(headers.get("content-length", "0")):
        chunk = sock.recv(65536)
        if not chunk:
            break
        body += chunk
    return int(status_line.split()[1]), headers, body


def test_a_declared_oversize_body_is_refused_before_it_is_sent(server: Server) -> None:
    """Content-Length 100 MB: the answer comes after the headers and 1 KB, not after 100 MB."""
    with socket.create_connection(_address(server), timeout=5) as sock:
        sock.sendall(_head("/v1/act:batch", Content_Length=str(100 << 20)) + b"[" * 1024)
        try:
            status, headers, body = _read_response(sock, timeout=5.0)
        except TimeoutError:
            pytest.fail("no answer within 5 s: the server waits for the whole body")
    assert status == 413
    error = json.loads(body)
    assert error["code"] == "body_too_large" and error["field"] == "body"
    assert LIMIT_TEXT in error["detail"] and "COEXIST_MAX_BODY_BYTES" in error["detail"]
    assert headers.get("x-request-id")  # the request id middleware saw it too
    assert headers.get("connection") == "close"  # the unread body is not parsed as a request


def test_a_streamed_body_is_cut_at_the_limit(server: Server) -> None:
    """A chunked body (no Content-Length) is counted while it streams: 413 once it passes the
    limit, while the client is still sending (it would send three times the limit)."""
    chunk = b"[" + b"0," * (64 << 10)
    framed = f"{len(chunk):x}\r\n".encode() + chunk + b"\r\n"
    sent, answered_at = 0, None
    with socket.create_connection(_address(server), timeout=5) as sock:
        sock.sendall(_head("/v1/act", Transfer_Encoding="chunked"))
        while sent < 3 * LIMIT:
            try:
                sock.sendall(framed)
            except (BrokenPipeError, ConnectionResetError):
                answered_at = sent  # the server answered and closed: read the answer below
                break
            sent += len(chunk)
            if select.select([sock], [], [], 0)[0]:
                answered_at = sent
                break
        if answered_at is None:
            with contextlib.suppress(BrokenPipeError, ConnectionResetError):
                sock.sendall(b"0\r\n\r\n")
        status, _, body = _read_response(sock, timeout=30.0)
    assert status == 413, body[:300]
    assert json.loads(body)["code"] == "body_too_large"
    # before the end of the body (the client's count runs ahead by the sockets' buffers)
    assert answered_at is not None, "the server answered only once the whole body was sent"


def _observations_of_strings(size: int) -> bytes:
    head = b'{"env": "particle", "ego_goal": "a2", "observations": [['
    count = (size - len(head) - 4) // 4
    return head + b",".join([b'"x"'] * count) + b"]]}"


def _versions_of_strings(size: int) -> bytes:
    pins = ", ".join(f'"m{i:07d}": "x"' for i in range(size // 16))
    return f'{{"env": "particle", "ego_goal": "a2", "observation": {OBS}, "versions": {{{pins}}}}}'.encode()


def _partners_of_strings(size: int) -> bytes:
    partners = ", ".join(['{"index": "x"}'] * (size // 16))
    return f'{{"env": "particle", "ego_goal": "a2", "observation": {OBS}, "partners": [{partners}]}}'.encode()


def _long_goal(size: int) -> bytes:
    body = {"env": "particle", "ego_goal": "g" * size, "observation": OBS}
    return json.dumps(body).encode()


BIG_BODIES = [  # (route, body builder, the field the 422 names, or its start)
    ("/v1/act:batch", _observations_of_strings, "observations[0]"),
    ("/v1/act", _versions_of_strings, "versions"),
    ("/v1/act", _partners_of_strings, "partners"),
    ("/v1/act", _long_goal, "ego_goal"),
]


def test_big_bodies_under_the_limit_stall_no_other_request(server: Server) -> None:
    """~10 MB bodies of a million bad values each: every one is a short 422 naming the field,
    and /healthz keeps answering meanwhile."""
    bodies = [(route, build(10 << 20), field) for route, build, field in BIG_BODIES]
    answers: list[tuple[str, httpx.Response]] = []

    def post_all() -> None:
        with httpx.Client(base_url=server.http_url, timeout=120.0) as client:
            for route, body, field in bodies:
                headers = {"content-type": "application/json"}
                answers.append((field, client.post(route, content=body, headers=headers)))

    worker = threading.Thread(target=post_all)
    latencies: list[float] = []
    with httpx.Client(base_url=server.http_url, timeout=60.0) as probe:
        worker.start()
        while worker.is_alive():
            started = time.perf_counter()
            assert probe.get("/healthz").status_code == 200
            latencies.append(time.perf_counter() - started)
            time.sleep(0.02)
        worker.join()
    assert len(answers) == len(bodies)
    for field, response in answers:
        assert response.status_code == 422, response.text[:300]
        assert response.json()["field"].startswith(field)
        assert len(response.content) < 4096, f"{field}: a {len(response.content)}-byte answer"
    assert max(latencies) < 1.5, f"/healthz stalled {max(latencies):.2f} s"
