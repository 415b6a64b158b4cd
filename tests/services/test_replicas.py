"""Several `coexist serve` processes over one PostgreSQL store, as an operator runs them.

- two replicas on loopback; an alias moved through the registry API of one of them; both serve
  the new version within seconds (hot reload from the shared store), while two clients (REST and
  gRPC) hammer both replicas without a single failed request;
- graceful shutdown: SIGTERM while a request is still uploading; it completes with 200;
- the logs are JSON lines with request ids (the id a client sent comes back in the header and in
  the access line);
- every server setting is in the table of `services/settings.py`.
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import httpx
import pytest
from coexist_client import GrpcCoexistClient
from replica_cluster import (
    ADMIN_TOKEN,
    OBS,
    act_body,
    pg_schema_url,
    running,
    seed_zoo,
    server_env,
    start_server,
)

import services.settings
from services.settings import Settings

pytestmark = pytest.mark.postgres
SWITCH_DEADLINE_S = 10.0  # refresh every 0.3 s: seconds are plenty even on a loaded machine
LOG_KEYS = {"ts", "level", "logger", "msg", "request_id"}


@pytest.fixture
def zoo_url() -> Iterator[str]:
    with pg_schema_url() as url:
        seed_zoo(url)
        yield url


def _task_version(models: Sequence[Any]) -> int:
    """The version of `particle/task/a2` in a response's models (dicts or SDK objects)."""
    for m in models:
        name = m["name"] if isinstance(m, dict) else m.name
        if name == "particle/task/a2":
            return int(m["version"] if isinstance(m, dict) else m.version)
    raise AssertionError(models)


@pytest.mark.slow  # two server processes start: ~10-20 s on 2 cores
def test_two_replicas_follow_an_alias_move_without_failed_requests(
    zoo_url: str, tmp_path: Path
) -> None:
    env = server_env(zoo_url, tmp_path)
    replicas = [start_server(name, env, tmp_path) for name in ("a", "b")]
    with running(replicas):
        # (client, replica) -> versions of particle/task/a2 served, in request order
        seen: dict[tuple[str, int], list[int]] = {
            (c, r): [] for c in ("rest", "grpc") for r in (0, 1)
        }
        failures: list[str] = []
        stop = threading.Event()

        def hammer_rest() -> None:
            with httpx.Client(timeout=10) as client:
                k = 0
                while not stop.is_set():
                    r = k % 2
                    try:
                        resp = client.post(f"{replicas[r].http_url}/v1/act", json=act_body())
                        if resp.status_code != 200:
                            failures.append(f"rest {r}: {resp.status_code} {resp.text}")
                        else:
                            seen["rest", r].append(_task_version(resp.json()["models"]))
                    except httpx.HTTPError as exc:
                        failures.append(f"rest {r}: {exc!r}")
                    k += 1

        def hammer_grpc() -> None:
            clients = [GrpcCoexistClient(s.grpc_target) for s in replicas]
            try:
                k = 0
                while not stop.is_set():
                    r = k % 2
                    try:
                        action = clients[r].act("particle", "a2", OBS, partners={1: "b3"}, seed=2)
                        seen["grpc", r].append(_task_version(action.models))
                    except Exception as exc:
                        failures.append(f"grpc {r}: {exc!r}")
                    k += 1
            finally:
                for c in clients:
                    c.close()

        threads = [threading.Thread(target=hammer_rest), threading.Thread(target=hammer_grpc)]
        for t in threads:
            t.start()
        try:
            time.sleep(1.0)
            moved_at = time.monotonic()
            resp = httpx.put(
                f"{replicas[0].http_url}/v1/registry/models/particle/task/a2/-/aliases/production",
                json={"version": 2},
                headers={"Authorization": f"Bearer {ADMIN_TOKEN}", "X-Request-ID": "move-a2"},
            )
            assert resp.status_code == 200, resp.text
            assert resp.headers["x-request-id"] == "move-a2"
            switched: dict[int, float] = {}
            while len(switched) < 2 and time.monotonic() - moved_at < SWITCH_DEADLINE_S:
                for r in (0, 1):
                    if r not in switched and 2 in seen["rest", r][-3:] + seen["grpc", r][-3:]:
                        switched[r] = time.monotonic() - moved_at
                time.sleep(0.05)
            time.sleep(1.0)  # keep hammering after the switch
        finally:
            stop.set()
            for t in threads:
                t.join(timeout=30)
        assert not failures, failures[:5]
        assert sorted(switched) == [0, 1], f"not every replica switched: {switched}"
        for (client, r), versions in seen.items():
            assert versions[0] == 1 and versions[-1] == 2, (client, r)
            # never back: a request sent after one that got version 2 gets version 2
            assert 1 not in versions[versions.index(2) :], (client, r)
        total = sum(len(versions) for versions in seen.values())
        assert total > 50, total
        print(f"replicas switched after {switched} s; {total} requests, none failed")

    # structured logs: every stderr line is a JSON object with the common fields
    records = [json.loads(line) for line in replicas[0].logs()]
    assert all(rec.keys() >= LOG_KEYS for rec in records)
    move = [rec for rec in records if rec.get("request_id") == "move-a2"]
    assert len(move) == 1 and move[0]["logger"] == "coexist.access"
    assert move[0]["method"] == "PUT" and move[0]["status"] == 200
    assert move[0]["route"] == "/v1/registry/models/{name:path}/-/aliases/{alias}"
    assert isinstance(move[0]["duration_ms"], float)
    started = [rec for rec in records if rec["msg"] == "Application startup complete."]
    assert started and started[0]["request_id"] is None  # written outside any request


@pytest.mark.slow  # a server process starts and stops: ~10 s on 2 cores
def test_sigterm_lets_an_in_flight_request_finish(zoo_url: str, tmp_path: Path) -> None:
    server = start_server("graceful", server_env(zoo_url, tmp_path), tmp_path)
    fields = act_body()
    fields["observations"] = [fields.pop("observation")] * 64
    body = json.dumps(fields).encode()
    half = len(body) // 2
    sent_first_half = threading.Event()
    terminated = threading.Event()

    def slow_upload() -> Iterator[bytes]:
        yield body[:half]
        sent_first_half.set()
        terminated.wait(timeout=30)  # the rest of the body only after SIGTERM
        yield body[half:]

    result: dict[str, httpx.Response] = {}
    with running([server]):
        url = f"{server.http_url}/v1/act:batch"

        def post() -> None:
            result["resp"] = httpx.post(
                url, content=slow_upload(), timeout=30, headers={"Content-Type": "application/json"}
            )

        poster = threading.Thread(target=post)
        poster.start()
        assert sent_first_half.wait(timeout=10)
        time.sleep(0.5)  # the server has the request's headers: the request is in flight
        server.process.terminate()
        time.sleep(0.5)  # shutting down, waiting for the in-flight request
        terminated.set()
        poster.join(timeout=30)
        code = server.process.wait(timeout=30)
    resp = result["resp"]
    assert resp.status_code == 200, resp.text
    assert len(resp.json()["results"]) == 64
    assert code in (0, -15)
    messages = [json.loads(line)["msg"] for line in server.logs()]
    assert "Application shutdown complete." in messages
    done = [i for i, m in enumerate(messages) if m.startswith("POST /v1/act:batch 200")]
    assert done and done[0] < messages.index("Application shutdown complete.")


def test_every_server_setting_is_in_the_settings_table() -> None:
    doc = services.settings.__doc__ or ""
    for field in Settings.model_fields:
        assert f"`COEXIST_{field.upper()}`" in doc, field
