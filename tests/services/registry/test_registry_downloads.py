"""Slow readers of a weights download against a real `coexist serve`
(`services.registry.downloads`): 40 clients that request a 55 MB version and never read it add
less than 200 MB to the server (one shared copy, sent in chunks as the clients read), and a
client that does read gets the whole file, its checksum right, meanwhile."""

from __future__ import annotations

import hashlib
import socket
import time
from pathlib import Path

import httpx
import pytest
from live_serve import serving, zoo_copy
from replica_cluster import Server
from zoo_fixtures import register

from model_store.sql import SqlModelStore
from policy.qnet import QNetSpec

LARGE = QNetSpec(obs_dim=8, n_actions=5, hidden=(3700, 3700))  # float32: about 55 MB
STALLED = 40


def _rss_mib(server: Server) -> float:
    for line in Path(f"/proc/{server.process.pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    raise AssertionError("no VmRSS")


def _settled_rss_mib(server: Server, seconds: float = 10.0) -> float:
    """The server's resident memory once it stopped growing (or after `seconds`)."""
    deadline = time.monotonic() + seconds
    last = _rss_mib(server)
    while time.monotonic() < deadline:
        time.sleep(1.0)
        now = _rss_mib(server)
        if abs(now - last) < 2:
            return now
        last = now
    return last


@pytest.mark.slow
def test_stalled_downloads_share_one_copy(tmp_path: Path, _tiny_zoo_template: Path) -> None:
    url = zoo_copy(_tiny_zoo_template, tmp_path / "store")
    with SqlModelStore(url) as store:  # not served: no alias moves to it
        version = register(store, "particle/task/a2", "task", ("a2",), LARGE, seed=5, aliases=())
    path = f"/v1/registry/models/particle/task/a2/-/versions/{version}/weights"
    with serving(tmp_path, url) as server:
        host, port = server.http_url.removeprefix("http://").split(":")
        with httpx.Client(base_url=server.http_url, timeout=60) as client:
            warm = client.get(path)  # one whole download first: the allocator's pools are warm
            assert warm.status_code == 200 and len(warm.content) > 50 << 20
        before = _settled_rss_mib(server)
        stalled = []
        for _ in range(STALLED):
            sock = socket.create_connection((host, int(port)), timeout=10)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)  # and never read
            sock.sendall(f"GET {path} HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n".encode())
            stalled.append(sock)
        try:
            time.sleep(2.0)  # every request arrived and filled what it could
            grown = _settled_rss_mib(server) - before
            with httpx.Client(base_url=server.http_url, timeout=60) as client:
                full = client.get(path)
        finally:
            for sock in stalled:
                sock.close()
    assert grown < 200, f"{STALLED} stalled downloads grew the server by {grown:.0f} MiB"
    assert full.status_code == 200
    assert hashlib.sha256(full.content).hexdigest() == full.headers["x-checksum-sha256"]
    assert full.content == warm.content
