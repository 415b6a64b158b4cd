"""`X-Forwarded-For` is believed only from the proxies `COEXIST_FORWARDED_ALLOW_IPS` names.

The attack: one local client of a real `coexist serve` sets a new `X-Forwarded-For` on every
request to pose as many clients and open sessions past its per-client cap (uvicorn, left to its
default, believes the header from 127.0.0.1). With no proxy configured the cap holds whatever
the header says; with 127.0.0.1 named as the proxy, the header is the client, as it should be
behind a real proxy."""

from __future__ import annotations

from pathlib import Path

import httpx
import pytest
from replica_cluster import running, seed_zoo, server_env, start_server

CAP = 3
SESSION = {"env": "particle", "ego_goal": "a2", "partners": [{"index": 1, "goal": "b3"}]}


def _open_sessions(base: str, count: int) -> list[int]:
    """POST /v1/sessions `count` times, each claiming another forwarded client address."""
    return [
        httpx.post(
            f"{base}/v1/sessions",
            json=SESSION,
            headers={"X-Forwarded-For": f"203.0.113.{k + 1}"},
            timeout=30,
        ).status_code
        for k in range(count)
    ]


@pytest.mark.slow
@pytest.mark.parametrize("proxies", ["", "127.0.0.1"])
def test_one_local_client_cannot_pass_its_session_cap_by_forging_the_header(
    tmp_path: Path, proxies: str
) -> None:
    url = f"sqlite:///{tmp_path / 'models.db'}"
    seed_zoo(url)
    env = server_env(
        url,
        tmp_path / "data",
        COEXIST_MAX_SESSIONS_PER_CLIENT=str(CAP),
        COEXIST_FORWARDED_ALLOW_IPS=proxies,
    )
    server = start_server("forwarded", env, tmp_path)
    with running([server]):
        statuses = _open_sessions(server.http_url, CAP + 2)
    if not proxies:  # the header is ignored: one client, capped
        assert statuses == [201] * CAP + [429, 429], statuses
    else:  # a trusted proxy's header names the client: five clients, one session each
        assert statuses == [201] * (CAP + 2), statuses
