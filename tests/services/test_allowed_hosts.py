"""DNS rebinding: a real `coexist serve` answers only the `Host` names it is known by.

A page on `evil.example` re-pointed at 127.0.0.1 sends `Host: evil.example`: refused (400)
before any route, while `localhost` and `127.0.0.1` (local use) answer as before; with
`COEXIST_ALLOWED_HOSTS` the configured names answer and nothing else does."""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any

import httpx
import pytest
from replica_cluster import running, seed_zoo, server_env, start_server

from services.allowed_hosts import AllowedHosts, allowed_hosts, host_allowed, host_name
from services.settings import Settings


def test_the_default_list_follows_the_listening_address() -> None:
    assert allowed_hosts(Settings()) == ["localhost", "127.0.0.1", "::1"]
    assert allowed_hosts(Settings(host="0.0.0.0")) == ["*"]
    assert allowed_hosts(Settings(allowed_hosts="a.example, *.b.example")) == [
        "a.example",
        "*.b.example",
    ]
    assert host_name("[::1]:8000") == "::1" and host_name("A.example:80") == "a.example"
    assert host_allowed("x.b.example:1", ["*.b.example"])
    assert not host_allowed("b.example.evil:1", ["*.b.example"])
    assert not host_allowed("", ["localhost"])


def _asgi_status(app: AllowedHosts, host: bytes | None) -> int:
    """The status `app` answers a GET with this `Host` header (None: without one)."""
    answers: list[int] = []

    async def inner(scope: Any, receive: Any, send: Any) -> None:
        answers.append(200)

    async def send(message: dict[str, Any]) -> None:
        if message["type"] == "http.response.start":
            answers.append(message["status"])

    async def receive() -> dict[str, Any]:
        return {"type": "http.request", "body": b"", "more_body": False}

    app.app = inner
    headers = [] if host is None else [(b"host", host)]
    scope = {"type": "http", "method": "GET", "path": "/v1/envs", "headers": headers}
    asyncio.run(app(scope, receive, send))
    (status,) = answers
    return status


def test_only_allowed_hosts_are_remembered_and_the_memory_is_bounded() -> None:
    """The names found allowed are remembered (a set look-up instead of the patterns on every
    request); a refused one never is, and a refused name stays refused after allowed ones."""
    app = AllowedHosts(None, ["localhost", "*.b.example"])
    for _ in range(2):
        assert _asgi_status(app, b"localhost:8000") == 200
        assert _asgi_status(app, b"evil.example") == 400
        assert _asgi_status(app, None) == 400
    assert app._seen_allowed == {b"localhost:8000"}
    for k in range(AllowedHosts.REMEMBERED + 10):
        assert _asgi_status(app, f"n{k}.b.example".encode()) == 200
    assert len(app._seen_allowed) == AllowedHosts.REMEMBERED
    assert _asgi_status(app, b"n500.b.example") == 200  # not remembered, still allowed
    assert _asgi_status(app, b"b.example.evil") == 400


def _status(base: str, host: str, path: str = "/v1/envs") -> int:
    return httpx.get(f"{base}{path}", headers={"Host": host}, timeout=30).status_code


@pytest.mark.slow
@pytest.mark.parametrize("configured", ["", "policy.example,127.0.0.1"])
def test_a_rebinding_host_is_refused(tmp_path: Path, configured: str) -> None:
    url = f"sqlite:///{tmp_path / 'models.db'}"
    seed_zoo(url)
    env = server_env(url, tmp_path / "data", COEXIST_ALLOWED_HOSTS=configured)
    server = start_server("hosts", env, tmp_path)
    with running([server]):
        base = server.http_url
        port = base.rsplit(":", 1)[1]
        refused = httpx.get(f"{base}/v1/envs", headers={"Host": f"evil.example:{port}"})
        assert refused.status_code == 400, refused.text
        assert refused.json()["code"] == "invalid_host"
        local = [_status(base, f"{h}:{port}") for h in ("127.0.0.1", "localhost", "[::1]")]
        if configured:
            assert _status(base, "policy.example") == 200
            assert local == [200, 400, 400]  # 127.0.0.1 is listed (health checks use it)
        else:
            assert local == [200, 200, 200]
