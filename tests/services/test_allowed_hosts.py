"""DNS rebinding: a real `coexist serve` answers only the `Host` names it is known by.

A page on `evil.example` re-pointed at 127.0.0.1 sends `Host: evil.example`: refused (400)
before any route, while `localhost` and `127.0.0.1` (local use) answer as before; with
`COEXIST_ALLOWED_HOSTS` the configured names answer and nothing else does."""

from __future__ import annotations

from pathlib import Path

import httpx
import pytest
from replica_cluster import running, seed_zoo, server_env, start_server

from services.allowed_hosts import allowed_hosts, host_allowed, host_name
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
